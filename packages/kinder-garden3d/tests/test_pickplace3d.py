"""PickPlace3D-o1 (upstream 0.2.5's mobile-manipulator pick-and-place on the floor): the reset
layout of upstream's task file and its goal region (upstream's box widened by its 5 cm floor
margin, at most 10 cm up)."""

from __future__ import annotations

import math
from typing import Any

import pytest

import kinder_core
import kinder_garden3d  # noqa: F401  (registers the ids)

ENV_ID = "kinder/PickPlace3D-o1-v0"


@pytest.fixture(scope="module")
def env() -> Any:
    env = kinder_core.make_object_centric(ENV_ID)
    yield env
    env.close()


def test_reset_follows_upstreams_task_file(env: Any) -> None:
    assert env.action_space.shape == (11,)
    robot, cube = env.objects["robot"], env.objects["cube1"]
    for seed in range(1000, 1010):
        state, info = env.reset(seed=seed)
        assert info["success"] is False
        assert -0.25 <= state.get(robot, "pos_base_x") <= -0.15
        assert -0.05 <= state.get(robot, "pos_base_y") <= 0.05
        assert abs(state.get(robot, "pos_base_rot")) <= math.radians(5.0) + 1e-6
        # The 4 cm cube rests on the floor in its region.
        assert state.get(cube, "bb_z") == pytest.approx(0.04)
        assert state.get(cube, "z") == pytest.approx(0.02, abs=2e-3)
        assert 0.4 <= state.get(cube, "x") <= 0.6 and -0.1 <= state.get(cube, "y") <= 0.1


@pytest.mark.parametrize(
    ("x", "y", "z", "inside"),
    [
        (1.1, 0.5, 0.02, True),  # upstream's region
        (0.96, 0.36, 0.02, True),  # within the 5 cm margin
        (0.94, 0.5, 0.02, False),
        (1.1, 0.66, 0.02, False),
        (1.1, 0.5, 0.11, False),  # more than 10 cm up
    ],
)
def test_the_goal_is_upstreams_floor_region(
    env: Any, x: float, y: float, z: float, inside: bool
) -> None:
    state, _ = env.reset(seed=1000)
    cube = env.objects["cube1"]
    for feature, value in (("x", x), ("y", y), ("z", z)):
        state.set(cube, feature, value)
    assert env.goal_reached(state) is inside
