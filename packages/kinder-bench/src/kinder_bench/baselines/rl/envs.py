"""The training env stack of the RL baselines (imports no torch; safe in ``SubprocVecEnv`` workers).

:func:`make_rl_env` builds, in this order (KinDER spec, baselines §3.3 and learning-stack §4):

1. ``kinder_core.make(env_id, max_episode_steps=max_steps)``: the Box view with its ``TimeLimit``;
2. :class:`BaseMotion3DDenseReward` when ``reward="dense"`` (BaseMotion3D only);
3. :class:`Float32Observation`: float32 observations (SB3's checker wants them);
4. ``gymnasium.wrappers.RescaleAction`` to [-1, 1] (our boxes are asymmetric, e.g. Motion2D's
   vacuum is [0, 1]; SAC squashes into [-1, 1] and PPO clips to it);
5. :class:`EpisodeOutcome`: ``info["episode"] = {"r", "l", "t"}`` (what SB3 reads) and
   ``info["is_success"]`` (terminated = goal reached) on the last step of each episode.

Observation and reward normalisation (SB3's ``VecNormalize``) wrap the vector env in
:mod:`~kinder_bench.baselines.rl.train`.
"""

from __future__ import annotations

import math
import time
from typing import Any, SupportsFloat

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.wrappers import RescaleAction
from numpy.typing import NDArray

from kinder_bench.evaluation.envs import make_env, short_id

#: Reward settings: the env's own sparse reward, or the paper's BaseMotion3D shaping.
REWARDS = ("sparse", "dense")


class Float32Observation(gymnasium.ObservationWrapper[NDArray[np.float32], Any, Any]):
    """Casts Box observations to float32 (bounds included)."""

    def __init__(self, env: gymnasium.Env[Any, Any]) -> None:
        super().__init__(env)
        box = env.observation_space
        if not isinstance(box, spaces.Box):
            raise ValueError(f"RL baselines need a Box observation space, got {box}")
        self.observation_space = spaces.Box(
            box.low.astype(np.float32), box.high.astype(np.float32), dtype=np.float32
        )

    def observation(self, observation: Any) -> NDArray[np.float32]:
        return np.asarray(observation, dtype=np.float32)


class EpisodeOutcome(gymnasium.Wrapper[Any, Any, Any, Any]):
    """Adds ``info["episode"]`` (return ``r``, length ``l``, seconds ``t``) and
    ``info["is_success"]`` (the env terminated, i.e. reached its goal) when an episode ends.

    Returns are of the reward seen here (the dense one under ``reward="dense"``); success is
    always the env's own goal test.
    """

    def __init__(self, env: gymnasium.Env[Any, Any]) -> None:
        super().__init__(env)
        self._return = 0.0
        self._length = 0
        self._t0 = time.perf_counter()

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        self._return, self._length, self._t0 = 0.0, 0, time.perf_counter()
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._return += float(reward)
        self._length += 1
        if terminated or truncated:
            info = dict(info)
            info["episode"] = {
                "r": self._return,
                "l": self._length,
                "t": round(time.perf_counter() - self._t0, 6),
            }
            info["is_success"] = bool(terminated)
        return obs, reward, terminated, truncated, info


class BaseMotion3DDenseReward(gymnasium.Wrapper[Any, Any, Any, Any]):
    """The paper's dense reward for BaseMotion3D (appendix "Dense Reward for RL").

    The shaping measures progress towards the target in the XOY plane: with ``d`` the xy distance
    from the base centre to the target before a step and ``d'`` after it, the reward of the step
    becomes::

        env_reward + scale * (progress_weight * (d - d') - step_penalty)
                   + success_bonus * terminated

    with the upstream defaults ``scale=0.1``, ``progress_weight=100``, ``step_penalty=0.1`` and
    ``success_bonus=10`` (spec baselines §3.3; the spec leaves open whether the bonus is scaled:
    here it is not). The env's −1 per step is kept. Only the training reward changes: evaluation
    in the runner always scores the env's sparse reward.
    """

    def __init__(
        self,
        env: gymnasium.Env[Any, Any],
        scale: float = 0.1,
        progress_weight: float = 100.0,
        step_penalty: float = 0.1,
        success_bonus: float = 10.0,
    ) -> None:
        super().__init__(env)
        oc = env.unwrapped
        if not (hasattr(oc, "robot") and hasattr(oc, "target") and hasattr(oc, "get_state")):
            raise ValueError(
                f"The dense reward is defined for BaseMotion3D only, got {type(oc).__name__}"
            )
        self.scale = scale
        self.progress_weight = progress_weight
        self.step_penalty = step_penalty
        self.success_bonus = success_bonus
        self._distance = 0.0

    def xy_distance(self) -> float:
        """The live xy distance from the base centre to the target."""
        oc: Any = self.env.unwrapped
        state = oc.get_state()
        robot, target = state[oc.robot], state[oc.target]
        return math.hypot(float(robot[0] - target[0]), float(robot[1] - target[1]))

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        out = self.env.reset(**kwargs)
        self._distance = self.xy_distance()
        return out

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        distance = self.xy_distance()
        shaped = self.scale * (
            self.progress_weight * (self._distance - distance) - self.step_penalty
        )
        self._distance = distance
        total = float(reward) + shaped + (self.success_bonus if terminated else 0.0)
        return obs, total, terminated, truncated, info


def make_rl_env(
    env_id: str, max_steps: int, reward: str = "sparse", dense_scale: float = 0.1
) -> gymnasium.Env[Any, Any]:
    """One training env (see the module docstring for the wrapper order).

    Raises:
        ValueError: for an unknown ``reward``, or ``reward="dense"`` on an env other than
            BaseMotion3D.
    """
    if reward not in REWARDS:
        raise ValueError(f"reward must be one of {REWARDS}, got {reward!r}")
    env = make_env(env_id, max_steps=max_steps, render_mode=None)
    if reward == "dense":
        if not short_id(env_id).startswith("BaseMotion3D"):
            raise ValueError(
                f"--reward dense is the paper's BaseMotion3D shaping; {env_id} has no dense "
                "reward (use --reward sparse)"
            )
        env = BaseMotion3DDenseReward(env, scale=dense_scale)
    env = Float32Observation(env)
    box = env.action_space
    if not (
        isinstance(box, spaces.Box)
        and np.all(np.isfinite(box.low))
        and np.all(np.isfinite(box.high))
    ):
        raise ValueError(f"RL baselines need a bounded Box action space, got {box}")
    ones = np.ones(box.shape, dtype=box.dtype)
    env = RescaleAction(env, -ones, ones)
    return EpisodeOutcome(env)


def unscale_action(
    action: NDArray[Any], low: NDArray[Any], high: NDArray[Any]
) -> NDArray[np.float64]:
    """An action in [-1, 1] mapped linearly onto the box [low, high] (clipped first)."""
    a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
    lo, hi = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    out: NDArray[np.float64] = lo + (a + 1.0) * 0.5 * (hi - lo)
    return out
