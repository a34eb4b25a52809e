"""MPC's warm start: upstream's (the previous best advanced by one time unit per solve, its
spline's duration shrinking) by default, and the receding horizon as an option."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from kinder_bench.baselines.mpc import MPCAgent, MPCArgs, advance_spline
from kinder_bench.evaluation.envs import make_env


class _TiedCosts(MPCAgent):
    """Every candidate costs the same, so every solve keeps its nominal: what the warm start
    makes of the previous best is then the whole plan."""

    name = "mpc_tied_costs_test"

    def rollout_costs(self, state: Any, plans: np.ndarray) -> np.ndarray:
        return np.zeros(len(plans))


def _solves(toy_id: str, solves: int, **args: Any) -> tuple[list[np.ndarray], list[float]]:
    """The plan and the stored solution's duration after each of ``solves`` solves."""
    env = make_env(toy_id)
    agent = _TiedCosts(env, MPCArgs(**args), seed=1000)
    obs, info = env.reset(seed=1000)
    agent.reset(obs, info)
    plans, durations = [], []
    for _ in range(solves):
        agent._solve(agent.planning_state(obs))
        assert agent._plan is not None and agent._solution_times is not None
        plans.append(agent._plan.copy())
        durations.append(float(agent._solution_times[-1]))
    return plans, durations


def test_advance_spline_keeps_the_later_control_points_and_their_spacing() -> None:
    times = np.array([0.0, 5.0, 10.0])
    points = np.array([[0.0, 10.0], [5.0, 0.0], [10.0, 10.0]], dtype=np.float32)
    new_times, new_points = advance_spline(times, points, 1.0)
    np.testing.assert_array_equal(new_times, [0.0, 4.0, 9.0])
    np.testing.assert_array_equal(new_points, [[1.0, 8.0], [5.0, 0.0], [10.0, 10.0]])
    assert new_points.dtype == np.float32
    # A control point exactly at the shift becomes the start, not a zero-length segment.
    again_times, again_points = advance_spline(new_times, new_points, 4.0)
    np.testing.assert_array_equal(again_times, [0.0, 5.0])
    np.testing.assert_array_equal(again_points, [[5.0, 0.0], [10.0, 10.0]])


@pytest.mark.parametrize("replan_interval", [1, 3])
def test_upstream_warm_start_advances_one_step_per_solve(toy_id: str, replan_interval: int):
    """Whatever the replan interval, each solve's nominal is the previous best from one time
    unit on, so the spline's duration shrinks by one per solve; the horizon's tail holds the
    last point."""
    horizon = 12
    plans, durations = _solves(toy_id, 5, horizon=horizon, num_rollouts=4,
                               num_control_points=4, replan_interval=replan_interval)  # fmt: skip
    assert durations == [12.0, 11.0, 10.0, 9.0, 8.0]
    for before, after, duration in zip(plans, plans[1:], durations[1:], strict=False):
        np.testing.assert_allclose(after[: horizon - 1], before[1:], atol=1e-6)
        np.testing.assert_array_equal(after[int(duration) :], after[[-1]].repeat(
            horizon - int(duration), axis=0))  # fmt: skip


def test_upstream_warm_start_restarts_once_the_spline_is_one_step_long(toy_id: str) -> None:
    plans, durations = _solves(toy_id, 6, horizon=5, num_rollouts=3, num_control_points=3)
    assert durations == [5.0, 4.0, 3.0, 2.0, 1.0, 5.0]
    assert not np.allclose(plans[5][:4], plans[4][1:5])  # fresh random points, not a shift


def test_executed_warm_start_keeps_the_whole_horizon(toy_id: str) -> None:
    """The receding-horizon option advances by the executed steps and re-spreads the control
    points over the whole horizon, so the plan does not end in a held tail."""
    horizon = 12
    env = make_env(toy_id)
    args = MPCArgs(horizon=horizon, num_rollouts=4, num_control_points=4, replan_interval=3,
                   warm_start_shift="executed")  # fmt: skip
    agent = _TiedCosts(env, args, seed=1000)
    obs, info = env.reset(seed=1000)
    agent.reset(obs, info)
    agent._solve(agent.planning_state(obs))
    first = agent._plan.copy()  # type: ignore[union-attr]
    agent._since_solve = 3
    agent._solve(agent.planning_state(obs))
    second = agent._plan
    assert second is not None
    knots = np.linspace(0.0, horizon, 4)
    inside = knots[knots + 3 < horizon - 1].astype(int)  # knots whose shifted time is a step
    np.testing.assert_allclose(second[inside], first[inside + 3], atol=1e-9)


def test_warm_start_shift_is_validated() -> None:
    with pytest.raises(ValueError, match="warm_start_shift must be one of"):
        MPCArgs(warm_start_shift="two_steps")
