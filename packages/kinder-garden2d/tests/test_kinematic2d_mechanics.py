"""The CRV robot's mechanics on hand-built states: motion, collision revert, suction, buttons,
hook pushing."""

from __future__ import annotations

import numpy as np
import pytest

from kinder_core import ObjectCentricState
from kinder_garden2d.kinematic2d.base import Kinematic2DEnv
from kinder_garden2d.kinematic2d.crv import robot_geometry
from kinder_garden2d.kinematic2d.motion2d import Motion2DEnv
from kinder_garden2d.kinematic2d.object_types import BUTTON_GREEN, BUTTON_RED
from kinder_garden2d.kinematic2d.obstruction2d import Obstruction2DEnv
from kinder_garden2d.kinematic2d.predicates import is_pressed
from kinder_garden2d.kinematic2d.pushpullhook2d import PushPullHook2DEnv
from kinder_garden2d.kinematic2d.stickbutton2d import StickButton2DEnv

STILL = np.array([0.0, 0.0, 0.0, 0.0, 0.0])


def act(dx: float = 0.0, dy: float = 0.0, dth: float = 0.0, darm: float = 0.0, vac: float = 0.0):
    return np.array([dx, dy, dth, darm, vac])


def place_robot(
    env: Kinematic2DEnv, state: ObjectCentricState, x: float, y: float, th: float
) -> None:
    for f, v in zip(("x", "y", "theta"), (x, y, th)):
        state.set(env.robot, f, v)


def test_robot_moves_turns_and_extends_its_arm() -> None:
    env = Motion2DEnv(num_passages=0)
    s, _ = env.reset(seed=0)
    place_robot(env, s, 1.0, 1.0, np.pi - 0.05)
    nxt, reward, term = env.transition(s, act(0.05, -0.03, 0.1, 0.05, 0.2))
    r = env.robot
    assert nxt.get(r, "x") == pytest.approx(1.05) and nxt.get(r, "y") == pytest.approx(0.97)
    assert nxt.get(r, "theta") == pytest.approx(0.05 - np.pi)  # wrapped into [−π, π)
    assert nxt.get(r, "arm_joint") == pytest.approx(0.15)
    assert nxt.get(r, "vacuum") == pytest.approx(0.2)
    assert (reward, term) == (-1.0, False)
    # The arm stays within [base_radius, arm_length].
    for _ in range(3):
        nxt, *_ = env.transition(nxt, act(darm=0.1))
    assert nxt.get(r, "arm_joint") == pytest.approx(0.2)
    for _ in range(3):
        nxt, *_ = env.transition(nxt, act(darm=-0.1))
    assert nxt.get(r, "arm_joint") == pytest.approx(0.1)


def test_robot_into_a_wall_is_reverted() -> None:
    env = Motion2DEnv(num_passages=0)
    s, _ = env.reset(seed=0)
    place_robot(env, s, 0.12, 1.0, 0.0)  # 0.02 from the left wall, gripper facing away
    blocked, *_ = env.transition(s, act(dx=-0.05))
    assert blocked == s
    moved, *_ = env.transition(s, act(dx=-0.015))
    assert moved.get(env.robot, "x") == pytest.approx(0.105)


def test_robot_into_a_passage_wall_is_reverted() -> None:
    env = Motion2DEnv(num_passages=1)
    s, _ = env.reset(seed=0)
    wall_bottom = env.obstacles[0]
    wx = s.get(wall_bottom, "x")
    place_robot(env, s, wx - 0.12, 0.1 + 0.05, 0.0)
    # The arm (and the gripper) faces the wall: turning and extending hits it.
    assert env.transition(s, act(darm=0.05))[0] == s
    # The wall is static: it never moves, even when pushed against.
    s2, *_ = env.transition(s, act(dx=0.05))
    assert s2.get(wall_bottom, "x") == wx


def _holding_block_state(env: Obstruction2DEnv) -> ObjectCentricState:
    """The robot points down at the target block's top, inside the suction zone."""
    s, _ = env.reset(seed=0)
    block = env.target_block
    rx, ry = 0.8, 0.6
    place_robot(env, s, rx, ry, -np.pi / 2)
    g = robot_geometry(s[env.robot])
    suction_y = g.suction[1]
    s.set(block, "width", 0.1)
    s.set(block, "height", 0.1)
    s.set(block, "x", rx - 0.05)
    s.set(block, "y", suction_y - 0.1)  # top edge in the middle of the suction zone
    for o in env.obstructions:  # park the obstructions far away on the table
        s.set(o, "x", 0.05 + 0.25 * env.obstructions.index(o))
    s.set(env.robot, "vacuum", 1.0)
    assert not env.world.in_collision(s.data), env.world.colliding_pairs(s.data)
    return s


def test_suction_picks_carries_rotates_and_releases() -> None:
    env = Obstruction2DEnv(num_obstructions=1)
    s = _holding_block_state(env)
    block = env.target_block
    assert env.held_objects(s) == [block]
    x0, y0 = s.get(block, "x"), s.get(block, "y")
    carried, *_ = env.transition(s, act(dx=0.05, dy=0.03, vac=1.0))
    assert carried.get(block, "x") == pytest.approx(x0 + 0.05)
    assert carried.get(block, "y") == pytest.approx(y0 + 0.03)
    # Turning rotates the block rigidly about the tool tip.
    tip = np.array(robot_geometry(carried[env.robot]).tool_tip)
    corner = np.array([carried.get(block, "x"), carried.get(block, "y")])
    turned, *_ = env.transition(carried, act(dth=0.1, vac=1.0))
    assert turned.get(block, "theta") == pytest.approx(0.1)
    tip2 = np.array(robot_geometry(turned[env.robot]).tool_tip)
    corner2 = np.array([turned.get(block, "x"), turned.get(block, "y")])
    assert np.linalg.norm(corner2 - tip2) == pytest.approx(np.linalg.norm(corner - tip))
    # Releasing: the step that turns the vacuum off still carries (suction is read from the
    # previous state); after it the block stays put.
    released, *_ = env.transition(turned, act(dy=0.02, vac=0.0))
    assert released.get(block, "y") == pytest.approx(turned.get(block, "y") + 0.02)
    assert env.held_objects(released) == []
    away, *_ = env.transition(released, act(dy=0.05))
    assert away.get(block, "y") == released.get(block, "y")
    assert away.get(env.robot, "y") == pytest.approx(released.get(env.robot, "y") + 0.05)


def test_suction_off_does_not_carry() -> None:
    env = Obstruction2DEnv(num_obstructions=1)
    s = _holding_block_state(env)
    s.set(env.robot, "vacuum", 0.3)
    nxt, *_ = env.transition(s, act(dy=0.05))
    assert nxt.get(env.target_block, "y") == s.get(env.target_block, "y")


def test_held_block_into_an_obstacle_is_reverted() -> None:
    env = Obstruction2DEnv(num_obstructions=1)
    s = _holding_block_state(env)
    block, other = env.target_block, env.obstructions[0]
    # An obstruction 0.03 to the right of the held block, lower than the robot's base.
    s.set(other, "x", s.get(block, "x") + s.get(block, "width") + 0.03)
    s.set(other, "y", 0.1 + 1e-6)
    s.set(other, "height", 0.35)
    assert not env.world.in_collision(s.data)
    assert env.transition(s, act(dx=0.05, vac=1.0))[0] == s
    moved, *_ = env.transition(s, act(dx=0.02, vac=1.0))
    assert moved.get(block, "x") == pytest.approx(s.get(block, "x") + 0.02)
    # Lowering the held block into the table is reverted too.
    low = s.copy()
    low.set(block, "y", 0.1 + 0.01)
    low.set(env.robot, "y", s.get(env.robot, "y") - (s.get(block, "y") - 0.11))
    assert env.transition(low, act(dy=-0.05, vac=1.0))[0] == low


def _stick_env() -> tuple[StickButton2DEnv, ObjectCentricState]:
    env = StickButton2DEnv(num_buttons=2)
    s, _ = env.reset(seed=0)
    place_robot(env, s, 1.0, 0.5, 0.0)
    s.set(env.stick, "x", 3.0)
    s.set(env.stick, "y", 0.7)
    s.set(env.buttons[0], "x", 1.3)
    s.set(env.buttons[0], "y", 0.5)
    s.set(env.buttons[1], "x", 3.025)
    s.set(env.buttons[1], "y", 2.2)
    return env, s


def test_robot_press_latches() -> None:
    env, s = _stick_env()
    b0, b1 = env.buttons
    assert not is_pressed(s, b0)
    nxt, reward, _ = env.transition(s, STILL)
    assert not is_pressed(nxt, b0)  # not touched yet
    for _ in range(4):
        nxt, reward, term = env.transition(nxt, act(dx=0.05))
    assert is_pressed(nxt, b0) and not is_pressed(nxt, b1)
    assert tuple(nxt[b0][4:7]) == pytest.approx(BUTTON_GREEN)
    assert (reward, term) == (-1.0, False)
    for _ in range(6):  # leave: the button stays pressed
        nxt, *_ = env.transition(nxt, act(dx=-0.05))
    assert is_pressed(nxt, b0)


def test_stick_press_and_terminal_reward() -> None:
    env, s = _stick_env()
    b0, b1 = env.buttons
    s.set(b0, "color_r", BUTTON_GREEN[0])
    s.set(b0, "color_g", BUTTON_GREEN[1])
    # Move the stick's top onto the button on the table, as if carried.
    s.set(env.stick, "y", 2.2 - 1.25 - 0.06)
    nxt, reward, term = env.transition(s, STILL)
    assert not is_pressed(nxt, b1) and not term
    s.set(env.stick, "y", 2.2 - 1.25 + 0.01)
    nxt, reward, term = env.transition(s, STILL)
    assert is_pressed(nxt, b1) and term and reward == 0.0


def test_suction_zone_presses_only_while_the_vacuum_is_on() -> None:
    """Upstream tests buttons against every robot body, the suction zone included when on."""
    env, s = _stick_env()
    b0 = env.buttons[0]
    g = robot_geometry(s[env.robot])
    s.set(b0, "x", g.suction[0] + 0.05 + 0.002)  # the circle's edge inside the suction zone
    s.set(b0, "y", g.suction[1])
    nxt, *_ = env.transition(s, act(vac=0.0))
    assert not is_pressed(nxt, b0)
    nxt, *_ = env.transition(s, act(vac=1.0))
    assert is_pressed(nxt, b0)


def test_table_blocks_the_base_but_not_the_arm() -> None:
    env, s = _stick_env()
    place_robot(env, s, 1.0, 1.25 - 0.1 - 0.03, np.pi / 2)  # base 0.03 below the table edge
    assert env.transition(s, act(dy=0.05))[0] == s
    reached, *_ = env.transition(s, act(darm=0.1))  # the arm reaches over the table
    assert reached.get(env.robot, "arm_joint") == pytest.approx(0.2)


def _hook_state() -> tuple[PushPullHook2DEnv, ObjectCentricState]:
    env = PushPullHook2DEnv()
    s, _ = env.reset(seed=0)
    rx, ry, ay = 1.0, 0.8, 1.6
    place_robot(env, s, rx, ry, 0.0)
    s.set(env.robot, "vacuum", 1.0)
    ax = rx + 0.11  # the handle's left edge inside the suction zone
    for f, v in (("x", ax), ("y", ay), ("theta", np.pi / 2)):
        s.set(env.hook, f, v)
    # The movable button rests just above the hook's short arm (which spans y 1.55..1.6).
    s.set(env.movable_button, "x", ax + 0.3)
    s.set(env.movable_button, "y", 1.6 + 0.05 + 0.01)
    s.set(env.target_button, "x", ax + 0.3)
    s.set(env.target_button, "y", 1.765)
    for b in (env.movable_button, env.target_button):
        for f, v in zip(("color_r", "color_g", "color_b"), BUTTON_RED):
            s.set(b, f, v)
    assert not env.world.in_collision(s.data), env.world.colliding_pairs(s.data)
    return env, s


def test_held_hook_pushes_the_button_and_presses() -> None:
    env, s = _hook_state()
    assert env.held_objects(s) == [env.hook]
    my0 = s.get(env.movable_button, "y")
    nxt, reward, term = env.transition(s, act(dy=0.05, vac=1.0))
    assert nxt.get(env.hook, "y") == pytest.approx(1.65)
    # Upstream's rule: the button moves by the vector from the hook outline's closest point
    # (on the arm's top edge, y = 1.65) to its centre (y = 1.66): 0.01 up, still overlapping.
    assert nxt.get(env.movable_button, "y") == pytest.approx(my0 + 0.01)
    assert nxt.get(env.movable_button, "x") == pytest.approx(s.get(env.movable_button, "x"))
    # Centres now 0.095 apart (< 0.10): both buttons pressed, the goal reached, reward 0.
    assert is_pressed(nxt, env.movable_button) and is_pressed(nxt, env.target_button)
    assert term and reward == 0.0


def test_pushing_into_a_wall_is_reverted() -> None:
    env, s = _hook_state()
    # The button sits 0.005 beyond the tip of the hook's short arm, 0.01 from the right wall.
    ax = 3.5 - 0.01 - 0.1 - 0.005 - 0.625
    s.set(env.hook, "x", ax)
    place_robot(env, s, ax - 0.11, 0.8, 0.0)
    s.set(env.movable_button, "x", 3.5 - 0.01 - 0.05)
    s.set(env.movable_button, "y", 1.575)
    assert not env.world.in_collision(s.data), env.world.colliding_pairs(s.data)
    # Overlapping by 0.005 pushes the button by its centre's distance to the tip (0.045), into
    # the wall: the whole step is reverted, hook and robot included.
    assert env.transition(s, act(dx=0.01, vac=1.0))[0] == s
    assert env.transition(s, act(dx=0.02, vac=1.0))[0] == s
    # Away from the wall the same nudge pushes the button by 0.045.
    s.set(env.hook, "x", ax - 0.2)
    place_robot(env, s, ax - 0.31, 0.8, 0.0)
    s.set(env.movable_button, "x", 3.5 - 0.21 - 0.05)
    nudged, *_ = env.transition(s, act(dx=0.01, vac=1.0))
    assert nudged.get(env.movable_button, "x") == pytest.approx(3.5 - 0.26 + 0.045)


def test_unheld_hook_is_an_obstacle_for_the_arm() -> None:
    env, s = _hook_state()
    s.set(env.robot, "vacuum", 0.0)
    # Extending the arm drives the gripper into the handle: reverted.
    assert env.transition(s, act(darm=0.05))[0] == s
