"""PrplLab3D: resets, the goal, and a cube raised to the counter's height and let go of."""

from __future__ import annotations

import numpy as np
import pytest
from garden3d_helpers import CLOSE, OPEN, move_ee

from kinder_garden3d.kinematic3d.prpl_lab3d import PrplLab3DEnv


@pytest.fixture
def env():
    e = PrplLab3DEnv(num_cubes=2)
    yield e
    e.close()


def test_resets_lie_on_the_floor_region_apart_and_unsolved(env):
    box = env.box_space
    seen = set()
    for seed in range(50):
        state, info = env.reset(seed=seed)
        assert box.contains(box.vectorize(state)), f"seed {seed}: outside the Box"
        assert not info["success"], f"seed {seed} is solved"
        assert env.penetrations(state) == [], f"seed {seed}: {env.penetrations(state)}"
        for cube in env.cubes:
            x, y, z = state[cube][:3]
            assert -1.0 <= x <= 1.6 and -1.5 <= y <= -0.2 and z == 0.025
        seen.add(state.stable_hash())
    assert len(seen) == 50
    assert list(state[env.robot][:3]) == pytest.approx([0.3, 0.0, np.pi / 2])
    assert list(state[env.lab]) == [-1.0, 2.0, 0.0, 0.0, 0.0, 0.0, 1.0]


def test_goal_needs_every_cube_at_counter_height_and_released(env):
    state, _ = env.reset(seed=0)
    a, b = env.cubes
    state[a][2] = 0.7776
    assert not env.goal_reached(state)
    state[b][2] = 0.9
    assert env.goal_reached(state)
    state[b][7] = 1.0  # held
    assert not env.goal_reached(state)
    state[b][7] = 0.0
    state[a][2] = 0.77
    assert not env.goal_reached(state)


def test_a_cube_raised_and_let_go_of_in_the_air_reaches_the_goal():
    env = PrplLab3DEnv(num_cubes=1)
    state, _ = env.reset(seed=0)
    cube = env.cubes[0]
    state[cube][:3] = (0.3, 0.6, 0.025)
    env.set_state(state)
    for p in ((0.3, 0.6, 0.2), (0.3, 0.6, 0.035)):
        state = move_ee(env, state, np.array(p))
    state, *_ = env.step(CLOSE)
    assert state[cube][7] == 1.0
    state = move_ee(env, state, np.array((0.3, 0.6, 0.85)))
    assert state[cube][2] == pytest.approx(0.84, abs=2e-3)
    state, _, terminated, _, _ = env.step(OPEN)
    assert state[cube][7] == 0.0 and state[env.robot][11] == 0.0
    assert state[cube][2] == pytest.approx(0.84, abs=2e-3)  # released in the air, it stays
    assert terminated
    env.close()
