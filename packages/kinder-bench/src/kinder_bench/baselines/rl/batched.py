"""The batched Kinematic2D vector env as a Stable-Baselines3 ``VecEnv`` (``--vec-env batched``).

:class:`BatchedVecEnv` gives SB3 exactly what ``DummyVecEnv`` of
:func:`~kinder_bench.baselines.rl.envs.make_rl_env` gives it, bit for bit, with all sub-envs
stepped in whole arrays by :class:`~kinder_garden2d.kinematic2d.batched.vector_env.
Kinematic2DVectorEnv`: float32 observations, actions rescaled from [-1, 1] by Gymnasium's own
``rescale_box``, float32 rewards, SB3's same-step autoreset (``terminal_observation`` and
``TimeLimit.truncated`` in the infos), and the ``EpisodeOutcome`` infos (``episode`` with
``r``/``l``/``t`` and ``is_success``) on the last step of every episode. Sub-env ``i`` resets
with ``seed + i`` after ``seed(seed)``, as ``DummyVecEnv`` does.

Only the Kinematic2D ids have a batched env, and only their own sparse reward.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.wrappers.utils import rescale_box
from numpy.typing import NDArray
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

from kinder_core.registration import ensure_registered
from kinder_garden2d.kinematic2d.batched.vector_env import Kinematic2DVectorEnv


class BatchedVecEnv(VecEnv):
    """``n_envs`` sub-envs of a Kinematic2D id for SB3 (see the module docstring).

    Args:
        env_id: A registered Kinematic2D id.
        n_envs: How many sub-envs.
        max_episode_steps: The training episode limit (``TimeLimit``).
        **env_kwargs: Constructor arguments of the single env that replace the id's own
            (``config=Motion2DConfig(...)``).

    Raises:
        ValueError: for an id that has no batched env.
    """

    def __init__(self, env_id: str, n_envs: int, max_episode_steps: int, **env_kwargs: Any) -> None:
        ensure_registered(env_id)
        spec = gymnasium.spec(env_id)
        if spec.vector_entry_point is None:
            raise ValueError(
                f"--vec-env batched needs a batched env; {env_id} has none (the Kinematic2D ids "
                f"have one); use --vec-env dummy or subproc"
            )
        venv = gymnasium.make_vec(
            env_id,
            n_envs,
            vectorization_mode="vector_entry_point",
            max_episode_steps=max_episode_steps,
            **env_kwargs,
        )
        if not isinstance(venv, Kinematic2DVectorEnv):
            raise ValueError(f"{env_id}'s vector env is not a Kinematic2DVectorEnv")
        self.venv = venv
        box = venv.single_observation_space
        assert isinstance(box, spaces.Box)
        observation_space = spaces.Box(
            box.low.astype(np.float32), box.high.astype(np.float32), dtype=np.float32
        )
        act = venv.single_action_space
        assert isinstance(act, spaces.Box)
        ones = np.ones(act.shape, dtype=act.dtype)
        action_space, _, self._unscale = rescale_box(act, -ones, ones)
        super().__init__(n_envs, observation_space, action_space)
        self._actions = np.zeros((n_envs, *action_space.shape), dtype=np.float32)
        self._returns = np.zeros(n_envs)
        self._lengths = np.zeros(n_envs, dtype=np.int64)
        self._starts = [time.perf_counter()] * n_envs

    def _start_episodes(self, rows: Iterable[int]) -> None:
        now = time.perf_counter()
        for i in rows:
            self._returns[i], self._lengths[i], self._starts[i] = 0.0, 0, now

    def reset(self) -> VecEnvObs:
        seeds = self._seeds
        seed = None if all(s is None for s in seeds) else list(seeds)
        obs, info = self.venv.reset(seed=seed)
        self._reset_seeds()
        self._reset_options()
        self._start_episodes(range(self.num_envs))
        self.reset_infos = [{"success": bool(s)} for s in info["success"]]
        return obs.astype(np.float32)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, terminated, truncated, info = self.venv.step(self._unscale(self._actions))
        dones = terminated | truncated
        # A sub-env that goes on has neither succeeded nor been truncated; the ended ones are
        # filled in below (building every dict from the arrays costs more than the env step).
        infos: list[dict[str, Any]] = [
            {"success": False, "TimeLimit.truncated": False} for _ in range(self.num_envs)
        ]
        now = time.perf_counter()
        self._returns += rewards.astype(np.float64)
        self._lengths += 1
        ended = np.flatnonzero(dones).tolist()
        out = obs.astype(np.float32)
        for i in ended:
            infos[i]["success"] = bool(info["success"][i])
            infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            infos[i]["episode"] = {
                "r": float(self._returns[i]),
                "l": int(self._lengths[i]),
                "t": round(now - self._starts[i], 6),
            }
            infos[i]["is_success"] = bool(terminated[i])
            infos[i]["terminal_observation"] = out[i]
        if ended:
            fresh, reset, success = self.venv.reset_ended()
            out = np.where(reset[:, None], fresh.astype(np.float32), out)
            for i in ended:
                self.reset_infos[i] = {"success": bool(success[i])}
            self._start_episodes(ended)
        return out, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def _indices(self, indices: VecEnvIndices) -> Sequence[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return list(indices)

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The attribute of the single env behind every sub-env (they share it)."""
        value = getattr(self.venv.env, attr_name)
        return [value for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Sub-envs share one single env, so attributes cannot be set per sub-env."""
        raise AttributeError(
            f"BatchedVecEnv: cannot set {attr_name!r}; its sub-envs share one single env"
        )

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        """``render`` draws the given sub-envs; other methods are not per sub-env here."""
        if method_name == "render":
            return [self.venv.render_env(i) for i in self._indices(indices)]
        raise AttributeError(
            f"BatchedVecEnv: {method_name!r} is not available per sub-env (only 'render')"
        )

    def env_is_wrapped(
        self,
        wrapper_class: type[gymnasium.Wrapper[Any, Any, Any, Any]],
        indices: VecEnvIndices = None,
    ) -> list[bool]:
        """No sub-env is a wrapped gymnasium env."""
        return [False for _ in self._indices(indices)]

    def get_images(self) -> Sequence[NDArray[np.uint8] | None]:
        return [self.venv.render_env(i) for i in range(self.num_envs)]
