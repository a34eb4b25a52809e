"""Reset validity over 100 seeds per family: in bounds, collision-free, supported, not solved."""

from __future__ import annotations

import numpy as np
import pytest

import kinder_core
import kinder_garden3d  # noqa: F401  (registers the ids)
from kinder_garden3d.kinematic3d.base_motion3d import BaseMotion3DEnv
from kinder_garden3d.kinematic3d.obstruction3d import Obstruction3DEnv
from kinder_garden3d.kinematic3d.packing3d import Packing3DEnv
from kinder_garden3d.kinematic3d.table3d import Table3DEnv
from kinder_garden3d.kinematic3d.transport3d import Transport3DEnv

FAMILIES = {
    "BaseMotion3D": lambda: BaseMotion3DEnv(),
    "Obstruction3D-o4": lambda: Obstruction3DEnv(num_obstructions=4),
    "Packing3D-p3": lambda: Packing3DEnv(num_parts=3),
    "Table3D-o3": lambda: Table3DEnv(num_cubes=3),
    "Transport3D-o2": lambda: Transport3DEnv(num_cubes=2),
}


@pytest.mark.parametrize("family", list(FAMILIES))
def test_resets_are_valid_over_100_seeds(family):
    env = FAMILIES[family]()
    try:
        box = env.box_space
        seen = set()
        for seed in range(100):
            state, info = env.reset(seed=seed)
            assert box.contains(box.vectorize(state)), f"{family} seed {seed}: outside the Box"
            assert not info["success"] and not env.goal_reached(state), f"seed {seed} is solved"
            assert env.penetrations(state) == [], f"{family} seed {seed}: {env.penetrations(state)}"
            for name in env.movable_names(state):
                gap = env.support_gap(state, name)
                # Upstream's floor top is 5 mm below the objects standing on the floor.
                ok = abs(gap) < 1e-6 or abs(gap - 0.005) < 1e-9
                assert ok, f"{family} seed {seed}: {name} is not resting ({gap})"
            seen.add(state.stable_hash())
        assert len(seen) == 100, f"{family}: repeated initial states"
    finally:
        env.close()


def test_obstructions_mostly_start_on_the_region():
    env = Obstruction3DEnv(num_obstructions=4)
    on_region = total = 0
    for seed in range(100):
        state, _ = env.reset(seed=seed)
        top = state[env.region][2] + state[env.region][11]
        for obs in env.obstructions:
            total += 1
            on_region += bool(abs(state[obs][2] - state[obs][11] - top) < 1e-9)
    env.close()
    # The coin says 0.9 per try, but crowded regions reject more on-region draws: 303 of 400
    # obstructions on seeds 0-99, as upstream's own resets (the same states, seed for seed).
    assert 0.7 < on_region / total < 0.9


def test_packing_parts_start_outside_the_expanded_rack_footprint():
    env = Packing3DEnv(num_parts=3)
    for seed in range(50):
        state, _ = env.reset(seed=seed)
        rack = state[env.rack]
        for part in env.parts:
            x, y = state[part][:2]
            assert not (abs(x - rack[0]) < 0.15 and abs(y - rack[1]) < 0.225)
            assert 0.1 <= x <= 0.4 + 1e-9
    env.close()


def test_same_seed_same_state_in_fresh_instances():
    for make in FAMILIES.values():
        a, b = make(), make()
        sa, _ = a.reset(seed=42)
        sb, _ = b.reset(seed=42)
        assert sa == sb
        assert np.array_equal(a.box_space.vectorize(sa), b.box_space.vectorize(sb))
        a.close()
        b.close()


@pytest.mark.slow
@pytest.mark.parametrize("env_id", kinder_core.list_envs("Kinematic3D"))
def test_every_variant_resets_validly_over_300_seeds(env_id):
    env = kinder_core.make_object_centric(env_id)
    try:
        for seed in range(300):
            state, _ = env.reset(seed=seed)
            assert not env.goal_reached(state), f"{env_id} seed {seed} is solved"
            assert env.penetrations(state) == [], f"{env_id} seed {seed}"
            for name in env.movable_names(state):
                gap = env.support_gap(state, name)
                ok = abs(gap) < 1e-6 or abs(gap - 0.005) < 1e-9  # upstream's floor: 5 mm below
                if gap == np.inf:  # the shelf families: on the floor, which is not a surface
                    f = state[state.get_object_from_name(name)]
                    ok = f[2] == f[11]
                assert ok, f"{env_id} seed {seed}: {name} ({gap})"
    finally:
        env.close()
