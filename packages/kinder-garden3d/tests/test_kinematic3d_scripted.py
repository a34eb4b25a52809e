"""Every family is solvable: scripted IK policies reach the goal through ``step`` alone."""

from __future__ import annotations

import numpy as np
import pytest
from garden3d_helpers import CLOSE, OPEN, action, move_ee

from kinder_garden3d.kinematic3d.base_motion3d import BaseMotion3DEnv
from kinder_garden3d.kinematic3d.obstruction3d import Obstruction3DEnv
from kinder_garden3d.kinematic3d.packing3d import Packing3DEnv
from kinder_garden3d.kinematic3d.table3d import Table3DEnv
from kinder_garden3d.kinematic3d.transport3d import Transport3DEnv


def _xyz(x: float, y: float, z: float) -> np.ndarray:
    return np.array([x, y, z])


def test_base_motion_drives_to_the_target():
    env = BaseMotion3DEnv()
    state, _ = env.reset(seed=5)
    terminated = False
    for _ in range(50):
        delta = state[env.target][:2] - state[env.robot][:2]
        step = np.clip(delta, -0.4, 0.4)
        state, reward, terminated, _, _ = env.step(action(base=(step[0], step[1], 0.0)))
        assert reward == -1.0
        if terminated:
            break
    assert terminated and env.goal_reached(state)
    env.close()


def test_table_grasp_and_lift():
    env = Table3DEnv(num_cubes=1)
    state, _ = env.reset(seed=2)
    cube = state[env.cubes[0]][:3].copy()
    state = move_ee(env, state, cube + _xyz(0.0, 0.0, 0.1))
    state = move_ee(env, state, cube + _xyz(0.0, 0.0, 0.01))
    state, _, terminated, _, _ = env.step(CLOSE)
    assert not terminated and state.get(env.robot, "grasp_active") == 1.0
    state = move_ee(env, state, cube + _xyz(0.0, 0.0, 0.13))
    assert env.goal_reached(state)
    env.close()


def test_obstruction_place_block_on_region():
    env = Obstruction3DEnv(num_obstructions=0)
    state, _ = env.reset(seed=3)
    block = state[env.block][:3].copy()
    region = state[env.region]
    above = 0.015  # end effector above the block centre when grasping
    state = move_ee(env, state, block + _xyz(0.0, 0.0, 0.08))
    state = move_ee(env, state, block + _xyz(0.0, 0.0, above))
    state, *_ = env.step(CLOSE)
    assert state[env.block][7] == 1.0
    state = move_ee(env, state, block + _xyz(0.0, 0.0, 0.1))
    drop_z = region[2] + region[11] + state[env.block][11] + 0.002 + above
    state = move_ee(env, state, _xyz(region[0], region[1], drop_z + 0.08))
    state = move_ee(env, state, _xyz(region[0], region[1], drop_z))
    assert not env.goal_reached(state)  # still held
    state, _, terminated, _, _ = env.step(OPEN)
    assert terminated and state[env.block][7] == 0.0
    env.close()


def test_packing_seat_a_part_in_the_rack():
    env = Packing3DEnv(num_parts=1)
    state, _ = env.reset(seed=0)
    part = env.parts[0]
    f = state[part]
    peg = f[:3] + _xyz(0.0, 0.0, f[11] / 2.0 + 0.025)  # the peg centre on the triangle
    state = move_ee(env, state, peg + _xyz(0.0, 0.0, 0.08))
    state = move_ee(env, state, peg)
    state, *_ = env.step(CLOSE)
    assert state[part][7] == 1.0
    rack = state[env.rack]
    floor_top = rack[2] - rack[11] + 0.01
    lift = peg + _xyz(0.0, 0.0, 0.1)
    state = move_ee(env, state, lift)
    offset = peg - f[:3]
    seat_z = floor_top + f[11] / 2.0 + 0.002 + offset[2]
    state = move_ee(env, state, _xyz(rack[0], rack[1], seat_z + 0.1))
    state = move_ee(env, state, _xyz(rack[0], rack[1], seat_z))
    state, _, terminated, _, _ = env.step(OPEN)
    assert state[part][7] == 0.0
    assert env.part_seated(state, part)
    assert terminated
    env.close()


def test_transport_cube_into_box_and_box_onto_table():
    env = Transport3DEnv(num_cubes=1)
    state, _ = env.reset(seed=0)
    cube, box = env.cubes[0], env.box
    # A hand-built layout beside the table: robot, a cube and the box on the floor.
    state[env.robot][:3] = (0.0, -0.55, 0.0)
    state[cube][:3] = (0.3, -0.25, 0.025)
    state[box][:3] = (0.45, -0.6, 0.1)
    assert env.penetrations(state) == []
    env.set_state(state)
    # Cube into the box (released onto the box floor, a surface).
    for p in ((0.3, -0.25, 0.2), (0.3, -0.25, 0.035)):
        state = move_ee(env, state, _xyz(*p))
    state, *_ = env.step(CLOSE)
    for p in ((0.3, -0.25, 0.45), (0.45, -0.6, 0.45), (0.45, -0.6, 0.047)):
        state = move_ee(env, state, _xyz(*p))
    state, *_ = env.step(OPEN)
    assert state[cube][7] == 0.0 and abs(state[cube][2] - 0.037) < 1e-3
    # Grasp the box by its wall, lift it with the cube inside, drive, set it on the table.
    for p in ((0.45, -0.6, 0.3), (0.45, -0.455, 0.3), (0.45, -0.455, 0.21)):
        state = move_ee(env, state, _xyz(*p))
    state, *_ = env.step(CLOSE)
    assert state[box][7] == 1.0
    state = move_ee(env, state, _xyz(0.45, -0.455, 0.65))
    assert state[cube][2] > 0.45  # carried inside the box
    for _ in range(2):
        state, *_ = env.step(action(base=(0.0, 0.175, 0.0)))
    assert state[box][1] == pytest.approx(-0.25, abs=1e-3)
    assert state[cube][1] == pytest.approx(-0.25, abs=1e-3)
    state = move_ee(env, state, _xyz(0.45, -0.105, 0.612))
    state, _, terminated, _, _ = env.step(OPEN)
    assert state[box][7] == 0.0 and not terminated  # the gripper is still next to the box
    state = move_ee(env, state, _xyz(0.3, -0.105, 0.85))
    assert env.goal_reached(state)
    env.close()
