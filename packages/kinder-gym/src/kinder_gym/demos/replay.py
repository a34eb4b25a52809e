"""Replaying recorded episodes from their reset seed, and checking they reproduce.

Every KinDER env is deterministic: ``reset(seed)`` followed by the recorded (clipped) actions
reproduces the episode's states exactly in any process. :func:`replay_record` checks this to a
tolerance (1e-9 by default) on every feature of every state, plus the rewards and the
termination flag, and reports the first step that differs.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_core import ObjectCentricEnv
from kinder_gym.demos.record import EpisodeRecord

#: The default tolerance of :func:`replay_record` (absolute, per feature).
REPLAY_ATOL = 1e-9


def _model(env: gymnasium.Env[Any, Any] | ObjectCentricEnv) -> ObjectCentricEnv:
    model = env.unwrapped
    if not isinstance(model, ObjectCentricEnv):
        raise TypeError(f"Replay needs a KinDER env, got {type(model).__name__}")
    return model


def replay_rollout(
    env: gymnasium.Env[Any, Any] | ObjectCentricEnv, record: EpisodeRecord
) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:
    """``(states (T + 1, D), rewards (T,), terminated)`` from replaying ``record``'s actions on
    ``env``'s object-centric model from its seed (no time limit applies)."""
    model = _model(env)
    if model.env_name != record.env_id and model.spec is not None:
        raise ValueError(f"Record of {record.env_id} cannot replay on {model.env_name}")
    box = model.box_space
    state, _ = model.reset(seed=int(record.seed))
    states = [box.vectorize(state).astype(np.float64)]
    rewards = []
    terminated = False
    for action in record.actions:
        state, reward, terminated, _, _ = model.step(action)
        states.append(box.vectorize(state).astype(np.float64))
        rewards.append(float(reward))
    return np.stack(states), np.asarray(rewards, dtype=np.float64), bool(terminated)


def replay_states(
    env: gymnasium.Env[Any, Any] | ObjectCentricEnv, record: EpisodeRecord
) -> NDArray[np.float64]:
    """The ``(T + 1, D)`` state vectors of ``record``, recovered by replay."""
    return replay_rollout(env, record)[0]


@dataclasses.dataclass(frozen=True)
class ReplayResult:
    """The outcome of replaying one episode."""

    name: str
    """Which episode (e.g. ``episode 3 (seed 123)``)."""
    ok: bool
    max_error: float
    """The largest absolute difference over every feature of every state."""
    first_bad_step: int | None
    """The first time index whose state differs by more than the tolerance (None: none)."""
    message: str


def replay_record(
    env: gymnasium.Env[Any, Any] | ObjectCentricEnv,
    record: EpisodeRecord,
    atol: float = REPLAY_ATOL,
    name: str | None = None,
) -> ReplayResult:
    """Replay ``record`` from its seed and compare states (``record.states``, or the
    observations when states were not stored), rewards and termination."""
    name = name or f"{record.env_id} seed {record.seed}"
    if record.seed < 0:
        return ReplayResult(
            name, False, float("inf"), 0, f"{name}: the reset seed is unknown (imported episode)"
        )
    try:
        states, rewards, terminated = replay_rollout(env, record)
    except Exception as e:  # a record whose actions an env rejects does not replay
        return ReplayResult(name, False, float("inf"), 0, f"{name}: replay raised {e!r}")
    expected = record.states if record.states is not None else record.observations
    if expected.shape != states.shape:
        return ReplayResult(
            name,
            False,
            float("inf"),
            0,
            f"{name}: recorded states have shape {expected.shape}, replay gives {states.shape}",
        )
    err = np.abs(states - expected)
    max_error = float(err.max()) if err.size else 0.0
    bad = np.flatnonzero(err.max(axis=1) > atol) if err.size else np.zeros(0, dtype=np.intp)
    problems = []
    first = int(bad[0]) if len(bad) else None
    if first is not None:
        problems.append(
            f"states differ from step {first} on (max error {max_error:.3g} > {atol:g})"
        )
    if not np.array_equal(rewards, record.rewards):
        problems.append("rewards differ")
    if terminated != record.terminated:
        problems.append(f"terminated is {terminated} on replay, {record.terminated} recorded")
    ok = not problems
    message = f"{name}: " + ("replays exactly" if ok else "; ".join(problems))
    return ReplayResult(name, ok, max_error, first, message)


__all__ = ["REPLAY_ATOL", "ReplayResult", "replay_record", "replay_rollout", "replay_states"]
