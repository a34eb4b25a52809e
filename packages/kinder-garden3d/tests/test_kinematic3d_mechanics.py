"""Shared Kinematic3D mechanics: collision revert, swept checks, grasp, release, container carry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from garden3d_helpers import CLOSE, OPEN, action, move_ee, with_arm_at

from kinder_garden3d.kinematic3d.base_env import Kinematic3DConfig, ResetError
from kinder_garden3d.kinematic3d.geometry import compose, invert
from kinder_garden3d.kinematic3d.kinematic_shelf3d import KinematicShelf3DEnv
from kinder_garden3d.kinematic3d.obstruction3d import Obstruction3DEnv
from kinder_garden3d.kinematic3d.table3d import Table3DConfig, Table3DEnv
from kinder_garden3d.kinematic3d.transport3d import Transport3DEnv


@pytest.fixture
def table_env():
    env = Table3DEnv(num_cubes=2)
    env.reset(seed=0)
    yield env
    env.close()


def _place_cubes(env, state, *xys):
    state = state.copy()
    for cube, (x, y) in zip(env.cubes, xys, strict=True):
        state[cube][:3] = (x, y, 0.425)
    return state


def test_base_move_into_the_table_is_reverted(table_env):
    env = table_env
    start = env.get_state()
    blocked, *_ = env.step(action(base=(0.3, 0.0, 0.0)))  # chassis front 0.2 -> 0.5 > table 0.4
    assert blocked == start
    moved, *_ = env.step(action(base=(0.1, 0.0, 0.0)))
    assert moved.get(env.robot, "pos_base_x") == pytest.approx(0.1)


@pytest.mark.parametrize("wrap", [False, True])
def test_joint_moves_are_clipped_to_limits_and_continuous_joints_wrap_only_if_asked(wrap):
    env = Table3DEnv(num_cubes=1, config=Table3DConfig(wrap_joints=wrap))
    state, _ = env.reset(seed=0)
    state[env.robot][4] = -2.2  # joint_2 (arm tilted back, away from the table), limit 2.41
    state[env.robot][5] = 3.1  # joint_3, continuous
    env.set_state(state)
    nxt, *_ = env.step(action(joints=np.array([0.0, -0.4, 0.4, 0.0, 0.0, 0.0, 0.0])))
    assert nxt != state, "the move was expected to be collision-free"
    assert nxt.get(env.robot, "joint_2") == pytest.approx(-2.41)
    expected = 3.5 - 2 * math.pi if wrap else 3.5
    assert nxt.get(env.robot, "joint_3") == pytest.approx(expected)
    env.close()


def _swept_env(step):
    env = Table3DEnv(num_cubes=1, config=Table3DConfig(max_collision_check_step=step))
    state, _ = env.reset(seed=0)
    # Arm stretched forward and up; a floating cube sits on the arc the gripper sweeps when
    # the base turns by 0.4 rad, but clear of both endpoints.
    state = with_arm_at(env, state, np.array([0.6, 0.0, 0.65]))
    ee, _ = env.pinch_pose(state)
    radius, angle = math.hypot(ee[0], ee[1]), math.atan2(ee[1], ee[0])
    mid = angle + 0.2
    state[env.cubes[0]][:3] = (radius * math.cos(mid), radius * math.sin(mid), ee[2])
    return env, state


def test_swept_collision_checks_catch_obstacles_between_endpoints():
    turn = action(base=(0.0, 0.0, 0.4))
    endpoint_only, state = _swept_env(None)
    endpoint_only.set_state(state)
    moved, *_ = endpoint_only.step(turn)
    assert moved.get(endpoint_only.robot, "pos_base_rot") == pytest.approx(0.4)
    endpoint_only.close()
    swept, state = _swept_env(0.005)
    swept.set_state(state)
    blocked, *_ = swept.step(turn)
    assert blocked == state
    swept.close()


def test_grasp_succeeds_with_exactly_one_object_at_the_end_effector(table_env):
    env = table_env
    state = _place_cubes(env, env.get_state(), (0.55, -0.1), (0.55, 0.2))
    state = with_arm_at(env, state, np.array([0.55, -0.1, 0.435]))
    env.set_state(state)
    held, *_ = env.step(CLOSE)
    assert held.get(env.robot, "grasp_active") == 1.0
    assert held[env.cubes[0]][7] == 1.0 and held[env.cubes[1]][7] == 0.0
    # The fingers stopped on the 5 cm cube: opening ~ 5 cm, finger state ~ 0.33.
    assert 0.3 < held.get(env.robot, "finger_state") < 0.36
    # The cube centre lies 1 cm past the pinch point, 2.5 cm past the tool frame (the grasp
    # transform's frame) along the approach.
    assert held.get(env.robot, "grasp_tf_z") == pytest.approx(0.035, abs=1e-3)


def test_grasp_is_refused_with_no_object_at_the_end_effector(table_env):
    env = table_env
    state = _place_cubes(env, env.get_state(), (0.55, -0.1), (0.55, 0.2))
    state = with_arm_at(env, state, np.array([0.55, 0.05, 0.435]))
    env.set_state(state)
    after, *_ = env.step(CLOSE)
    assert after == state


def test_grasp_is_refused_with_two_objects_at_the_end_effector(table_env):
    env = table_env
    # Two cubes 5 mm apart; the end effector between them touches both.
    state = _place_cubes(env, env.get_state(), (0.55, 0.0), (0.605, 0.0))
    state = with_arm_at(env, state, np.array([0.5775, 0.0, 0.435]))
    env.set_state(state)
    after, *_ = env.step(CLOSE)
    assert after == state


def test_release_is_refused_in_mid_air_and_accepted_on_a_surface(table_env):
    env = table_env
    state = _place_cubes(env, env.get_state(), (0.55, -0.1), (0.55, 0.2))
    state = with_arm_at(env, state, np.array([0.55, -0.1, 0.435]))
    env.set_state(state)
    state, *_ = env.step(CLOSE)
    lifted = move_ee(env, state, np.array([0.55, -0.1, 0.56]))
    cube = env.cubes[0]
    assert lifted[cube][2] > 0.52 and lifted.get(env.robot, "grasp_active") == 1.0
    env.set_state(lifted)
    still, *_ = env.step(OPEN)
    assert still.get(env.robot, "grasp_active") == 1.0 and still == lifted
    lowered = move_ee(env, still, np.array([0.55, -0.1, 0.4375]))
    gap = lowered[cube][2] - 0.025 - 0.4
    assert 0.0 <= gap < 0.005
    env.set_state(lowered)
    released, *_ = env.step(OPEN)
    assert released.get(env.robot, "grasp_active") == 0.0
    assert released[cube][7] == 0.0 and released.get(env.robot, "finger_state") == 0.0
    assert np.allclose(released[cube][:3], lowered[cube][:3])


def test_the_held_object_moves_with_the_gripper(table_env):
    env = table_env
    state = _place_cubes(env, env.get_state(), (0.55, -0.1), (0.55, 0.2))
    state = with_arm_at(env, state, np.array([0.55, -0.1, 0.435]))
    env.set_state(state)
    state, *_ = env.step(CLOSE)
    lifted = move_ee(env, state, np.array([0.5, -0.1, 0.6]))
    ee, _ = env.pinch_pose(lifted)
    assert np.allclose(lifted[env.cubes[0]][:3], ee + np.array([0.0, 0.0, -0.01]), atol=2e-3)


def test_the_box_carries_the_cubes_inside_it():
    env = Transport3DEnv(num_cubes=2)
    state, _ = env.reset(seed=0)
    ee, ee_q = env.ee_pose(state)
    box, inside, outside = env.box, env.cubes[0], env.cubes[1]
    # The robot holds the box by its near wall; one cube rests inside, one on the floor.
    state[box][:3] = ee + np.array([0.1 - 0.005, 0.0, -0.06])
    state[box][3:7] = (0.0, 0.0, 0.0, 1.0)
    state[box][7] = 1.0
    state[inside][:3] = state[box][:3] + np.array([0.0, 0.05, -0.1 + 0.01 + 0.025])
    state[outside][:3] = (-0.6, 0.6, 0.025)
    tf_p, tf_q = compose(*invert(ee, ee_q), state[box][:3], state[box][3:7])
    robot = state[env.robot]
    robot[11] = 1.0
    robot[12:19] = [*tf_p, *tf_q]
    robot[10] = 0.1
    env.set_state(state)
    moved, *_ = env.step(action(base=(0.1, -0.05, 0.0)))
    assert moved.get(env.robot, "pos_base_x") == pytest.approx(0.1)
    assert np.allclose(moved[box][:3] - state[box][:3], [0.1, -0.05, 0.0], atol=1e-6)
    assert np.allclose(moved[inside][:3] - state[inside][:3], [0.1, -0.05, 0.0], atol=1e-6)
    assert np.allclose(moved[outside][:3], state[outside][:3])
    turned, *_ = env.step(action(base=(0.0, 0.0, 0.2)))  # the bound is 0.2
    rel_before = moved[inside][:3] - moved[box][:3]
    rel_after = turned[inside][:3] - turned[box][:3]
    c, s = math.cos(0.2), math.sin(0.2)
    rotated = np.array([[c, -s], [s, c]]) @ rel_before[:2]
    assert np.allclose(rel_after[:2], rotated, atol=1e-9)
    env.close()


def test_obstruction_grasp_with_swept_checks():
    env = Obstruction3DEnv(num_obstructions=0)
    state, _ = env.reset(seed=3)
    block = state[env.block]
    target = block[:3] + np.array([0.0, 0.0, 0.015])
    state = with_arm_at(env, state, target)
    env.set_state(state)
    state, *_ = env.step(CLOSE)
    assert state[env.block][7] == 1.0
    lifted = move_ee(env, state, target + np.array([0.0, 0.0, 0.08]))
    assert lifted[env.block][2] == pytest.approx(block[2] + 0.08, abs=2e-3)
    env.close()


def test_bad_arguments_raise_clear_errors():
    with pytest.raises(ValueError, match="num_obstructions"):
        Obstruction3DEnv(num_obstructions=-1)
    with pytest.raises(ValueError, match="num_cubes"):
        Table3DEnv(num_cubes=0)
    with pytest.raises(ValueError, match="max_action_mag"):
        Kinematic3DConfig(max_action_mag=0.0)
    with pytest.raises(ValueError, match="home_joints"):
        Kinematic3DConfig(home_joints=(0.0,))


def test_impossible_layouts_raise_a_reset_error():
    env = Table3DEnv(num_cubes=200, config=Table3DConfig(max_reset_tries=3))
    with pytest.raises(ResetError, match="could not sample"):
        env.reset(seed=0)
    env.close()


def _scene_poses(env, state):
    """Each observed object's body pose in the env's pybullet scene, as a flat vector."""
    import pybullet as pb

    scene = env._scene
    out = []
    for obj in state:
        if obj == env.robot:
            continue
        pos, quat = pb.getBasePositionAndOrientation(scene.body(obj.name), scene.client)
        out += [*pos, *quat]
    return np.array(out)


def test_syncing_states_in_any_order_leaves_the_scene_as_a_fresh_sync_does():
    """The scene keeps an object's body and pose while its features are unchanged: after a run
    of states that move one object, then another, then step, the scene holds each state exactly
    as an env that loads only that state."""
    env = KinematicShelf3DEnv(num_cubes=3)
    fresh = KinematicShelf3DEnv(num_cubes=3)
    try:
        start = env.reset(seed=1000)[0]
        fresh.reset(seed=1000)
        states = [start]
        for i, cube in enumerate(env.cubes):
            s = states[-1].copy()
            s[cube][:3] += np.array([0.05 * (i + 1), -0.03, 0.0])
            states.append(s)
        states.append(start)  # back to the first: every moved cube is posed again
        for s in [*states, states[2], states[1]]:
            env.penetrations(s)
            fresh._sync_cache.rows.clear()  # no body kept from an earlier state
            fresh._sync(s, force=True)
            assert np.array_equal(_scene_poses(env, s), _scene_poses(fresh, s))
        # A step sweeps the robot (and moves bodies itself); what it leaves is loaded again.
        env.set_state(start)
        after, *_ = env.step(action(base=(0.05, 0.0, 0.0)))
        fresh._sync(after, force=True)
        assert np.array_equal(_scene_poses(env, after), _scene_poses(fresh, after))
    finally:
        env.close()
        fresh.close()


def test_penetrations_among_moving_bodies_are_those_of_the_full_check():
    """``penetrations(state, moving)`` reports exactly the full check's pairs that have one
    member moving (what a motion planner tests) and skips the rest."""
    env = KinematicShelf3DEnv(num_cubes=3)
    try:
        state = env.reset(seed=1001)[0].copy()
        a, b, c = env.cubes
        # Stack two cubes into each other and push the third into the shelf's post.
        state[b][:3] = state[a][:3]
        state[c][:3] = state[env.shelf][:3]
        full = env.penetrations(state)
        assert (a.name, b.name) in full or (b.name, a.name) in full
        for moving in ({"robot"}, {"robot", a.name}, {b.name, c.name}, set()):
            want = [p for p in full if (p[0] in moving) != (p[1] in moving)]
            assert env.penetrations(state, moving) == want
    finally:
        env.close()
