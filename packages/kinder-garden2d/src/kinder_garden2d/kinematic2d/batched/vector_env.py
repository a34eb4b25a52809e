"""A native Gymnasium vector env for the Kinematic2D ids: N sub-envs stepped in whole arrays.

:class:`Kinematic2DVectorEnv` is every Kinematic2D id's ``vector_entry_point``::

    gymnasium.make_vec("kinder/Motion2D-p0-v0", num_envs=1024,
                       vectorization_mode="vector_entry_point")

It behaves as ``gymnasium.make_vec(..., vectorization_mode="sync")`` does on the same id, bit for
bit: sub-env ``i`` of ``reset(seed=s)`` is the single env reset with seed ``s + i``; observations
are the Box view's vectors (same features, same dtype); rewards, terminations and the
``TimeLimit`` truncation are the single env's; ``info["success"]`` (with Gymnasium's
``info["_success"]`` mask) is the goal test; and a sub-env that ended is reset on the next
``step`` (``AutoresetMode.NEXT_STEP``: that step returns its first observation with reward 0,
ignoring its action).

Steps are whole-array numpy (:mod:`~kinder_garden2d.kinematic2d.batched.world`); resets, which
are rare, draw each sub-env's initial state with the single env's own sampler and RNG stream.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import ArrayLike, NDArray

from kinder_core import ObjectCentricState
from kinder_core.registration import load_entry_point
from kinder_garden2d.geometry import BoolArray, FloatArray
from kinder_garden2d.kinematic2d.base import Kinematic2DEnv
from kinder_garden2d.kinematic2d.batched.families import batched_world


class Kinematic2DVectorEnv(VectorEnv[NDArray[Any], NDArray[Any], NDArray[Any]]):
    """``num_envs`` sub-envs of one Kinematic2D env, stepped together.

    Args:
        num_envs: How many sub-envs (≥ 1).
        env_entry_point: ``"module:Class"`` of the single env (what the registry stores).
        max_episode_steps: The ``TimeLimit`` of each sub-env (None: no truncation).
        render_mode: ``"rgb_array"`` or None; :meth:`render` draws sub-env ``render_index``.
        render_index: Which sub-env :meth:`render` draws (see also :meth:`render_env`).
        **env_kwargs: The single env's constructor arguments (``num_passages=2``, ``config``).
    """

    metadata: dict[str, Any] = {  # noqa: RUF012 (gymnasium's convention)
        "render_modes": ["rgb_array"],
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int,
        env_entry_point: str,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        render_index: int = 0,
        **env_kwargs: Any,
    ) -> None:
        if int(num_envs) != num_envs or num_envs < 1:
            raise ValueError(
                f"Kinematic2DVectorEnv: num_envs must be an int >= 1, got {num_envs!r}"
            )
        if max_episode_steps is not None and max_episode_steps < 1:
            raise ValueError(
                f"Kinematic2DVectorEnv: max_episode_steps must be >= 1 or None, got "
                f"{max_episode_steps!r}"
            )
        if render_mode not in (None, "rgb_array"):
            raise ValueError(
                f"Kinematic2DVectorEnv: render_mode must be 'rgb_array' or None, got "
                f"{render_mode!r}"
            )
        cls = load_entry_point(env_entry_point)
        env = cls(render_mode=render_mode, **env_kwargs)
        if not isinstance(env, Kinematic2DEnv):
            raise ValueError(f"{env_entry_point} is not a Kinematic2D env")
        self.env = env
        self.num_envs = int(num_envs)
        self.max_episode_steps = max_episode_steps
        self.render_mode = render_mode
        self.render_index = self._index(render_index)
        self.world = batched_world(env)
        self.world.allocate(self.num_envs)
        box = env.box_space
        self._layout = box.layout
        self._obs_perm = np.array(
            [box.layout.index(o, f) for o in box.objects for f in o.type.features], dtype=np.intp
        )
        self._obs_dtype = box.dtype
        self.single_observation_space = box
        self.single_action_space = env.action_space
        self.observation_space = batch_space(box, self.num_envs)
        self.action_space = batch_space(env.action_space, self.num_envs)
        self._low = env.action_space.low.astype(np.float64)
        self._high = env.action_space.high.astype(np.float64)
        self.data = np.zeros((self.num_envs, self.world.size))
        self.elapsed = np.zeros(self.num_envs, dtype=np.int64)
        self._rngs: list[np.random.Generator | None] = [None] * self.num_envs
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._started = False

    # -- helpers --------------------------------------------------------------------------------
    @property
    def env_name(self) -> str:
        """The registered id when made by ``make_vec``, else the single env's class name."""
        return self.spec.id if self.spec is not None else type(self.env).__name__

    def _index(self, i: int) -> int:
        if int(i) != i or not 0 <= i < self.num_envs:
            raise ValueError(
                f"Kinematic2DVectorEnv: sub-env index must be an int in [0, {self.num_envs}), "
                f"got {i!r}"
            )
        return int(i)

    def _obs(self) -> NDArray[Any]:
        out: NDArray[Any] = self.data[:, self._obs_perm].astype(self._obs_dtype, copy=False)
        return out

    def _reset_rows(self, rows: NDArray[np.intp]) -> None:
        """Draw new initial states for sub-envs ``rows`` from their own RNGs."""
        for i in rows.tolist():
            rng = self._rngs[i]
            if rng is None:
                rng, _ = seeding.np_random(None)
                self._rngs[i] = rng
            self.data[i] = self.env._sample_initial_state(rng).data
        self.world.load_statics(rows, self.data)
        self.elapsed[rows] = 0

    def _seeds(self, seed: int | Sequence[int | None] | None) -> list[int | None]:
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, (int, np.integer)):
            return [int(seed) + i for i in range(self.num_envs)]
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(
                f"{self.env_name}: reset got {len(seeds)} seeds; expected one int, None or "
                f"{self.num_envs} seeds (one per sub-env)"
            )
        return seeds

    def check_actions(self, actions: ArrayLike, rows: NDArray[np.intp]) -> FloatArray:
        """Validate the batch of actions (the rows ``rows`` are stepped) and clip them to the
        bounds, raising the single env's errors (with the sub-env's index) on bad input."""
        try:
            a = np.asarray(actions, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise ValueError(
                f"{self.env_name}: actions {actions!r} are not numeric; expected an array of "
                f"shape {self.action_space.shape} in {self.single_action_space}"
            ) from e
        expected = (self.num_envs, *self._low.shape)
        if a.shape != expected:
            raise ValueError(
                f"{self.env_name}: actions have shape {a.shape}; expected shape {expected} "
                f"(one action of shape {self._low.shape} in {self.single_action_space} per sub-env)"
            )
        bad = rows[~np.isfinite(a[rows]).all(axis=1)]
        if bad.size:
            i = int(bad[0])
            raise ValueError(
                f"{self.env_name}: sub-env {i}'s action contains NaN or inf ({a[i]}); expected "
                f"finite values in {self.single_action_space}"
            )
        out: FloatArray = np.clip(a, self._low, self._high)
        return out

    # -- gymnasium API --------------------------------------------------------------------------
    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[NDArray[Any], dict[str, Any]]:
        """Reset every sub-env; ``seed`` (an int ``s``) seeds sub-env ``i`` with ``s + i``."""
        if options:
            raise ValueError(
                f"{self.env_name}: the batched env takes no reset options, got {sorted(options)}"
            )
        for i, s in enumerate(self._seeds(seed)):
            if s is not None or self._rngs[i] is None:
                self._rngs[i], _ = seeding.np_random(s)
        self._reset_rows(np.arange(self.num_envs))
        self._autoreset[:] = False
        self._started = True
        success = self.world.goal(self.data)
        return self._obs(), {"success": success, "_success": np.ones(self.num_envs, dtype=bool)}

    def step(
        self, actions: ArrayLike
    ) -> tuple[NDArray[Any], FloatArray, BoolArray, BoolArray, dict[str, Any]]:
        """Step every sub-env (reset those that ended on the previous step)."""
        if not self._started:
            raise RuntimeError(f"{self.env_name}: call reset() before step()")
        resets = np.flatnonzero(self._autoreset)
        stepped = np.flatnonzero(~self._autoreset)
        a = self.check_actions(actions, stepped)
        if resets.size:
            a[resets] = 0.0  # ignored: those sub-envs reset instead
        self.data = self.world.transition(self.data, a)
        terminated = self.world.goal(self.data)
        rewards = self.world.reward(terminated)
        self.elapsed += 1
        if self.max_episode_steps is None:
            truncated = np.zeros(self.num_envs, dtype=bool)
        else:
            truncated = self.elapsed >= self.max_episode_steps
        success = terminated.copy()
        if resets.size:
            self._reset_rows(resets)
            rewards[resets] = 0.0
            terminated[resets] = False
            truncated[resets] = False
            success[resets] = self.world.goal(self.data[resets])
        self._autoreset = terminated | truncated
        info = {"success": success, "_success": np.ones(self.num_envs, dtype=bool)}
        return self._obs(), rewards, terminated, truncated, info

    def reset_ended(self) -> tuple[NDArray[Any], BoolArray, BoolArray]:
        """Reset now every sub-env that ended on the last step, instead of on the next one:
        Stable-Baselines3's autoreset (``AutoresetMode.SAME_STEP``). Returns the observations
        (the new first ones for the reset sub-envs), which sub-envs were reset, and their goal
        test (``info["success"]`` of their reset)."""
        rows = np.flatnonzero(self._autoreset)
        if rows.size:
            self._reset_rows(rows)
            self._autoreset[rows] = False
        success = np.zeros(self.num_envs, dtype=bool)
        success[rows] = self.world.goal(self.data[rows])
        reset = np.zeros(self.num_envs, dtype=bool)
        reset[rows] = True
        return self._obs(), reset, success

    # -- states and rendering -------------------------------------------------------------------
    def get_state(self, index: int) -> ObjectCentricState:
        """A copy of sub-env ``index``'s live state."""
        return ObjectCentricState(self._layout, self.data[self._index(index)].copy())

    def set_state(self, index: int, state: ObjectCentricState | ArrayLike) -> None:
        """Replace sub-env ``index``'s live state (a state or a Box vector), as the single env's
        ``set_state`` does; its episode's step count is kept."""
        i = self._index(index)
        self.data[i] = self.env._coerce_state(state, "state").data
        self.world.load_statics(np.array([i], dtype=np.intp), self.data)

    def render_env(self, index: int) -> NDArray[np.uint8]:
        """An RGB frame of sub-env ``index``."""
        if not self._started:
            raise RuntimeError(f"{self.env_name}: call reset() before render_env()")
        return self.env.render_state(self.get_state(index))

    def render(self) -> tuple[NDArray[np.uint8], ...] | None:
        """A one-frame tuple: sub-env ``render_index``'s RGB frame (None without a render mode;
        drawing every sub-env would cost far more than stepping them)."""
        if self.render_mode is None:
            return None
        return (self.render_env(self.render_index),)

    def close_extras(self, **kwargs: Any) -> None:
        """Nothing to release (no processes or simulators)."""


__all__ = ["Kinematic2DVectorEnv"]
