"""MPC by predictive sampling (Howell et al. 2022), rolled out on the env's own model.

The paper's "MPC" baseline (KinDER spec, baselines §3.1). Every solve scores ``num_rollouts``
candidate action sequences over ``horizon`` steps on ``env.unwrapped.transition`` (pure: the live
episode is never touched) with the env's own (sparse) reward, and keeps the best one:

* A candidate is a piecewise-linear spline through ``num_control_points`` control points in action
  space, spanning ``horizon`` steps; the action at step ``t`` is the spline's value at ``t``.
* The nominal candidate is the previous best shifted forward by the steps executed since it was
  found (warm start; times past its end hold its last control point), or, on the first solve or
  without warm start, control points drawn from a standard normal and clipped to the action box.
* The other ``num_rollouts - 1`` candidates are the nominal plus Gaussian noise of per-dimension std
  ``noise_fraction * (high - low)``, clipped to the action box.
* Cost = −(sum of rewards up to and including the first terminating step); with the −1 per step
  reward that is "steps to the goal, or ``horizon`` if it is never reached".
* The lowest cost wins; the nominal is scored first, so ties (frequent with a sparse reward) keep
  the warm-started nominal.

The first action of the best candidate is executed; the agent solves again every
``replan_interval`` steps and executes the stored solution in between.

The rollout model is pluggable: :meth:`MPCAgent.transition` (default: the env's ``transition``)
and :meth:`MPCAgent.planning_state` (default: the observation as a model state) are what the
MBRL baseline (:mod:`kinder_bench.baselines.mbrl`) overrides to plan on a learned model.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_bench.agents.base import Agent

FloatArray = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class MPCArgs:
    """Arguments of the predictive-sampling MPC baseline (defaults: the paper's configuration)."""

    horizon: int = 100
    """Length of every candidate action sequence, in env steps."""
    num_rollouts: int = 10
    """Candidates scored per solve: the nominal and ``num_rollouts - 1`` perturbed copies."""
    noise_fraction: float = 1.0
    """Std of the perturbation per action dimension, as a fraction of that dimension's range."""
    num_control_points: int = 10
    """Control points of the piecewise-linear action spline that spans the horizon."""
    warm_start: bool = True
    """Start each solve from the previous best shifted forward (else from fresh random points)."""
    replan_interval: int = 1
    """Solve every this many env steps; in between, execute the stored best sequence."""

    def __post_init__(self) -> None:
        checks = [
            (self.horizon >= 1, "horizon must be >= 1"),
            (self.num_rollouts >= 1, "num_rollouts must be >= 1"),
            (self.noise_fraction >= 0, "noise_fraction must be >= 0"),
            (self.num_control_points >= 2, "num_control_points must be >= 2"),
            (1 <= self.replan_interval <= self.horizon, "replan_interval must be in [1, horizon]"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ValueError(f"MPCArgs: {msg}, got {self}")


def interpolation_matrix(knot_times: FloatArray, times: FloatArray) -> FloatArray:
    """``W`` with ``W @ points`` = the piecewise-linear spline through ``(knot_times, points)``
    evaluated at ``times`` (times outside the knots hold the end points)."""
    eye = np.eye(len(knot_times))
    columns = [np.interp(times, knot_times, eye[k]) for k in range(len(knot_times))]
    return np.stack(columns, axis=1).astype(np.float64)


class MPCAgent(Agent[MPCArgs]):
    """Predictive-sampling MPC on the env's ground-truth model (see the module docstring)."""

    name = "mpc"
    Args = MPCArgs

    def __init__(self, env: gymnasium.Env[Any, Any], args: MPCArgs, seed: int) -> None:
        super().__init__(env, args, seed)
        low = self.action_space.low.astype(np.float64)
        high = self.action_space.high.astype(np.float64)
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
            raise ValueError(f"MPCAgent needs finite action bounds, got {self.action_space}")
        self._low, self._high = low, high
        self._noise_std = args.noise_fraction * (high - low)
        h, k = args.horizon, args.num_control_points
        self._knots = np.linspace(0.0, float(h), k)
        self._weights = interpolation_matrix(self._knots, np.arange(h, dtype=np.float64))
        self._model = self.model
        self._solution: FloatArray | None = None  # control points of the best candidate
        self._plan: FloatArray | None = None  # its actions, one per step
        self._since_solve = 0
        self.num_solves = 0
        self.num_model_steps = 0

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        self._solution = None
        self._plan = None
        self._since_solve = 0

    def act(self, obs: Any) -> FloatArray:
        if self._plan is None or self._since_solve >= self.args.replan_interval:
            self._solve(self.planning_state(obs))
        assert self._plan is not None
        action: FloatArray = self._plan[self._since_solve].copy()
        self._since_solve += 1
        return action

    def planning_state(self, obs: Any) -> Any:
        """The state rollouts start from: the observation as a model state. Subclasses that
        plan on another model (MBRL) return that model's state."""
        return self.observed_state(obs)

    def transition(self, state: Any, action: FloatArray) -> tuple[Any, float, bool]:
        """One rollout step, ``(next_state, reward, terminated)``: the env model's pure
        ``transition``. Subclasses plug in a learned model here (MBRL)."""
        return self._model.transition(state, action)

    def _nominal(self) -> FloatArray:
        a, shift = self.args, self._since_solve
        if a.warm_start and self._solution is not None and shift < a.horizon:
            return interpolation_matrix(self._knots, self._knots + shift) @ self._solution
        points = self.rng.standard_normal((a.num_control_points, len(self._low)))
        return np.clip(points, self._low, self._high)

    def _solve(self, state: Any) -> None:
        a = self.args
        nominal = self._nominal()
        noise = self.rng.standard_normal((a.num_rollouts - 1, *nominal.shape)) * self._noise_std
        candidates = np.clip(
            np.concatenate([nominal[None], nominal[None] + noise]), self._low, self._high
        )
        plans = np.einsum("hk,nka->nha", self._weights, candidates)
        costs = np.array([self._rollout_cost(state, plan) for plan in plans])
        best = int(np.argmin(costs))  # first minimum: ties keep the nominal
        self._solution = candidates[best]
        self._plan = plans[best]
        self._since_solve = 0
        self.num_solves += 1

    def _rollout_cost(self, state: Any, plan: FloatArray) -> float:
        cost = 0.0
        transition = self.transition
        for t, action in enumerate(plan):
            state, reward, terminated = transition(state, action)
            cost -= reward
            if terminated:
                self.num_model_steps += t + 1
                return cost
        self.num_model_steps += len(plan)
        return cost
