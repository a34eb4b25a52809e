"""Each family's goal predicate on hand-built states."""

from __future__ import annotations

import numpy as np
import pytest
from garden3d_helpers import with_arm_at

from kinder_garden3d.kinematic3d.base_motion3d import BaseMotion3DEnv
from kinder_garden3d.kinematic3d.geometry import yaw_quat
from kinder_garden3d.kinematic3d.obstruction3d import Obstruction3DEnv
from kinder_garden3d.kinematic3d.packing3d import Packing3DEnv
from kinder_garden3d.kinematic3d.table3d import Table3DEnv
from kinder_garden3d.kinematic3d.transport3d import Transport3DEnv


@pytest.fixture
def closing():
    envs = []
    yield envs.append
    for env in envs:
        env.close()


def test_base_motion_goal(closing):
    env = BaseMotion3DEnv()
    closing(env)
    state = env.exemplar_state().copy()
    state[env.target][:2] = (1.0, -1.0)
    state[env.robot][:2] = (1.0 + 0.03, -1.0 + 0.03)  # 4.2 cm away
    assert env.goal_reached(state)
    state[env.robot][:2] = (1.0 + 0.05, -1.0)
    assert not env.goal_reached(state)
    state[env.robot][:2] = (1.0, -1.0)
    state[env.target][2] = 1.0  # height does not matter
    assert env.goal_reached(state)


def _obstruction_goal_state(env):
    state = env.exemplar_state().copy()
    region, block = state[env.region], state[env.block]
    region[:3] = (0.3, 0.1, 0.08)
    region[9:12] = (0.05, 0.04, 0.005)
    block[9:12] = (0.04, 0.032, 0.025)
    block[:3] = (0.3, 0.1, 0.08 + 0.005 + 0.025)
    return state


def test_obstruction_goal(closing):
    env = Obstruction3DEnv(num_obstructions=1)
    closing(env)
    state = _obstruction_goal_state(env)
    assert env.goal_reached(state)
    # Off-centre but every corner within the region + 5 mm.
    state[env.block][0] += 0.014
    assert env.goal_reached(state)
    state[env.block][0] += 0.002  # a corner now 6 mm past the edge
    assert not env.goal_reached(state)
    state = _obstruction_goal_state(env)
    state[env.block][2] += 0.006  # hovering 6 mm above
    assert not env.goal_reached(state)
    state = _obstruction_goal_state(env)
    state[env.block][3:7] = yaw_quat(np.pi / 4)  # rotated 45 deg: corners stick out in y
    assert not env.goal_reached(state)
    state = _obstruction_goal_state(env)
    state[env.block][7] = 1.0
    state[env.robot][11] = 1.0  # held
    assert not env.goal_reached(state)


def test_table_goal(closing):
    env = Table3DEnv(num_cubes=2)
    closing(env)
    state = env.exemplar_state().copy()
    cube = env.cubes[1]
    state[cube][2] = 0.4 + 0.11
    assert not env.goal_reached(state)  # lifted but not held
    state[cube][7] = 1.0
    state[env.robot][11] = 1.0
    assert env.goal_reached(state)
    state[cube][2] = 0.4 + 0.09
    assert not env.goal_reached(state)


def _transport_goal_state(env):
    state = env.exemplar_state().copy()
    xs = iter([0.5, 0.7])
    for cube in env.cubes:
        state[cube][:3] = (next(xs), 0.3, 0.425)
    state[env.box][:3] = (0.62, -0.2, 0.5)
    return state


def test_transport_goal(closing):
    env = Transport3DEnv(num_cubes=2)
    closing(env)
    state = _transport_goal_state(env)
    assert env.goal_reached(state)
    state[env.cubes[0]][2] = 0.025  # left on the floor
    assert not env.goal_reached(state)
    state = _transport_goal_state(env)
    state[env.robot][10] = 0.02  # gripper not open
    assert not env.goal_reached(state)
    state = _transport_goal_state(env)
    # The pinch point 12.5 cm above cube0 puts the end effector (2.5 cm above the pinch point)
    # 15 cm from it. (17.5 cm above put the end effector at the 0.2 m clearance itself, within
    # the IK's 1e-5 m residual either side.)
    near = with_arm_at(env, state, np.array([0.5, 0.3, 0.55]))
    assert not env.goal_reached(near)
    far = with_arm_at(env, state, np.array([0.3, 0.0, 0.8]))
    assert env.goal_reached(far)


def _packing_goal_state(env):
    state = env.exemplar_state().copy()
    rack = state[env.rack]
    floor_top = rack[2] - rack[11] + 0.01
    cube_part, tri_part = env.parts
    state[cube_part][:3] = (rack[0], rack[1] - 0.065, floor_top + 0.01)
    state[tri_part][:3] = (rack[0], rack[1] + 0.07, floor_top + 0.01)
    return state


def test_packing_goal(closing):
    env = Packing3DEnv(num_parts=2)
    closing(env)
    state = _packing_goal_state(env)
    assert env.goal_reached(state)
    cube_part, tri_part = env.parts
    # Overlapping parts.
    state[tri_part][1] = state[cube_part][1] + 0.06
    assert not env.goal_reached(state)
    # A part outside the rack.
    state = _packing_goal_state(env)
    state[tri_part][:3] = (0.2, 0.3, 0.085)
    assert not env.goal_reached(state)
    # A part 6 mm above the rack floor.
    state = _packing_goal_state(env)
    state[cube_part][2] += 0.006
    assert not env.goal_reached(state)
    # A part through the rack wall.
    state = _packing_goal_state(env)
    state[cube_part][1] = state[env.rack][1] - 0.15
    assert not env.goal_reached(state)
    # Held.
    state = _packing_goal_state(env)
    state[cube_part][7] = 1.0
    state[env.robot][11] = 1.0
    assert not env.goal_reached(state)


def test_packing_part_shapes_follow_the_count_rule(closing):
    for n, kinds in ((1, ["tri"]), (2, ["cub", "tri"]), (3, ["cub", "tri", "tri"])):
        env = Packing3DEnv(num_parts=n)
        closing(env)
        got = ["cub" if p.type.name == "Kinematic3DCuboid" else "tri" for p in env.parts]
        assert got == kinds
