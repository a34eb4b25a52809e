"""Reset validity: many seeds per family give collision-free states, inside the Box bounds, whose
goal does not already hold."""

from __future__ import annotations

import pytest

import kinder_core
from kinder_garden2d.kinematic2d.base import Kinematic2DEnv

# One variant per family in the default run (the largest count that keeps it quick); every
# variant in the slow run.
DEFAULT = [
    "kinder/Motion2D-p5-v0",
    "kinder/Obstruction2D-o4-v0",
    "kinder/ClutteredRetrieval2D-o10-v0",
    "kinder/ClutteredStorage2D-b15-v0",
    "kinder/StickButton2D-b10-v0",
    "kinder/PushPullHook2D-v0",
]
SEEDS = range(200)


def check_resets(env_id: str, seeds: range) -> None:
    env = kinder_core.make_object_centric(env_id)
    assert isinstance(env, Kinematic2DEnv)
    box = env.box_space
    for seed in seeds:
        state, info = env.reset(seed=seed)
        pairs = env.world.colliding_pairs(state.data)
        assert not pairs, f"{env_id} seed {seed}: initial collisions {pairs}"
        assert not env.goal_reached(state) and not info["success"], f"{env_id} seed {seed}"
        assert box.contains(box.vectorize(state)), f"{env_id} seed {seed}: outside the Box"
        assert env.held_objects(state) == [], f"{env_id} seed {seed}: holds something"


@pytest.mark.parametrize("env_id", DEFAULT)
def test_resets_are_valid(env_id: str) -> None:
    check_resets(env_id, SEEDS)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", sorted(set(kinder_core.list_envs("Kinematic2D")) - set(DEFAULT)))
def test_resets_are_valid_every_variant(env_id: str) -> None:
    check_resets(env_id, SEEDS)


def test_seeds_differ_and_repeat() -> None:
    env = kinder_core.make_object_centric("kinder/Obstruction2D-o2-v0")
    a, _ = env.reset(seed=1)
    b, _ = env.reset(seed=2)
    c, _ = env.reset(seed=1)
    assert a != b and a == c
