"""MPC by predictive sampling (Howell et al. 2022), rolled out on the env's own model.

The paper's "MPC" baseline (KinDER spec, baselines §3.1). Every solve scores ``num_rollouts``
candidate action sequences over ``horizon`` steps on ``env.unwrapped.transition`` (pure: the live
episode is never touched) with the env's own (sparse) reward, and keeps the best one:

* A candidate is a piecewise-linear spline through control points in action space; the action at
  step ``t`` (``t`` = 0 … ``horizon`` − 1) is the spline's value at ``t``, and times past the
  spline's end hold its last point.
* The nominal candidate is the previous best advanced in time (warm start), or, on the first solve
  or without warm start, ``num_control_points`` points drawn from a standard normal, clipped to the
  action box and spread evenly over ``horizon`` steps. How the previous best is advanced is
  ``warm_start_shift``:

  - ``"one_step"`` (default; upstream's ``prpl_utils`` 0.0.7 ``PredictiveSamplingSolver``, which
    made the paper's figures): by one time unit at every solve, whatever the replan interval, so
    the spline's duration shrinks by one per solve (its control points keep their times, and it
    holds its last point for the rest of the horizon); once that duration is 1 or less, the next
    solve starts from fresh random points. The control points are stored in the action space's
    dtype, as upstream's spline stores them.
  - ``"executed"``: by the steps executed since it was solved, re-spread over the whole horizon
    (a receding horizon of constant length; our earlier default, kept as an option).

* The other ``num_rollouts - 1`` candidates are ``num_control_points`` points spread evenly over
  the nominal's duration (the nominal's values there) plus Gaussian noise of per-dimension std
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

**Fast rollouts** (``batched=True``, the default; the costs, hence every action, are exactly the
plain loop's): a solve scores its candidates through :meth:`MPCAgent.fast_model` when there is
one, a :class:`RolloutModel` that rolls all candidates out together:

* Kinematic2D families with a batched world (all of them today: Motion2D, Obstruction2D,
  ClutteredRetrieval2D, ClutteredStorage2D, StickButton2D, PushPullHook2D;
  :mod:`kinder_garden2d.kinematic2d.batched`, bit-for-bit the single env's transition, goal and
  reward) step all candidates in lockstep as one ``(N, D)`` array (:class:`BatchedWorldRollouts`).
* Dynamic3D (MuJoCo) rolls each candidate out on its own copy of the env in a thread pool
  (:class:`ThreadedCloneRollouts`): MuJoCo's ``mj_step`` releases the GIL, so the candidates'
  physics runs on as many cores as there are. ``mujoco.rollout`` is not used: its states leave
  out the fixtures' mocap poses and the solver's warm start, which this env's states carry, and
  the env's controller (``ctrl = qpos + delta`` every env step) rules out one open-loop rollout
  over the horizon; the copies run the env's own ``transition``, exact by construction.
* Every other env (Dynamic2D, Kinematic3D) keeps the plain loop.
"""

from __future__ import annotations

import dataclasses
import pickle
import sys
import weakref
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Protocol

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_bench.agents.base import Agent
from kinder_bench.evaluation.executors import available_cpus
from kinder_core import ObjectCentricEnv, ObjectCentricState

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


#: The values of ``MPCArgs.warm_start_shift``.
WARM_START_SHIFTS = ("one_step", "executed")


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
    warm_start_shift: str = "one_step"
    """How the warm start advances the previous best (see the module docstring): ``"one_step"``,
    upstream's (one time unit per solve, the spline's duration shrinking), or ``"executed"``
    (the steps executed since it was solved, over the whole horizon)."""
    batched: bool = True
    """Roll the candidates out together where the model allows it (same costs, so same actions,
    as the plain one-by-one loop; see the module docstring)."""
    rollout_threads: int = 0
    """Threads of the Dynamic3D fast path (0: one per CPU this process may use, at most one per
    candidate). With a process pool that already runs one episode per core, 1 avoids
    oversubscribing the cores."""

    def __post_init__(self) -> None:
        checks = [
            (self.horizon >= 1, "horizon must be >= 1"),
            (self.num_rollouts >= 1, "num_rollouts must be >= 1"),
            (self.noise_fraction >= 0, "noise_fraction must be >= 0"),
            (self.num_control_points >= 2, "num_control_points must be >= 2"),
            (1 <= self.replan_interval <= self.horizon, "replan_interval must be in [1, horizon]"),
            (self.rollout_threads >= 0, "rollout_threads must be >= 0"),
            (
                self.warm_start_shift in WARM_START_SHIFTS,
                f"warm_start_shift must be one of {WARM_START_SHIFTS}",
            ),
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


def advance_spline(
    times: FloatArray, points: FloatArray, shift: float
) -> tuple[FloatArray, FloatArray]:
    """The piecewise-linear spline through ``(times, points)`` from time ``shift`` on, re-timed
    to start at 0: its value at ``shift`` followed by the control points after it, which keep
    their spacing (the sub-trajectory ``[shift, end]`` of upstream's ``Trajectory``, whose
    segments shorter than 1e-10 are dropped)."""
    later = times > shift + 1e-10
    new_times = np.concatenate([[0.0], times[later] - shift])
    start = interpolation_matrix(times, np.array([shift])) @ points
    new_points = np.concatenate([start.astype(points.dtype), points[later]])
    return new_times, new_points


class RolloutModel(Protocol):
    """Scores many candidate action sequences from one start state at once."""

    def costs(self, state: Any, plans: FloatArray) -> tuple[FloatArray, int]:
        """``(costs, model_steps)``: for every plan of ``plans`` ``(N, H, A)`` rolled out from
        ``state``, −(sum of rewards up to and including the first terminating step), and the
        number of model steps taken (a rollout stops at its first terminating step)."""
        ...


#: One lockstep step: states ``(N, D)`` and actions ``(N, A)`` to next states, rewards ``(N,)``
#: and terminated flags ``(N,)``.
BatchStep = Callable[[FloatArray, FloatArray], tuple[FloatArray, FloatArray, BoolArray]]


def lockstep_costs(step: BatchStep, start: FloatArray, plans: FloatArray) -> tuple[FloatArray, int]:
    """Roll every plan out from ``start`` ``(D,)`` in lockstep (see :class:`RolloutModel`).

    Rollouts that terminated are dropped from the batch, so each plan's cost sums exactly the
    rewards the plain one-by-one loop sums, in the same order.
    """
    n, horizon = plans.shape[:2]
    costs = np.zeros(n)
    rows = np.arange(n)
    states = np.repeat(start[None], n, axis=0)
    steps = 0
    for t in range(horizon):
        states, rewards, terminated = step(states, plans[rows, t])
        costs[rows] -= rewards
        steps += len(rows)
        keep = ~terminated
        rows, states = rows[keep], states[keep]
        if not rows.size:
            break
    return costs, steps


def _instance_of(obj: object, module: str, name: str) -> bool:
    """``isinstance(obj, module.name)`` without importing ``module`` (an env of that class has
    imported it already)."""
    cls = getattr(sys.modules.get(module), name, None)
    return isinstance(cls, type) and isinstance(obj, cls)


_STATIC_TABLES = ("static_obbs", "static_circles", "static_obb_aabb", "static_circ_aabb")


class BatchedWorldRollouts:
    """Candidates of a Kinematic2D env stepped together on its family's batched world (whose
    transition, goal and reward equal the single env's bit for bit)."""

    def __init__(self, world: Any, low: FloatArray, high: FloatArray) -> None:
        self.world = world
        self._low, self._high = low, high

    def costs(self, state: Any, plans: FloatArray) -> tuple[FloatArray, int]:
        if not isinstance(state, ObjectCentricState):
            raise TypeError(f"BatchedWorldRollouts needs an ObjectCentricState, got {state!r}")
        world = self.world
        # Static bodies are the same for every candidate: build them once for row 0, then give
        # the world as many identical rows as there are live rollouts at each step.
        world.allocate(1)
        world.load_statics(np.zeros(1, dtype=np.intp), state.data[None])
        tables = {name: getattr(world, name) for name in _STATIC_TABLES}

        def step(data: FloatArray, actions: FloatArray) -> tuple[FloatArray, FloatArray, BoolArray]:
            for name, table in tables.items():
                setattr(world, name, np.repeat(table, len(data), axis=0))
            nxt: FloatArray = world.transition(data, np.clip(actions, self._low, self._high))
            terminated: BoolArray = world.goal(nxt)
            rewards: FloatArray = world.reward(terminated)
            return nxt, rewards, terminated

        return lockstep_costs(step, state.data, plans)


class _ClonePool:
    """Copies of one env (rebuilt from its pickle) and the threads that roll them out."""

    def __init__(self) -> None:
        self.clones: list[ObjectCentricEnv] = []
        self.pool: ThreadPoolExecutor | None = None
        self.threads = 1

    def ensure(self, env: ObjectCentricEnv, clones: int, threads: int) -> None:
        """At least ``clones`` copies of ``env`` and a pool of exactly ``threads`` threads (the
        pool holds no reference to ``env``, so that the weak registry below can drop it)."""
        while len(self.clones) < clones:
            clone = pickle.loads(pickle.dumps(env))
            assert isinstance(clone, ObjectCentricEnv)
            self.clones.append(clone)
        if threads != self.threads:
            if self.pool is not None:
                self.pool.shutdown()
            self.pool = ThreadPoolExecutor(threads) if threads > 1 else None
            self.threads = threads


#: Per env, the copies the Dynamic3D fast path rolls candidates out on (kept while the env lives,
#: so that the agents the runner makes afresh every episode reuse them).
_POOLS: weakref.WeakKeyDictionary[ObjectCentricEnv, _ClonePool] = weakref.WeakKeyDictionary()


class ThreadedCloneRollouts:
    """Each candidate rolled out on its own copy of the env, the copies in a thread pool.

    A copy is the env rebuilt from its pickle (same configuration, same MuJoCo model), and its
    ``transition`` is the env's own, so every cost equals the plain loop's; only the wall-clock
    time changes, because MuJoCo's ``mj_step`` releases the GIL.
    """

    def __init__(self, env: ObjectCentricEnv, num_rollouts: int, threads: int) -> None:
        pool = _POOLS.get(env)
        if pool is None:
            pool = _POOLS[env] = _ClonePool()
        self._pool = pool
        self.threads = max(1, min(threads or available_cpus(), num_rollouts))
        self._pool.ensure(env, num_rollouts, self.threads)

    def costs(self, state: Any, plans: FloatArray) -> tuple[FloatArray, int]:
        clones = self._pool.clones

        def one(i: int) -> tuple[float, int]:
            return plain_cost(clones[i].transition, state, plans[i])

        jobs = range(len(plans))
        pool = self._pool.pool
        results = list(pool.map(one, jobs) if pool is not None else map(one, jobs))
        return np.array([c for c, _ in results]), sum(k for _, k in results)


def plain_cost(
    transition: Callable[[Any, FloatArray], tuple[Any, float, bool]],
    state: Any,
    plan: FloatArray,
) -> tuple[float, int]:
    """``(cost, model_steps)`` of one plan rolled out step by step on ``transition``."""
    cost = 0.0
    for t, action in enumerate(plan):
        state, reward, terminated = transition(state, action)
        cost -= reward
        if terminated:
            return cost, t + 1
    return cost, len(plan)


def batched_world_of(env: ObjectCentricEnv) -> Any:
    """The Kinematic2D family's batched world of ``env`` (``transition``, ``goal`` and
    ``reward`` over ``(N, D)`` state arrays, bit for bit the single env's), or None (another kind
    of env, or a family without one)."""
    if not _instance_of(env, "kinder_garden2d.kinematic2d.base", "Kinematic2DEnv"):
        return None
    from kinder_garden2d.kinematic2d.batched.families import batched_world

    try:
        return batched_world(env)  # type: ignore[arg-type]
    except ValueError:  # a family without a batched world
        return None


def env_fast_model(
    env: ObjectCentricEnv, args: MPCArgs, low: FloatArray, high: FloatArray
) -> RolloutModel | None:
    """The fast rollout model of an env (see the module docstring), or None (plain loop)."""
    if _instance_of(env, "kinder_garden3d.dynamic3d.env", "Dynamic3DEnv"):
        return ThreadedCloneRollouts(env, args.num_rollouts, args.rollout_threads)
    world = batched_world_of(env)
    return None if world is None else BatchedWorldRollouts(world, low, high)


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
        self._fast = self.fast_model() if args.batched else None
        self._dtype = self.action_space.dtype
        self._solution: FloatArray | None = None  # control points of the best candidate
        self._solution_times: FloatArray | None = None  # their times ("one_step" warm start)
        self._plan: FloatArray | None = None  # its actions, one per step
        self._since_solve = 0
        self.num_solves = 0
        self.num_model_steps = 0

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        self._solution = None
        self._solution_times = None
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

    def fast_model(self) -> RolloutModel | None:
        """What scores the candidates all at once with the same costs as :meth:`transition`'s
        one-by-one loop, or None (the plain loop). Subclasses with another model override it."""
        return env_fast_model(self._model, self.args, self._low, self._high)

    def rollout_costs(self, state: Any, plans: FloatArray) -> FloatArray:
        """The cost of every plan ``(N, H, A)`` from ``state`` (fast model or plain loop)."""
        if self._fast is not None:
            costs, steps = self._fast.costs(state, plans)
            self.num_model_steps += steps
            return costs
        return np.array([self._rollout_cost(state, plan) for plan in plans])

    def _nominal(self) -> FloatArray:
        a, shift = self.args, self._since_solve
        if a.warm_start and self._solution is not None and shift < a.horizon:
            return interpolation_matrix(self._knots, self._knots + shift) @ self._solution
        points = self.rng.standard_normal((a.num_control_points, len(self._low)))
        return np.clip(points, self._low, self._high)

    def _solve(self, state: Any) -> None:
        if self.args.warm_start_shift == "one_step":
            self._solve_one_step(state)
            return
        a = self.args
        nominal = self._nominal()
        noise = self.rng.standard_normal((a.num_rollouts - 1, *nominal.shape)) * self._noise_std
        candidates = np.clip(
            np.concatenate([nominal[None], nominal[None] + noise]), self._low, self._high
        )
        plans = np.einsum("hk,nka->nha", self._weights, candidates)
        costs = self.rollout_costs(state, plans)
        best = int(np.argmin(costs))  # first minimum: ties keep the nominal
        self._solution = candidates[best]
        self._plan = plans[best]
        self._since_solve = 0
        self.num_solves += 1

    def _solve_one_step(self, state: Any) -> None:
        """One solve with upstream's warm start (``warm_start_shift="one_step"``)."""
        a = self.args
        times, points = self._solution_times, self._solution
        if a.warm_start and times is not None and points is not None and times[-1] > 1 + 1e-6:
            times, points = advance_spline(times, points, 1.0)
        else:
            times = np.linspace(0.0, float(a.horizon), a.num_control_points)
            draw = self.rng.standard_normal((a.num_control_points, len(self._low)))
            points = np.clip(draw, self._low, self._high).astype(self._dtype)
        knots = np.linspace(0.0, float(times[-1]), a.num_control_points)
        at_knots = interpolation_matrix(times, knots) @ points
        noise = self.rng.standard_normal((a.num_rollouts - 1, *at_knots.shape)) * self._noise_std
        samples = np.clip(at_knots[None] + noise, self._low, self._high).astype(self._dtype)
        steps = np.arange(a.horizon, dtype=np.float64)
        plans = np.concatenate(
            [
                (interpolation_matrix(times, steps) @ points)[None],
                np.einsum("hk,nka->nha", interpolation_matrix(knots, steps), samples),
            ]
        )
        costs = self.rollout_costs(state, plans)
        best = int(np.argmin(costs))  # first minimum: ties keep the nominal
        if best == 0:
            self._solution_times, self._solution = times, points
        else:
            self._solution_times, self._solution = knots, samples[best - 1]
        self._plan = plans[best]
        self._since_solve = 0
        self.num_solves += 1

    def _rollout_cost(self, state: Any, plan: FloatArray) -> float:
        cost, steps = plain_cost(self.transition, state, plan)
        self.num_model_steps += steps
        return cost
