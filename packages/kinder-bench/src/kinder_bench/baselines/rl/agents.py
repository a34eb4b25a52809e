"""The ``ppo`` and ``sac`` agents: a trained policy evaluated by the runner.

``kinder bench run --env Motion2D-p0 --agent ppo --arg checkpoint=runs/ppo/seed{seed}`` loads the
newest checkpoint of a ``kinder train ppo`` output directory (or the checkpoint directory given)
and acts with the deterministic policy: the mean action for PPO, ``tanh`` of the mean for SAC.
Each step normalises the observation with the statistics saved with the checkpoint (clipped to
±10), asks the policy for an action in [-1, 1] and maps it linearly onto the env's action box.
The runner measures this as the agent's inference time. ``{seed}`` in the path is the runner's
run seed, so the policy trained with seed ``s`` is evaluated on the episodes of seed ``s``.

A loaded policy is cached per process (by path and file time), so the per-episode agents of a run
share one copy. Loading sets ``torch.set_num_threads(torch_threads)`` for the process.

Errors (raised when the agent is made): no checkpoint or an incomplete one; a checkpoint of the
other algorithm; a checkpoint trained on another env id, another observation size or other action
bounds than the evaluation env's.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, ClassVar

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_bench.agents.base import Agent, needs_checkpoint
from kinder_bench.baselines.rl.envs import unscale_action
from kinder_bench.training.checkpoints import Checkpoint, find_checkpoint, load_checkpoint


@dataclasses.dataclass(frozen=True)
class RLAgentArgs:
    """Arguments of the ``ppo`` and ``sac`` agents."""

    checkpoint: str = ""
    """A ``kinder train`` output directory (its newest checkpoint) or one ``checkpoints/step_*``
    directory; ``{seed}`` is replaced by the run seed. Required."""
    torch_threads: int = 1
    """``torch.set_num_threads`` of the evaluating process (1: fastest for one observation)."""

    def __post_init__(self) -> None:
        if not self.checkpoint:
            raise ValueError(
                "the ppo/sac agents need --arg checkpoint=DIR (a `kinder train` output directory)"
            )
        if "{seed}" not in self.checkpoint:
            find_checkpoint(self.checkpoint)  # a missing checkpoint fails before any episode
        if self.torch_threads < 1:
            raise ValueError(f"torch_threads must be >= 1, got {self.torch_threads}")


@dataclasses.dataclass(frozen=True)
class LoadedPolicy:
    """A checkpoint loaded for inference."""

    checkpoint: Checkpoint
    model: Any
    """The SB3 model (PPO or SAC)."""
    vecnorm: Any
    """The saved ``VecNormalize`` (statistics only; its venv is not set)."""

    @property
    def path(self) -> Path:
        return self.checkpoint.path


_CACHE: dict[tuple[str, str, float], LoadedPolicy] = {}


def load_policy(checkpoint: Path | str, algo: str, torch_threads: int = 1) -> LoadedPolicy:
    """Load (or reuse) a checkpoint's policy; ``algo`` must match the checkpoint's.

    Raises:
        FileNotFoundError: no checkpoint at ``checkpoint``, or a file of it is missing.
        CheckpointError: the checkpoint holds another method, or is not of this format.
    """
    from kinder_bench.baselines.rl.train import ALGORITHMS, MODEL_FILE, VECNORM_FILE

    ckpt = load_checkpoint(checkpoint, (algo,))
    path = ckpt.path
    model_file = path / MODEL_FILE
    for f in (model_file, path / VECNORM_FILE):
        if not f.is_file():
            raise FileNotFoundError(f"Checkpoint {path} is incomplete: {f.name} is missing")
    key = (str(path.resolve()), algo, model_file.stat().st_mtime)
    if key in _CACHE:
        return _CACHE[key]
    import pickle

    import torch

    torch.set_num_threads(torch_threads)
    model = ALGORITHMS[algo].load(model_file, device="cpu")
    with (path / VECNORM_FILE).open("rb") as fh:
        vecnorm = pickle.load(fh)
    loaded = LoadedPolicy(ckpt, model, vecnorm)
    _CACHE[key] = loaded
    return loaded


def check_compatible(meta: dict[str, Any], env: gymnasium.Env[Any, Any], where: Path) -> None:
    """Raise a ValueError when a checkpoint's env (its ``info``) differs from the evaluation
    env."""
    spec_id = env.spec.id if env.spec is not None else None
    if spec_id is not None and spec_id != meta["env_id"]:
        raise ValueError(
            f"Checkpoint {where} was trained on {meta['env_id']}, but the evaluation env is "
            f"{spec_id}; train on {spec_id} or evaluate on {meta['env_id']}"
        )
    shape = list(env.observation_space.shape or ())
    if shape != list(meta["obs_shape"]):
        raise ValueError(
            f"Checkpoint {where} expects observations of shape {tuple(meta['obs_shape'])}, the "
            f"evaluation env gives {tuple(shape)}"
        )
    low = np.asarray(getattr(env.action_space, "low", []), dtype=float)
    high = np.asarray(getattr(env.action_space, "high", []), dtype=float)
    if not (
        low.shape == np.shape(meta["action_low"])
        and np.allclose(low, meta["action_low"])
        and np.allclose(high, meta["action_high"])
    ):
        raise ValueError(
            f"Checkpoint {where} was trained with action bounds {meta['action_low']} .. "
            f"{meta['action_high']}, the evaluation env has {low.tolist()} .. {high.tolist()}"
        )


class _SB3Agent(Agent[RLAgentArgs]):
    """Acts with a trained SB3 policy (see the module docstring)."""

    Args = RLAgentArgs

    @classmethod
    def unavailable(cls, args: Any, env_id: str) -> str | None:
        """Needs a trained checkpoint."""
        del env_id
        return needs_checkpoint(args, cls.name)

    algo: ClassVar[str]

    def __init__(self, env: gymnasium.Env[Any, Any], args: RLAgentArgs, seed: int) -> None:
        super().__init__(env, args, seed)
        policy = load_policy(args.checkpoint, self.algo, args.torch_threads)
        check_compatible(policy.checkpoint.info, env, policy.path)
        self.policy = policy
        self._low = self.action_space.low.astype(np.float64)
        self._high = self.action_space.high.astype(np.float64)

    def act(self, obs: Any) -> NDArray[np.float64]:
        x = np.asarray(obs, dtype=np.float32).reshape(1, -1)
        x = self.policy.vecnorm.normalize_obs(x)
        action, _ = self.policy.model.predict(x, deterministic=True)
        return unscale_action(np.asarray(action).reshape(-1), self._low, self._high)


class PPOAgent(_SB3Agent):
    """A policy trained by ``kinder train ppo``, acting with its mean action."""

    name = "ppo"
    algo = "ppo"


class SACAgent(_SB3Agent):
    """A policy trained by ``kinder train sac``, acting with ``tanh`` of its mean action."""

    name = "sac"
    algo = "sac"
