"""Wrappers: the fixed-object Box view, and the paper's observation and action noise."""

from __future__ import annotations

from typing import Any, SupportsFloat, cast

import gymnasium
import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from kinder_core.env import ObjectCentricEnv
from kinder_core.spaces import ObjectCentricBoxSpace
from kinder_core.state import FloatArray, ObjectCentricState


class BoxObservation(gymnasium.ObservationWrapper[FloatArray, FloatArray, ObjectCentricState]):
    """Observations as fixed-size float64 vectors (the registered ids' observation).

    The vector layout is ``env.box_space`` (robot and goal objects first, then the rest by name,
    as each family documents). ``get_state``/``set_state``/``transition`` work on vectors here;
    ``env.unwrapped`` is the object-centric env.
    """

    def __init__(self, env: ObjectCentricEnv) -> None:
        super().__init__(env)
        self.box: ObjectCentricBoxSpace = env.box_space
        self.observation_space = self.box  # type: ignore[assignment]

    @property
    def oc_env(self) -> ObjectCentricEnv:
        """The wrapped object-centric env."""
        return cast(ObjectCentricEnv, self.env.unwrapped)

    def observation(self, observation: ObjectCentricState) -> FloatArray:
        return cast(FloatArray, self.box.vectorize(observation))

    def vectorize(self, state: ObjectCentricState) -> FloatArray:
        """A state as a vector."""
        return cast(FloatArray, self.box.vectorize(state))

    def devectorize(self, vector: ArrayLike) -> ObjectCentricState:
        """A vector as a state."""
        return self.box.devectorize(vector)

    def get_state(self) -> FloatArray:
        """The live state as a vector."""
        return self.vectorize(self.oc_env.get_state())

    def set_state(self, state: ObjectCentricState | ArrayLike) -> None:
        """Set the live state from a vector (or a state)."""
        self.oc_env.set_state(state)

    def transition(
        self, state: ObjectCentricState | ArrayLike, action: ArrayLike
    ) -> tuple[FloatArray, float, bool]:
        """The pure transition on vectors."""
        s, r, term = self.oc_env.transition(state, action)
        return self.vectorize(s), r, term


def _derive_rng(env: gymnasium.Env[Any, Any], seed: int | None, tag: int) -> np.random.Generator:
    """A wrapper-private RNG: from the reset seed when given, else drawn once from the env's RNG."""
    if seed is not None:
        return np.random.default_rng([seed, tag])
    return np.random.default_rng(env.unwrapped.np_random.integers(2**63))


class NoisyObservation(gymnasium.Wrapper[Any, Any, Any, Any]):
    """Adds Gaussian noise (std ``std``, scalar or per-dimension) to every observation.

    Works on Box vectors and on object-centric states (noise on every feature). A noisy Box
    vector is clipped to the observation space's bounds, as upstream's ``NoisyObservation`` does
    (a feature at its bound, a radius of 0 say, stays inside the space). The noise RNG is seeded
    from ``reset(seed=...)`` (so a seeded episode is reproducible), or drawn once from the env's
    RNG when no seed was ever given.
    """

    _TAG = 0x6F6273  # distinguishes this wrapper's stream from NoisyAction's

    def __init__(self, env: gymnasium.Env[Any, Any], std: ArrayLike) -> None:
        super().__init__(env)
        self.std = np.asarray(std, dtype=np.float64)
        if np.any(self.std < 0) or not np.all(np.isfinite(self.std)):
            raise ValueError(f"NoisyObservation: std must be finite and >= 0, got {std!r}")
        self._rng: np.random.Generator | None = None

    def _noisy(self, obs: Any) -> Any:
        assert self._rng is not None
        if isinstance(obs, ObjectCentricState):
            out = obs.copy()
            out.data += self._rng.normal(0.0, 1.0, out.data.shape) * self.std
            return out
        arr = np.asarray(obs)
        noisy = arr + self._rng.normal(0.0, 1.0, arr.shape) * self.std
        space = self.observation_space
        if isinstance(space, spaces.Box) and space.shape == arr.shape:
            noisy = np.clip(noisy, space.low, space.high)
        return noisy.astype(arr.dtype, copy=False)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        if seed is not None or self._rng is None:
            self._rng = _derive_rng(self.env, seed, self._TAG)
        return self._noisy(obs), info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._noisy(obs), reward, terminated, truncated, info


class NoisyAction(gymnasium.ActionWrapper[Any, NDArray[Any], NDArray[Any]]):
    """Adds Gaussian noise (std ``std``, scalar or per-dimension) to every action, then clips the
    result to the action bounds. Seeded like :class:`NoisyObservation`."""

    _TAG = 0x616374

    def __init__(self, env: gymnasium.Env[Any, Any], std: ArrayLike) -> None:
        super().__init__(env)
        if not isinstance(env.action_space, spaces.Box):
            raise ValueError(f"NoisyAction needs a Box action space, got {env.action_space}")
        self.std = np.asarray(std, dtype=np.float64)
        if np.any(self.std < 0) or not np.all(np.isfinite(self.std)):
            raise ValueError(f"NoisyAction: std must be finite and >= 0, got {std!r}")
        self._rng: np.random.Generator | None = None

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        out = self.env.reset(seed=seed, options=options)
        if seed is not None or self._rng is None:
            self._rng = _derive_rng(self.env, seed, self._TAG)
        return out

    def action(self, action: NDArray[Any]) -> NDArray[Any]:
        if self._rng is None:
            raise RuntimeError("NoisyAction: call reset() before step()")
        box = cast(spaces.Box, self.action_space)
        a = np.asarray(action, dtype=np.float64)
        noisy = a + self._rng.normal(0.0, 1.0, a.shape) * self.std
        return np.clip(noisy, box.low, box.high).astype(box.dtype)
