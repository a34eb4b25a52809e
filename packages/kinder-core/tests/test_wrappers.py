import numpy as np
import pytest
from toy_env import ToyReach

import kinder_core
from kinder_core import NoisyAction, NoisyObservation


def test_noisy_observation_is_seeded_and_works_on_boxes_and_states(toy_id: str) -> None:
    clean = kinder_core.make(toy_id)
    a, b = (
        NoisyObservation(kinder_core.make(toy_id), 0.05),
        NoisyObservation(kinder_core.make(toy_id), 0.05),
    )
    o_clean, _ = clean.reset(seed=1)
    oa, _ = a.reset(seed=1)
    ob, _ = b.reset(seed=1)
    np.testing.assert_array_equal(oa, ob)
    assert not np.array_equal(oa, o_clean)
    assert np.abs(oa - o_clean).max() < 0.5
    oc = NoisyObservation(ToyReach(), 0.05)
    s, _ = oc.reset(seed=1)
    assert isinstance(s, kinder_core.ObjectCentricState)
    with pytest.raises(ValueError, match="std"):
        NoisyObservation(clean, -1.0)


def test_noisy_observation_stays_in_the_observation_space(toy_id: str) -> None:
    """Like upstream's wrapper: noise far larger than the space is clipped to its bounds."""
    env = NoisyObservation(kinder_core.make(toy_id), 100.0)
    space = env.observation_space
    obs, _ = env.reset(seed=3)
    for _ in range(3):
        assert space.contains(obs)
        assert np.any(obs == space.low) or np.any(obs == space.high)
        obs, *_ = env.step(env.action_space.sample())


def test_noisy_action_clips_to_bounds_and_is_seeded() -> None:
    env = ToyReach()
    noisy = NoisyAction(env, [1.0, 0.0])
    noisy.reset(seed=2)
    a = noisy.action(np.zeros(2))
    assert np.all(np.abs(a) <= 0.1) and a[1] == 0.0
    again = NoisyAction(ToyReach(), [1.0, 0.0])
    again.reset(seed=2)
    np.testing.assert_array_equal(again.action(np.zeros(2)), a)
