"""OMPL-backed motion planning with our own collision checkers."""

from __future__ import annotations

import math
import time

import numpy as np

from kinder_gym.motion_planning import (
    cap_clock,
    interpolate_path,
    path_valid,
    plan_joint_space,
    plan_se2,
    timeouts_counted_by,
    wrap_angle,
)


def _wall_with_gap(q: np.ndarray) -> bool:
    """A point robot; a wall at x in [1.0, 1.1] with a gap for y in [1.0, 1.3]."""
    x, y = q[0], q[1]
    return not (1.0 <= x <= 1.1 and (y < 1.0 or y > 1.3))


def test_se2_plan_goes_through_the_gap_and_is_deterministic() -> None:
    start, goal = [0.3, 0.3, 0.0], [2.3, 0.3, 1.0]
    bounds = ((0.0, 2.5), (0.0, 2.5))
    path = plan_se2(start, goal, _wall_with_gap, bounds, seed=3)
    assert path is not None and len(path) > 2
    assert np.allclose(path[0], start) and np.allclose(path[-1], goal)
    assert path_valid(path, _wall_with_gap, np.array([0.01, 0.01, 0.05]), wrap_dims=(2,))
    again = plan_se2(start, goal, _wall_with_gap, bounds, seed=3)
    assert again is not None and all(np.array_equal(a, b) for a, b in zip(path, again))


def test_attempt_timeouts_count_the_clock_in_force() -> None:
    """RRT-Connect attempts stop after ``timeout`` seconds of :func:`cap_clock`: a clock that
    jumps 10 s per reading ends every attempt at once, a stopped one never does, and the
    default (wall-clock) comes back after the block."""
    start, goal = [0.3, 0.3, 0.0], [2.3, 0.3, 1.0]
    bounds = ((0.0, 2.5), (0.0, 2.5))
    ticks = iter(range(0, 10**6, 10))
    with timeouts_counted_by(lambda: float(next(ticks))):
        assert plan_se2(start, goal, _wall_with_gap, bounds, seed=3, timeout=1.0) is None
    with timeouts_counted_by(lambda: 0.0):
        stopped = plan_se2(start, goal, _wall_with_gap, bounds, seed=3, timeout=1e-9)
    assert stopped is not None and all(
        np.array_equal(a, b)
        for a, b in zip(stopped, plan_se2(start, goal, _wall_with_gap, bounds, seed=3))
    )
    assert cap_clock() is time.perf_counter


def test_straight_line_when_free_and_none_when_blocked() -> None:
    bounds = ((0.0, 2.5), (0.0, 2.5))
    free = plan_se2([0.2, 0.2, 0.0], [0.8, 0.9, 3.0], lambda q: True, bounds)
    assert free is not None and len(free) == 2
    blocked = plan_se2(
        [0.3, 0.3, 0.0],
        [2.3, 0.3, 0.0],
        lambda q: not 1.0 <= q[0] <= 1.1,
        bounds,
        timeout=0.2,
        max_iterations=500,
    )
    assert blocked is None
    assert plan_se2([1.05, 0.1, 0.0], [2.0, 2.0, 0.0], _wall_with_gap, bounds) is None


def test_interpolation_respects_step_bounds_and_wraps_angles() -> None:
    path = [np.array([0.0, 0.0, 3.0]), np.array([0.3, -0.1, -3.0])]
    dense = interpolate_path(path, [0.05, 0.05, math.pi / 16], wrap_dims=(2,))
    steps = np.diff(np.array(dense), axis=0)
    steps[:, 2] = [wrap_angle(float(a)) for a in steps[:, 2]]
    assert np.all(np.abs(steps[:, :2]) <= 0.05 + 1e-12)
    # The angle goes the short way round (through ±π), not 6 radians the long way.
    assert np.sum(np.abs(steps[:, 2])) < 0.3
    assert np.allclose(dense[-1], [0.3, -0.1, -3.0])


def test_joint_space_plan_avoids_a_ball() -> None:
    def valid(q: np.ndarray) -> bool:
        return float(np.linalg.norm(q[:2])) > 0.3

    path = plan_joint_space([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], valid, [-2.0] * 3, [2.0] * 3, seed=1)
    assert path is not None
    assert path_valid(path, valid, np.full(3, 0.05))
