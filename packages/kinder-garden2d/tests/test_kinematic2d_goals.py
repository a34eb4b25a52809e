"""Goal predicates on hand-built states that do and do not satisfy them."""

from __future__ import annotations

import numpy as np
import pytest

from kinder_garden2d.kinematic2d.clutteredretrieval2d import ClutteredRetrieval2DEnv
from kinder_garden2d.kinematic2d.clutteredstorage2d import ClutteredStorage2DEnv
from kinder_garden2d.kinematic2d.motion2d import Motion2DEnv
from kinder_garden2d.kinematic2d.object_types import BUTTON_GREEN
from kinder_garden2d.kinematic2d.obstruction2d import Obstruction2DEnv
from kinder_garden2d.kinematic2d.predicates import (
    all_pressed,
    is_inside,
    is_inside_shelf,
    is_on,
    is_pressed,
    rectangle_vertices,
    robot_in_region,
)
from kinder_garden2d.kinematic2d.pushpullhook2d import PushPullHook2DEnv
from kinder_garden2d.kinematic2d.stickbutton2d import StickButton2DEnv


def set_pose(state, obj, x, y, theta=0.0):  # type: ignore[no-untyped-def]
    state.set(obj, "x", x)
    state.set(obj, "y", y)
    state.set(obj, "theta", theta)


def test_robot_in_region() -> None:
    env = Motion2DEnv(num_passages=2)
    s, _ = env.reset(seed=0)
    r, g = env.robot, env.target_region
    gx, gy = s.get(g, "x"), s.get(g, "y")
    set_pose(s, r, gx + 0.1, gy + 0.2)
    assert robot_in_region(s, r, g) and env.goal_reached(s)
    set_pose(s, r, gx + 0.25, gy + 0.25)  # the far corner: closed region
    assert env.goal_reached(s)
    set_pose(s, r, gx - 0.01, gy + 0.1)  # base overlaps the region, centre outside
    assert not robot_in_region(s, r, g) and not env.goal_reached(s)


def test_is_on_with_tolerance() -> None:
    env = Obstruction2DEnv(num_obstructions=0)
    s, _ = env.reset(seed=0)
    b, t = env.target_block, env.target_surface
    s.set(t, "x", 0.5)
    s.set(t, "width", 0.2)
    s.set(b, "width", 0.15)
    set_pose(s, b, 0.52, 0.1 + 1e-6)
    assert is_on(s, b, t) and env.goal_reached(s)
    set_pose(s, b, 0.52, 0.1 + 0.02)  # hovering, but within the 0.025 tolerance
    assert is_on(s, b, t)
    set_pose(s, b, 0.52, 0.1 + 0.03)  # too high
    assert not is_on(s, b, t) and not env.goal_reached(s)
    set_pose(s, b, 0.6, 0.1 + 1e-6)  # sticks out on the right
    assert not is_on(s, b, t)
    set_pose(s, b, 0.52, 0.1 + 1e-6, 0.05)  # slightly tilted: lowest vertices still on it
    assert is_on(s, b, t)
    assert is_on(s, b, t, tol=0.025) and not is_on(s, b, t, tol=0.2)


def test_is_inside_rotated_region() -> None:
    env = ClutteredRetrieval2DEnv(num_obstructions=1)
    s, _ = env.reset(seed=0)
    b, g = env.target_block, env.target_region
    set_pose(s, g, 1.0, 1.0, 0.5)
    # Put the block's centre on the region's centre with the same orientation.
    gv = rectangle_vertices(s, g)
    centre = gv.mean(axis=0)
    c, sn = np.cos(0.5), np.sin(0.5)
    set_pose(s, b, centre[0] - c * 0.07 + sn * 0.07, centre[1] - sn * 0.07 - c * 0.07, 0.5)
    np.testing.assert_allclose(rectangle_vertices(s, b).mean(axis=0), centre)
    assert is_inside(s, b, g) and env.goal_reached(s)
    set_pose(s, b, s.get(b, "x"), s.get(b, "y"), 0.5 + np.pi / 4)  # turned 45°: corners out
    assert not is_inside(s, b, g)
    set_pose(s, b, centre[0] + 0.1, centre[1], 0.5)  # off to the side
    assert not env.goal_reached(s)


def test_is_inside_shelf() -> None:
    env = ClutteredStorage2DEnv(num_blocks=3)
    s, _ = env.reset(seed=0)
    shelf = env.shelf
    x1, y1 = s.get(shelf, "x1"), s.get(shelf, "y1")
    stored, loose = env.blocks[0], env.blocks[2]
    assert is_inside_shelf(s, stored, shelf)  # the reset stores n // 2 = 1 block
    assert not is_inside_shelf(s, loose, shelf) and not env.goal_reached(s)
    # Standing upright (turned 90° about the anchor) inside the opening.
    for i, block in enumerate(env.blocks):
        set_pose(s, block, x1 + 0.05 + 0.06 * i, y1 + 0.02, np.pi / 2)
    assert all(is_inside_shelf(s, b, shelf) for b in env.blocks) and env.goal_reached(s)
    set_pose(s, loose, x1 + 0.2, y1 + 0.2, np.pi / 2)  # pokes out of the top
    assert not env.goal_reached(s)


def _press(state, button) -> None:  # type: ignore[no-untyped-def]
    for f, v in zip(("color_r", "color_g", "color_b"), BUTTON_GREEN):
        state.set(button, f, v)


def test_all_buttons_pressed() -> None:
    env = StickButton2DEnv(num_buttons=3)
    s, _ = env.reset(seed=0)
    assert not any(is_pressed(s, b) for b in env.buttons)
    for b in env.buttons[:2]:
        _press(s, b)
    assert not all_pressed(s, env.buttons) and not env.goal_reached(s)
    _press(s, env.buttons[2])
    assert all_pressed(s, env.buttons) and env.goal_reached(s)


def test_pushpullhook_goal_needs_both_buttons() -> None:
    env = PushPullHook2DEnv()
    s, _ = env.reset(seed=0)
    _press(s, env.movable_button)
    assert not env.goal_reached(s)
    _press(s, env.target_button)
    assert env.goal_reached(s)


@pytest.mark.parametrize(
    ("env", "reward_on_goal"),
    [(StickButton2DEnv(num_buttons=1), 0.0), (Motion2DEnv(num_passages=0), -1.0)],
)
def test_reward_on_the_goal_step(env, reward_on_goal: float) -> None:  # type: ignore[no-untyped-def]
    s, _ = env.reset(seed=0)
    if isinstance(env, StickButton2DEnv):
        b = env.buttons[0]
        set_pose(s, b, s.get(env.robot, "x") + 0.12, s.get(env.robot, "y"))
        set_pose(s, env.robot, s.get(env.robot, "x"), s.get(env.robot, "y"), np.pi)
    else:
        g = env.target_region
        set_pose(s, env.robot, s.get(g, "x") - 0.02, s.get(g, "y") + 0.1)
    _nxt, reward, term = env.transition(s, np.array([0.04, 0.0, 0.0, 0.0, 0.0]))
    assert term and reward == reward_on_goal
