"""KinematicShelf3D and KinematicCylinderShelf3D: resets, goals, and scripted pick and place."""

from __future__ import annotations

import math

import numpy as np
import pytest
from garden3d_helpers import CLOSE, OPEN, _ik, action, move_ee

from kinder_garden3d.kinematic3d.kinematic_cylinder_shelf3d import (
    CYLINDER,
    KinematicCylinderShelf3DEnv,
)
from kinder_garden3d.kinematic3d.kinematic_shelf3d import KinematicShelf3DEnv, ShelfGeometry

#: The end effector's approach axis along +x (a quarter turn about y): a side grasp whose
#: fingers close horizontally.
SIDE_X = np.array([0.0, math.sqrt(0.5), 0.0, math.sqrt(0.5)])


@pytest.fixture
def closing():
    envs = []
    yield envs.append
    for env in envs:
        env.close()


@pytest.mark.parametrize(
    "make",
    [
        lambda: KinematicShelf3DEnv(num_cubes=5),
        lambda: KinematicCylinderShelf3DEnv(num_cylinders=3),
    ],
    ids=["shelf-o5", "cylinder-o3"],
)
def test_resets_stand_apart_on_the_floor_and_are_unsolved(make, closing):
    env = make()
    closing(env)
    box = env.box_space
    seen = set()
    for seed in range(50):
        state, info = env.reset(seed=seed)
        assert box.contains(box.vectorize(state)), f"seed {seed}: outside the Box"
        assert not info["success"], f"seed {seed} is solved"
        assert env.penetrations(state) == [], f"seed {seed}: {env.penetrations(state)}"
        for name in env.movable_names(state):
            f = state[state.get_object_from_name(name)]
            assert f[2] == f[11], f"seed {seed}: {name} does not stand on the floor"
            assert max(abs(f[0]), abs(f[1])) <= 1.0
        seen.add(state.stable_hash())
    assert len(seen) == 50


def test_cylinders_cycle_heights_and_are_tagged(closing):
    env = KinematicCylinderShelf3DEnv(num_cylinders=3)
    closing(env)
    state, _ = env.reset(seed=0)
    heights = [2 * state[c][11] for c in env.cylinders]
    assert heights == pytest.approx([0.20, 0.15, 0.175])
    assert all(
        state[c][8] == CYLINDER and state[c][9] == state[c][10] == 0.03 for c in env.cylinders
    )


def test_shelf_geometry_boards_and_supports():
    shelf = ShelfGeometry()
    parts = shelf.parts()
    assert len(parts) == 6
    assert [p.pos[2] for p in parts[:4]] == pytest.approx([0.0, 0.2667, 0.5334, 0.8001])
    assert shelf.surface_heights(0.02)[1] == pytest.approx(0.02 + 0.2667 + 0.00635)
    assert len(ShelfGeometry(omitted_layers=(1,)).parts()) == 5
    with pytest.raises(ValueError, match="num_layers"):
        ShelfGeometry(num_layers=0)


def test_shelf_goal(closing):
    env = KinematicShelf3DEnv(num_cubes=2)
    closing(env)
    state, _ = env.reset(seed=0)
    a, b = env.cubes
    state[a][:3] = (2.0, 2.4, 0.02 + 0.2667 + 0.00635 + 0.025)
    assert not env.goal_reached(state)  # cube1 is still on the floor
    state[b][:3] = (1.9, 2.4, 0.02 + 0.2667 + 0.00635 + 0.025)
    assert env.goal_reached(state)
    state[env.robot][10] = 0.2  # the gripper is not open
    assert not env.goal_reached(state)
    state[env.robot][10] = 0.0
    state[b][2] = 0.22  # below the threshold 0.224
    assert not env.goal_reached(state)


def test_cylinder_goal(closing):
    env = KinematicCylinderShelf3DEnv(num_cylinders=2)
    closing(env)
    state, _ = env.reset(seed=0)
    a, b = env.cylinders
    top1 = 0.02 + 0.2667 + 0.00635
    state[a][:3] = (2.0, 2.4, top1 + 0.10)
    state[b][:3] = (2.2, 2.45, 0.02 + 0.00635 + 0.075)  # on the bottom board
    assert env.goal_reached(state)
    state[b][0] = 2.35  # outside the footprint along x
    assert not env.goal_reached(state)
    state[b][0] = 2.2
    state[a][2] = top1 + 0.10 + 0.06  # floating above its resting height
    assert not env.goal_reached(state)


def test_bad_counts_are_rejected():
    with pytest.raises(ValueError, match="num_cubes"):
        KinematicShelf3DEnv(num_cubes=0)
    with pytest.raises(ValueError, match="num_cylinders"):
        KinematicCylinderShelf3DEnv(num_cylinders=-1)


def test_pick_a_cube_from_the_floor_and_place_it_on_the_shelf(closing):
    env = KinematicShelf3DEnv(num_cubes=1)
    closing(env)
    state, _ = env.reset(seed=0)
    cube = env.cubes[0]
    state[cube][:3] = (0.55, 0.0, 0.025)
    env.set_state(state)
    for p in ((0.55, 0.0, 0.2), (0.55, 0.0, 0.035)):
        state = move_ee(env, state, np.array(p))
    state, *_ = env.step(CLOSE)
    assert state[cube][7] == 1.0
    state, *_ = env.step(OPEN)
    assert state[cube][7] == 1.0  # the floor is not a surface: still held
    state = move_ee(env, state, np.array((0.4, 0.0, 0.9)))
    for _ in range(8):  # turn to face +y, then drive to the front of the shelf
        state, *_ = env.step(action(base=(0.0, 0.0, math.pi / 16)))
    for _ in range(20):
        d = np.clip(np.array([2.0, 1.85]) - state[env.robot][:2], -0.2, 0.2)
        state, *_ = env.step(action(base=(float(d[0]), float(d[1]), 0.0)))
    assert state[env.robot][:2] == pytest.approx((2.0, 1.85))
    for p in ((2.0, 2.4, 0.9), (2.0, 2.4, 0.864)):
        state = move_ee(env, state, np.array(p))
    state, _, terminated, _, info = env.step(OPEN)
    assert state[cube][7] == 0.0 and terminated and info["success"]
    assert state[cube][2] == pytest.approx(0.02 + 0.8001 + 0.00635 + 0.025, abs=0.006)


def test_side_grasp_lifts_a_cylinder(closing):
    env = KinematicCylinderShelf3DEnv(num_cylinders=1)
    closing(env)
    state, _ = env.reset(seed=0)
    cylinder = env.cylinders[0]
    state[cylinder][:3] = (0.8, 0.0, 0.1)
    env.set_state(state)

    def reach(state, pos):
        robot = state[env.robot]
        res = _ik().solve(
            np.array(pos),
            SIDE_X,
            base_pose=(0.0, 0.0, 0.0),
            initial_arm_joints=robot[3:10],
            base_z=0.0,
        )
        assert res.success, pos
        delta = (res.arm_joints - robot[3:10] + np.pi) % (2 * np.pi) - np.pi
        n = max(1, int(np.ceil(np.max(np.abs(delta)) / env.config.max_action_mag)))
        for _ in range(n):
            state, *_ = env.step(action(joints=delta / n))
        return state

    for p in ((0.75, 0.0, 0.15), (0.8, 0.0, 0.15)):
        state = reach(state, p)
    assert env.pinch_pose(state)[0] == pytest.approx((0.8, 0.0, 0.15), abs=1e-3)
    state, *_ = env.step(CLOSE)
    assert state[cylinder][7] == 1.0 and state[env.robot][10] > 0.0
    state = reach(state, (0.8, 0.0, 0.4))
    assert state[cylinder][2] == pytest.approx(0.35, abs=1e-3)
