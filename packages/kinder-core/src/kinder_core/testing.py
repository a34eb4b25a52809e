"""The test kit: one call that checks any registered KinDER id against the env contract.

Use it from a package's tests, parametrized over the package's ids::

    @pytest.mark.parametrize("env_id", kinder_core.list_envs("Kinematic2D"))
    def test_contract(env_id):
        check_kinder_env(env_id)

or run the checks one by one (:data:`CHECKS`) to see which part fails.
"""

from __future__ import annotations

import hashlib
import pickle
import subprocess
import sys
import warnings
from collections.abc import Callable
from typing import Any, cast

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

from kinder_core.env import ObjectCentricEnv
from kinder_core.registration import make, make_object_centric
from kinder_core.spaces import ObjectCentricBoxSpace
from kinder_core.wrappers import BoxObservation

# Warnings gymnasium's checker raises for legitimate object-centric Box views (Gymnasium's own
# registry tests whitelist the same ones).
_ALLOWED_CHECKER_WARNINGS = (
    "is different from the unwrapped version",
    "infinity",  # unbounded Box features (gymnasium: "minimum value is -infinity")
    "precision",
    "normaliz",
    "symmetric",
    "not within the observation space",  # only for the object-centric (non-Box) layer, see below
)
REPLAY_ATOL = 1e-9


def _rollout_actions(space: spaces.Space[Any], seed: int, n: int) -> list[Any]:
    space = pickle.loads(pickle.dumps(space))
    space.seed(seed)
    return [space.sample() for _ in range(n)]


def check_docs(env_id: str) -> None:
    """Metadata holds the user documentation and the Box view's observation table."""
    env = make(env_id)
    try:
        md = env.metadata
        for key in (
            "description",
            "observation_space",
            "action_space",
            "reward",
            "starting_state",
            "episode_end",
            "version_history",
            "variant",
            "observation_table",
        ):
            assert md.get(key), f"{env_id}: metadata[{key!r}] is missing or empty"
        box = cast(ObjectCentricBoxSpace, env.get_wrapper_attr("box"))
        assert len(box.feature_names) == box.shape[0], f"{env_id}: names do not cover the Box"
        assert env.spec is not None and env.spec.max_episode_steps, f"{env_id}: no step budget"
    finally:
        env.close()


def check_gymnasium_checker(env_id: str) -> None:
    """gymnasium's ``check_env`` on the Box view and on the object-centric env; unexpected
    checker warnings fail."""
    for layer in ("box", "object_centric"):
        oc = make_object_centric(env_id)
        env: gymnasium.Env[Any, Any] = BoxObservation(oc) if layer == "box" else oc
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                check_env(env, skip_render_check=True)
            allowed = _ALLOWED_CHECKER_WARNINGS[: -1 if layer == "box" else None]
            bad = [str(w.message) for w in caught if not any(a in str(w.message) for a in allowed)]
            assert not bad, f"{env_id} ({layer}): gymnasium checker warnings: {bad}"
        finally:
            env.close()


def check_box_roundtrip(env_id: str, seed: int = 0) -> None:
    """``vectorize``/``devectorize`` are exact inverses and observations lie in the Box."""
    env = make(env_id)
    try:
        obs, _ = env.reset(seed=seed)
        box = cast(ObjectCentricBoxSpace, env.get_wrapper_attr("box"))
        assert isinstance(obs, np.ndarray) and obs.shape == box.shape, f"{env_id}: obs shape"
        assert box.contains(obs), f"{env_id}: reset observation outside the Box bounds"
        state = box.devectorize(obs)
        live = cast(ObjectCentricEnv, env.unwrapped).get_state()
        assert state == live, f"{env_id}: devectorize(obs) differs from the live state"
        assert np.array_equal(box.vectorize(state), obs), f"{env_id}: round trip is not exact"
        env.action_space.seed(seed)
        for _ in range(5):
            obs, *_ = env.step(env.action_space.sample())
            assert box.contains(obs), f"{env_id}: step observation outside the Box bounds"
    finally:
        env.close()


def _equal_step(a: tuple[Any, ...], b: tuple[Any, ...]) -> bool:
    obs_a, r_a, te_a, tr_a, info_a = a
    obs_b, r_b, te_b, tr_b, info_b = b
    return (
        np.array_equal(obs_a, obs_b)
        and r_a == r_b
        and te_a == te_b
        and tr_a == tr_b
        and info_a == info_b
    )


def check_twin_determinism(env_id: str, num_steps: int = 50, seed: int = 0) -> None:
    """Two instances, same seed, same actions: identical observations, rewards, flags, infos."""
    env1, env2 = make(env_id), make(env_id)
    try:
        o1, i1 = env1.reset(seed=seed)
        o2, i2 = env2.reset(seed=seed)
        assert np.array_equal(o1, o2) and i1 == i2, f"{env_id}: seeded resets differ"
        for t, action in enumerate(_rollout_actions(env1.action_space, seed, num_steps)):
            s1, s2 = env1.step(action), env2.step(action)
            assert _equal_step(s1, s2), f"{env_id}: twin rollouts diverge at step {t}"
            if s1[2] or s1[3]:
                o1, _ = env1.reset()
                o2, _ = env2.reset()
                assert np.array_equal(o1, o2), f"{env_id}: unseeded re-resets differ"
    finally:
        env1.close()
        env2.close()


def check_set_state_determinism(env_id: str, seed: int = 0, horizon: int = 5) -> None:
    """``set_state(s)`` then the same actions reproduces the first pass through ``s``, every
    time, even after the env did other things in between."""
    env = make_object_centric(env_id)
    try:
        env.reset(seed=seed)
        actions = _rollout_actions(env.action_space, seed, 3 + horizon)
        for a in actions[:3]:
            env.step(a)
        start = env.get_state()
        original = [env.step(a)[0] for a in actions[3:]]
        for replay in range(3):
            env.set_state(start)
            for t, a in enumerate(actions[3:]):
                got = env.step(a)[0]
                assert got.allclose(original[t], atol=REPLAY_ATOL), (
                    f"{env_id}: replay {replay} from set_state differs at step {t} by "
                    f"{np.max(np.abs(got.data - original[t].data)):.3g}"
                )
            # Stir hidden simulator state before the next replay.
            env.reset(seed=seed + 1 + replay)
            for a in actions[::-1]:
                env.step(a)
    finally:
        env.close()


def check_transition(env_id: str, seed: int = 0) -> None:
    """``transition(s, a)`` agrees with ``step(a)`` from ``s`` and leaves the live episode alone."""
    env = make_object_centric(env_id)
    try:
        env.reset(seed=seed)
        actions = _rollout_actions(env.action_space, seed, 6)
        for a in actions[:3]:
            env.step(a)
        live = env.get_state()
        for a in actions[3:]:
            pred, reward, terminated = env.transition(live, a)
            assert env.get_state() == live, f"{env_id}: transition() changed the live state"
            other = env.transition(pred, actions[0])  # extra model use between the two
            del other
            obs, r, term, _, _ = env.step(a)
            assert obs.allclose(pred, atol=REPLAY_ATOL), f"{env_id}: transition != step"
            assert (r, term) == (reward, terminated), f"{env_id}: transition reward/flag != step"
            live = env.get_state()
    finally:
        env.close()


def check_bad_actions(env_id: str, seed: int = 0) -> None:
    """Wrong shape, NaN and inf raise a ValueError naming the env and the space; finite
    out-of-bound actions are clipped."""
    env = make_object_centric(env_id)
    try:
        env.reset(seed=seed)
        space = env.action_space
        good = np.asarray(space.sample(), dtype=np.float64)
        bad_actions = {
            "wrong shape": np.zeros(good.size + 1),
            "NaN": np.where(np.arange(good.size) == 0, np.nan, good),
            "inf": np.where(np.arange(good.size) == 0, np.inf, good),
        }
        for what, bad in bad_actions.items():
            try:
                env.step(bad)
            except ValueError as e:
                msg = str(e)
                assert env.env_name in msg and "expected" in msg, (
                    f"{env_id}: the {what} error should name the env and the expected space: "
                    f"{msg!r}"
                )
            else:
                raise AssertionError(f"{env_id}: a {what} action was accepted")
        start = env.get_state()
        high = space.high.astype(np.float64)
        clipped = env.transition(start, high)[0]
        beyond = env.transition(start, high + 10.0 * (np.abs(high) + 1.0))[0]
        assert clipped == beyond, f"{env_id}: out-of-bound actions are not clipped"
    finally:
        env.close()


def check_pickle(env_id: str, seed: int = 0) -> None:
    """A pickled and restored env continues exactly like the original."""
    env = make(env_id)
    try:
        env.reset(seed=seed)
        actions = _rollout_actions(env.action_space, seed, 8)
        for a in actions[:3]:
            env.step(a)
        clone = pickle.loads(pickle.dumps(env))
        try:
            for t, a in enumerate(actions[3:]):
                assert _equal_step(env.step(a), clone.step(a)), f"{env_id}: clone diverges at {t}"
        finally:
            clone.close()
    finally:
        env.close()


def check_render(env_id: str, seed: int = 0) -> None:
    """``render()`` returns H×W×3 uint8 frames, the same frame for the same state."""
    env = make(env_id, render_mode="rgb_array")
    try:
        env.reset(seed=seed)
        frame = env.render()
        assert isinstance(frame, np.ndarray), f"{env_id}: render() returned {type(frame)}"
        assert frame.dtype == np.uint8, f"{env_id}: frame dtype {frame.dtype}, expected uint8"
        assert frame.ndim == 3 and frame.shape[2] == 3 and min(frame.shape[:2]) > 0, (
            f"{env_id}: frame shape {frame.shape}, expected (H, W, 3)"
        )
        again = cast(np.ndarray, env.render())
        assert np.array_equal(frame, again), f"{env_id}: render() is not repeatable"
        assert frame.std() > 0, f"{env_id}: the frame is blank"
        env.action_space.seed(seed)
        env.step(env.action_space.sample())
        after = env.render()
        assert isinstance(after, np.ndarray) and after.shape == frame.shape
    finally:
        env.close()


def rollout_digest(env_id: str, seed: int = 0, num_steps: int = 20) -> str:
    """A digest of a seeded random rollout (observations and rewards)."""
    env = make(env_id)
    try:
        h = hashlib.blake2b(digest_size=16)
        obs, _ = env.reset(seed=seed)
        h.update(np.asarray(obs, dtype="<f8").tobytes())
        for a in _rollout_actions(env.action_space, seed, num_steps):
            obs, r, term, trunc, _ = env.step(a)
            h.update(np.asarray(obs, dtype="<f8").tobytes() + repr((float(r), term)).encode())
            if term or trunc:
                obs, _ = env.reset()
                h.update(np.asarray(obs, dtype="<f8").tobytes())
        return h.hexdigest()
    finally:
        env.close()


def check_cross_process_determinism(env_id: str, seed: int = 0) -> None:
    """The same seeded rollout in a fresh interpreter (new hash seed) gives the same digest."""
    code = (
        "import sys; from kinder_core.testing import rollout_digest; "
        f"print(rollout_digest({env_id!r}, {seed}))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        env={**__import__("os").environ, "PYTHONHASHSEED": "12345"},
    )
    assert out.stdout.strip() == rollout_digest(env_id, seed), (
        f"{env_id}: a rollout in another process differs"
    )


def check_vector_consistency(env_id: str, num_envs: int = 2, num_steps: int = 20) -> None:
    """``SyncVectorEnv`` and ``AsyncVectorEnv`` give identical results under identical seeds.

    Each sub-env gets ``seed + index`` and sees the same actions; a sub-env that ends autoresets
    in gymnasium's default (next-step) mode.
    """

    def thunk() -> gymnasium.Env[Any, Any]:
        return make(env_id)

    sync = gymnasium.vector.SyncVectorEnv([thunk] * num_envs)
    asyn = gymnasium.vector.AsyncVectorEnv([thunk] * num_envs)
    try:
        o_s, _ = sync.reset(seed=0)
        o_a, _ = asyn.reset(seed=0)
        assert np.array_equal(o_s, o_a), f"{env_id}: Sync and Async resets differ"
        for t, action in enumerate(_rollout_actions(sync.action_space, 0, num_steps)):
            o_s, r_s, te_s, tr_s, _ = sync.step(action)
            o_a, r_a, te_a, tr_a, _ = asyn.step(action)
            assert np.array_equal(o_s, o_a), f"{env_id}: Sync and Async differ at step {t}"
            assert np.array_equal(r_s, r_a), f"{env_id}: rewards differ at step {t}"
            assert np.array_equal(te_s, te_a), f"{env_id}: terminations differ at step {t}"
            assert np.array_equal(tr_s, tr_a), f"{env_id}: truncations differ at step {t}"
    finally:
        sync.close()
        asyn.close()


CHECKS: dict[str, Callable[[str], None]] = {
    "docs": check_docs,
    "gymnasium_checker": check_gymnasium_checker,
    "box_roundtrip": check_box_roundtrip,
    "twin_determinism": check_twin_determinism,
    "set_state_determinism": check_set_state_determinism,
    "transition": check_transition,
    "bad_actions": check_bad_actions,
    "pickle": check_pickle,
    "render": check_render,
}


def check_kinder_env(
    env_id: str,
    *,
    skip: tuple[str, ...] = (),
    cross_process: bool = False,
    vector: bool = False,
) -> None:
    """Run every check of :data:`CHECKS` on ``env_id`` (minus ``skip``); with ``cross_process``,
    also compare a rollout against a fresh interpreter; with ``vector``, compare Sync and Async
    vector envs (both spawn processes, so families run them on one id each)."""
    unknown = set(skip) - set(CHECKS)
    if unknown:
        raise ValueError(f"Unknown check(s) {sorted(unknown)}; known: {sorted(CHECKS)}")
    for name, check in CHECKS.items():
        if name not in skip:
            check(env_id)
    if cross_process:
        check_cross_process_determinism(env_id)
    if vector:
        check_vector_consistency(env_id)
