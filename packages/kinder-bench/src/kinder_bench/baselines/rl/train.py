"""Training PPO and SAC on KinDER envs with Stable-Baselines3 (``kinder train ppo|sac``).

The paper's settings (appendix "Baselines" and spec baselines §3.3): actor and critic MLPs of four
hidden layers, 128 wide in 2D and 256 in 3D, tanh; 1M env steps; PPO with clip 0.2 and Adam at
3e-4; SAC with a 500k replay buffer, learning from 5,000 steps on, policy lr 3e-4 and Q lr 1e-3;
observation and reward normalisation with ±10 clipping (SB3's ``VecNormalize``, saved with every
checkpoint); actions rescaled to [-1, 1]; a sparse reward (−1 per step) unless ``reward="dense"``
(BaseMotion3D only). The upstream code was CleanRL-style PyTorch; the SB3 equivalents chosen here:

* PPO: ``n_envs`` × ``n_steps`` = 8 × 256 per rollout, 10 epochs of minibatches of 64 (CleanRL's
  32 minibatches), linearly annealed lr, clipped value loss (``clip_range_vf=0.2``), GAE λ 0.95,
  γ 0.99, grad-norm 0.5. SB3's PPO shares no layers between actor and critic here
  (``net_arch=dict(pi=..., vf=...)``), uses orthogonal init and a state-independent log-std, as
  CleanRL does. Because PPO collects whole rollouts, a run ends at the first multiple of
  ``n_envs × n_steps`` at or past ``total_steps`` (1M → 1,001,472).
* SAC: one gradient step per vector step (``train_freq=1``, ``gradient_steps=1``), batch 256,
  τ 0.005, automatic entropy tuning. **Deviations** SB3 cannot express: the actor is updated on
  every step (CleanRL: every 2nd step, twice), and the log-std is clamped to [-20, 2] (CleanRL:
  [-5, 2]). The separate Q learning rate is applied by :class:`KinderSAC`.
* Vector envs: 8 (16 for BaseMotion3D and Transport3D, and for Shelf3D with PPO), as the released
  configs. ``vec_env="dummy"`` steps them in this process, ``"subproc"`` in one process each.
* Training episodes end at the paper's evaluation budget (``kinder_bench.evaluation.protocol``),
  else the env's registered ``max_episode_steps``. **Deviation:** the upstream 2D configs trained
  with a 300-step limit and evaluated with 200.

Checkpoints are written every ``checkpoint_every`` env steps and at the end, in the trainers'
format (:mod:`kinder_bench.training.checkpoints`; method ``ppo`` or ``sac``, step = env steps).
A training output directory holds::

    config.json                  the algorithm, its full arguments, the env's spaces, versions
    progress.csv                 one row per logging interval (CsvLog)
    checkpoints/step_000051200/  one checkpoint per directory, named by its env step count:
        model.zip                  the SB3 model (policy, optimizers, hyperparameters)
        vecnormalize.pkl           the observation/reward normalisation statistics
        replay_buffer.pkl          SAC only: the replay buffer, so that training resumes exactly
        checkpoint.json            the arguments, versions and ``info``: env id, observation
                                   shape, action bounds, reward, seed, n_envs, hidden_size
    tb/                          TensorBoard events, when tensorboard is installed

Rerunning with the same output directory resumes from the newest checkpoint. A resumed run is
deterministic given its checkpoint (the envs and RNGs are
re-seeded with ``seed + steps``), but it is not bit-identical to an uninterrupted run: the vector
envs restart their episodes, and progress rows logged after the checkpoint are logged again.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
import json
import sys
import time
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal, cast

import numpy as np
import torch
from stable_baselines3 import PPO, SAC
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger, make_output_format
from stable_baselines3.common.utils import LinearSchedule, set_random_seed, update_learning_rate
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecNormalize

import kinder_core
from kinder_bench.agents import parse_value
from kinder_bench.baselines.rl.envs import REWARDS, make_rl_env
from kinder_bench.evaluation.envs import default_max_steps, make_env, resolve_env_id, short_id
from kinder_bench.evaluation.protocol import PAPER_MAX_STEPS
from kinder_bench.evaluation.results import environment_info, write_json
from kinder_bench.training.checkpoints import latest_checkpoint, read_checkpoint, save_checkpoint
from kinder_bench.training.csvlog import CsvLog

Algo = Literal["ppo", "sac"]
CONFIG_FILE = "config.json"
PROGRESS_FILE = "progress.csv"
#: The trainer's files in a checkpoint directory.
MODEL_FILE = "model.zip"
VECNORM_FILE = "vecnormalize.pkl"
REPLAY_FILE = "replay_buffer.pkl"
VEC_ENVS = ("dummy", "subproc", "batched")

#: Vector envs of the released configs that differ from 8 (by algorithm, then env family).
PAPER_N_ENVS: dict[str, dict[str, int]] = {
    "ppo": {"BaseMotion3D": 16, "Transport3D": 16, "Shelf3D": 16},
    "sac": {"BaseMotion3D": 16, "Transport3D": 16},
}


@dataclasses.dataclass(frozen=True)
class RLArgs:
    """Arguments shared by PPO and SAC."""

    env_id: str = "kinder/Motion2D-p0-v0"
    """The env to train on (``Motion2D-p0`` is accepted)."""
    seed: int = 0
    """Seeds the networks, the learner's RNGs and the envs (env ``i`` resets with ``seed + i``)."""
    total_steps: int = 1_000_000
    """Env steps to train for, summed over the vector envs (the paper: 1M)."""
    n_envs: int | None = None
    """Vector envs; None: the released configs' (8; 16 for BaseMotion3D, Transport3D, and
    Shelf3D with PPO)."""
    vec_env: str = "dummy"
    """``dummy`` (envs stepped in this process), ``subproc`` (one process per env) or
    ``batched`` (Kinematic2D ids only: all envs stepped in whole numpy arrays, bit-exact with
    ``dummy``; see :mod:`~kinder_bench.baselines.rl.batched`)."""
    reward: str = "sparse"
    """``sparse`` (the env's −1 per step) or ``dense`` (the paper's BaseMotion3D shaping)."""
    dense_scale: float = 0.1
    """Scale of the dense shaping term (``reward=dense`` only)."""
    max_episode_steps: int | None = None
    """Training episode limit; None: the paper's evaluation budget, else the env's own."""
    hidden_size: int | None = None
    """Width of every hidden layer; None: 128 for 2D envs, 256 for 3D envs (the paper)."""
    num_layers: int = 4
    """Hidden layers of the actor and of the critic (the paper: 4)."""
    gamma: float = 0.99
    """Discount factor (also used by the reward normalisation)."""
    norm_obs: bool = True
    """Normalise observations with running statistics (``VecNormalize``), clipped to ±10."""
    norm_reward: bool = True
    """Scale rewards by the running std of the discounted return, clipped to ±10."""
    checkpoint_every: int = 50_000
    """Write a checkpoint every this many env steps (and always at the end)."""
    keep_checkpoints: int = 1
    """How many of the newest checkpoints to keep (older ones are deleted)."""
    log_every: int = 10_000
    """Append a row to ``progress.csv`` every this many env steps (and at the end)."""
    torch_threads: int = 1
    """``torch.set_num_threads`` for training (1 is fastest for these small MLPs)."""
    device: str = "cpu"
    """Torch device of the learner (``cpu``, ``cuda``, ``cuda:1``, ``auto``); the envs always
    step on the CPU. A run may resume on another device."""
    keep_steps: tuple[int, ...] = ()
    """Also keep, for good, the checkpoint taken at the first update boundary at or past each of
    these env step counts (``--arg keep_steps=[1000000,10000000]``). With a constant learning
    rate (``anneal_lr=false``) the checkpoint kept at 1M steps of a 100M-step run is the policy a
    1M-step run with the same seed and arguments would end with, so one run serves every budget."""
    max_wall_s: float | None = None
    """Stop this call's training at the first update boundary after this many seconds, with a
    checkpoint there (rerunning resumes); None: train to ``total_steps``."""

    def __post_init__(self) -> None:
        checks = [
            (self.total_steps > 0, "total_steps must be > 0"),
            (self.n_envs is None or self.n_envs >= 1, "n_envs must be >= 1"),
            (self.vec_env in VEC_ENVS, f"vec_env must be one of {VEC_ENVS}"),
            (self.reward in REWARDS, f"reward must be one of {REWARDS}"),
            (self.hidden_size is None or self.hidden_size >= 1, "hidden_size must be >= 1"),
            (self.num_layers >= 1, "num_layers must be >= 1"),
            (self.checkpoint_every > 0, "checkpoint_every must be > 0"),
            (self.keep_checkpoints >= 1, "keep_checkpoints must be >= 1"),
            (self.log_every > 0, "log_every must be > 0"),
            (self.torch_threads >= 1, "torch_threads must be >= 1"),
            (all(int(k) > 0 for k in self.keep_steps), "keep_steps must all be > 0"),
            (self.max_wall_s is None or self.max_wall_s > 0, "max_wall_s must be > 0"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ValueError(f"{type(self).__name__}: {msg}, got {self}")
        # A JSON list from the command line (or a config file) becomes the declared sorted tuple.
        object.__setattr__(self, "keep_steps", tuple(sorted(int(k) for k in self.keep_steps)))


@dataclasses.dataclass(frozen=True)
class PPOArgs(RLArgs):
    """PPO (defaults: the paper's CleanRL configuration, in SB3 terms)."""

    learning_rate: float = 3e-4
    """Adam learning rate of actor and critic."""
    anneal_lr: bool = True
    """Anneal the learning rate linearly to 0 over ``total_steps``."""
    n_steps: int = 256
    """Steps per env per rollout (rollout size: ``n_envs × n_steps``)."""
    batch_size: int = 64
    """Minibatch size (2048 / 64 = CleanRL's 32 minibatches)."""
    n_epochs: int = 10
    """Passes over each rollout."""
    gae_lambda: float = 0.95
    """GAE λ."""
    clip_range: float = 0.2
    """PPO clip ratio (the paper: 0.2)."""
    clip_range_vf: float | None = 0.2
    """Value-function clipping (CleanRL's clipped value loss); None: off."""
    ent_coef: float = 0.0
    """Entropy bonus."""
    vf_coef: float = 0.5
    """Value-loss weight."""
    max_grad_norm: float = 0.5
    """Gradient-norm clip."""


@dataclasses.dataclass(frozen=True)
class SACArgs(RLArgs):
    """SAC (defaults: the paper's settings, in SB3 terms)."""

    policy_lr: float = 3e-4
    """Adam learning rate of the actor (and of the entropy coefficient)."""
    q_lr: float = 1e-3
    """Adam learning rate of the twin Q networks."""
    buffer_size: int = 500_000
    """Replay buffer capacity in transitions (the paper: 500k)."""
    learning_starts: int = 5_000
    """Env steps of uniformly random actions before learning starts."""
    batch_size: int = 256
    """Minibatch size."""
    tau: float = 0.005
    """Target-network Polyak coefficient."""
    gradient_steps: int = 1
    """Gradient steps after each vector step (one step of every env)."""


ARGS: dict[str, type[RLArgs]] = {"ppo": PPOArgs, "sac": SACArgs}


class KinderPPO(PPO):
    """SB3's PPO that reads episode statistics from the infos of the sub-envs that ended only.

    SB3 scans every sub-env's info after every step for an ``episode`` entry, which only an
    ended sub-env carries; with thousands of batched sub-envs that scan costs about as much as
    stepping them. The statistics kept are the same.
    """

    def _update_info_buffer(
        self, infos: list[dict[str, Any]], dones: np.ndarray | None = None
    ) -> None:
        if dones is None:
            super()._update_info_buffer(infos, dones)
            return
        ended = np.flatnonzero(dones)
        super()._update_info_buffer([infos[i] for i in ended], np.ones(len(ended), dtype=bool))


class KinderSAC(SAC):
    """SB3's SAC with a separate learning rate for the Q networks (``q_learning_rate``).

    SB3 sets one learning rate on every optimizer at each update; this sets the critic's to
    ``q_learning_rate`` after it. ``q_learning_rate`` is saved and loaded with the model.
    """

    q_learning_rate: float | None = None

    def _update_learning_rate(
        self, optimizers: list[torch.optim.Optimizer] | torch.optim.Optimizer
    ) -> None:
        super()._update_learning_rate(optimizers)
        if self.q_learning_rate is not None:
            update_learning_rate(self.critic.optimizer, self.q_learning_rate)
            self.logger.record("train/q_learning_rate", self.q_learning_rate)


ALGORITHMS: dict[str, type[BaseAlgorithm]] = {"ppo": KinderPPO, "sac": KinderSAC}

#: progress.csv columns: common ones, then each algorithm's SB3 training statistics.
COMMON_COLUMNS = (
    "steps",
    "wall_s",
    "steps_per_s",
    "episodes",
    "ep_return_mean",
    "ep_len_mean",
    "success_rate",
)
ALGO_COLUMNS: dict[str, tuple[str, ...]] = {
    "ppo": (
        "train/loss",
        "train/policy_gradient_loss",
        "train/value_loss",
        "train/entropy_loss",
        "train/approx_kl",
        "train/clip_fraction",
        "train/explained_variance",
        "train/learning_rate",
    ),
    "sac": ("train/actor_loss", "train/critic_loss", "train/ent_coef", "train/ent_coef_loss"),
}


@dataclasses.dataclass(frozen=True)
class Resolved:
    """The defaults of a run filled in for its env."""

    env_id: str
    n_envs: int
    hidden_size: int
    max_episode_steps: int


def resolve(algo: str, args: RLArgs) -> Resolved:
    """Fill in the env-dependent defaults (errors early for an unknown env id)."""
    env_id = resolve_env_id(args.env_id)
    family = short_id(env_id).split("-")[0]
    source = kinder_core.registration.FAMILY_SOURCES.get(family)
    is_2d = source is not None and source.category.endswith("2D")
    max_steps = args.max_episode_steps
    if max_steps is None:
        max_steps = PAPER_MAX_STEPS.get(env_id) or default_max_steps(env_id)
    return Resolved(
        env_id=env_id,
        n_envs=args.n_envs or PAPER_N_ENVS.get(algo, {}).get(family, 8),
        hidden_size=args.hidden_size or (128 if is_2d else 256),
        max_episode_steps=max_steps,
    )


def env_signature(env_id: str) -> dict[str, Any]:
    """What a policy depends on: the env id, observation shape and action bounds."""
    env = make_env(env_id, render_mode=None)
    try:
        obs_space, act_space = env.observation_space, env.action_space
        return {
            "env_id": env_id,
            "obs_shape": list(obs_space.shape or ()),
            "action_low": np.asarray(getattr(act_space, "low", [])).astype(float).tolist(),
            "action_high": np.asarray(getattr(act_space, "high", [])).astype(float).tolist(),
        }
    finally:
        env.close()


def _config(algo: str, args: RLArgs, res: Resolved) -> dict[str, Any]:
    return {
        "algo": algo,
        "args": dataclasses.asdict(dataclasses.replace(args, env_id=res.env_id)),
        "resolved": dataclasses.asdict(res),
        "env": env_signature(res.env_id),
    }


# Arguments a rerun may change without making it another run.
_MAY_CHANGE = {
    "total_steps",
    "checkpoint_every",
    "keep_checkpoints",
    "log_every",
    "torch_threads",
    "device",
    "keep_steps",
    "max_wall_s",
}


def _check_or_write_config(out: Path, config: dict[str, Any]) -> None:
    path = out / CONFIG_FILE
    if path.exists():
        old = json.loads(path.read_text())
        mine = {k: v for k, v in config["args"].items() if k not in _MAY_CHANGE}
        theirs = {k: v for k, v in old.get("args", {}).items() if k not in _MAY_CHANGE}
        if old.get("algo") != config["algo"] or mine != theirs:
            diff = sorted(k for k in set(mine) | set(theirs) if mine.get(k) != theirs.get(k))
            raise ValueError(
                f"{out} holds a {old.get('algo')} run with other arguments (differing: "
                f"{diff or ['algo']}); resume it with the same arguments or use another --out"
            )
    write_json(path, {**config, **environment_info()})


def make_venv(algo: str, args: RLArgs, res: Resolved) -> VecEnv:
    """The training vector env (``res.n_envs`` copies of :func:`make_rl_env`), unnormalised."""
    fn: Callable[[], Any] = functools.partial(
        make_rl_env, res.env_id, res.max_episode_steps, args.reward, args.dense_scale
    )
    if args.vec_env == "batched":
        if args.reward != "sparse":
            raise ValueError("--vec-env batched trains on the env's own (sparse) reward only")
        from kinder_bench.baselines.rl.batched import BatchedVecEnv

        return BatchedVecEnv(res.env_id, res.n_envs, res.max_episode_steps)
    fns = [fn] * res.n_envs
    venv: VecEnv = SubprocVecEnv(fns) if args.vec_env == "subproc" else DummyVecEnv(fns)
    return venv


def _build(algo: str, args: RLArgs, res: Resolved, env: VecNormalize) -> BaseAlgorithm:
    layers = [res.hidden_size] * args.num_layers
    if isinstance(args, PPOArgs):
        lr: Any = (
            LinearSchedule(args.learning_rate, 0.0, 1.0) if args.anneal_lr else args.learning_rate
        )
        return KinderPPO(
            "MlpPolicy",
            env,
            learning_rate=lr,
            n_steps=args.n_steps,
            batch_size=args.batch_size,
            n_epochs=args.n_epochs,
            gamma=args.gamma,
            gae_lambda=args.gae_lambda,
            clip_range=args.clip_range,
            clip_range_vf=args.clip_range_vf,
            ent_coef=args.ent_coef,
            vf_coef=args.vf_coef,
            max_grad_norm=args.max_grad_norm,
            policy_kwargs={
                "net_arch": {"pi": layers, "vf": layers},
                "activation_fn": torch.nn.Tanh,
            },
            seed=args.seed,
            device=args.device,
            verbose=0,
        )
    assert isinstance(args, SACArgs)
    model = KinderSAC(
        "MlpPolicy",
        env,
        learning_rate=args.policy_lr,
        buffer_size=args.buffer_size,
        learning_starts=args.learning_starts,
        batch_size=args.batch_size,
        tau=args.tau,
        gamma=args.gamma,
        train_freq=1,
        gradient_steps=args.gradient_steps,
        ent_coef="auto",
        policy_kwargs={"net_arch": {"pi": layers, "qf": layers}, "activation_fn": torch.nn.Tanh},
        seed=args.seed,
        device=args.device,
        verbose=0,
    )
    model.q_learning_rate = args.q_lr
    return model


def _save_checkpoint(
    model: BaseAlgorithm,
    venv: VecNormalize,
    out: Path,
    algo: str,
    args: RLArgs,
    info: dict[str, Any],
    keep: int,
    kept: bool = False,
) -> Path:
    """Write a checkpoint of ``model`` at its step count, then delete all but the newest ``keep``
    checkpoints, except those written with ``kept=True`` (``RLArgs.keep_steps``)."""

    def write(d: Path) -> None:
        model.save(d / MODEL_FILE)
        venv.save(str(d / VECNORM_FILE))
        if isinstance(model, SAC):
            model.save_replay_buffer(d / REPLAY_FILE)

    steps = int(model.num_timesteps)
    return save_checkpoint(out, steps, algo, args, write, info=info, keep=keep, kept=kept)


class _Monitor(BaseCallback):
    """Progress bar, ``progress.csv`` rows and periodic checkpoints."""

    def __init__(
        self,
        algo: str,
        args: RLArgs,
        out: Path,
        venv: VecNormalize,
        info: dict[str, Any],
        log: CsvLog,
        wall_offset: float,
        progress: bool,
    ) -> None:
        super().__init__()
        self.algo, self.args, self.out, self.venv, self.info = algo, args, out, venv, info
        self.csv = log
        self.wall_offset = wall_offset
        self.progress = progress
        self.returns: list[float] = []
        self.lengths: list[int] = []
        self.successes: list[bool] = []
        self.episodes = 0
        self.stopped_at: Path | None = None
        """The checkpoint where ``max_wall_s`` stopped training (None: not stopped)."""

    def _on_training_start(self) -> None:
        from tqdm import tqdm

        steps = int(self.num_timesteps)
        self.t0 = time.perf_counter()
        self.last_t, self.last_steps = self.t0, steps
        every_log, every_ckpt = self.args.log_every, self.args.checkpoint_every
        self.next_log = (steps // every_log + 1) * every_log
        self.next_ckpt = (steps // every_ckpt + 1) * every_ckpt
        self.start_steps = steps
        self.pending_keep = [k for k in self.args.keep_steps if k > steps]
        self.deadline = None if self.args.max_wall_s is None else self.t0 + self.args.max_wall_s
        self.bar = tqdm(
            total=self.args.total_steps,
            initial=steps,
            desc=f"{self.algo} {short_id(self.info['env_id'])} s{self.args.seed}",
            unit="step",
            disable=not self.progress,
            file=sys.stderr,
            dynamic_ncols=True,
        )

    def _on_step(self) -> bool:
        infos = self.locals.get("infos", [])
        dones = self.locals.get("dones")
        # Only an ended sub-env's info carries ``episode``.
        rows = range(len(infos)) if dones is None else np.flatnonzero(dones).tolist()
        for info in (infos[i] for i in rows):
            ep = info.get("episode")
            if ep is not None:
                self.returns.append(float(ep["r"]))
                self.lengths.append(int(ep["l"]))
                self.successes.append(bool(info.get("is_success", False)))
                self.episodes += 1
        self.bar.update(len(infos))
        return self.stopped_at is None

    def _on_rollout_start(self) -> None:
        # Rollout starts follow an update, so the model and the statistics are consistent here.
        steps = int(self.num_timesteps)
        if steps >= self.next_log:
            self.write_row()
            self.next_log = (steps // self.args.log_every + 1) * self.args.log_every
        if self.pending_keep and steps >= self.pending_keep[0]:
            self.checkpoint(kept=True)
            self.pending_keep = [k for k in self.pending_keep if k > steps]
        if steps >= self.next_ckpt:
            self.checkpoint()
            self.next_ckpt = (steps // self.args.checkpoint_every + 1) * self.args.checkpoint_every
        past = self.deadline is not None and time.perf_counter() >= self.deadline
        if past and steps > self.start_steps:
            # Stop before this rollout's first step is used: the checkpoint is the update boundary
            # (after at least one update, so every call makes progress).
            if steps > self.last_steps:
                self.write_row()
            self.stopped_at = self.checkpoint()

    def checkpoint(self, kept: bool = False) -> Path:
        return _save_checkpoint(
            self.model, self.venv, self.out, self.algo, self.args, self.info,
            self.args.keep_checkpoints, kept,
        )  # fmt: skip

    def write_row(self) -> None:
        steps = int(self.num_timesteps)
        now = time.perf_counter()
        rate = (steps - self.last_steps) / max(now - self.last_t, 1e-9)
        row: dict[str, object] = {
            "steps": steps,
            "wall_s": round(self.wall_offset + now - self.t0, 3),
            "steps_per_s": round(rate, 1),
            "episodes": self.episodes,
        }
        if self.returns:
            row["ep_return_mean"] = round(float(np.mean(self.returns)), 4)
            row["ep_len_mean"] = round(float(np.mean(self.lengths)), 2)
            row["success_rate"] = round(float(np.mean(self.successes)), 4)
        values = self.model.logger.name_to_value
        for key in ALGO_COLUMNS[self.algo]:
            if key in values:
                row[key] = float(values[key])
        self.csv.write(row)
        for key in COMMON_COLUMNS[2:]:
            if key in row:
                self.model.logger.record(f"rollout/{key}", row[key])
        self.model.logger.dump(steps)  # to TensorBoard when installed; clears the values
        self.bar.set_postfix(
            success=row.get("success_rate", "-"), steps_s=f"{rate:.0f}", refresh=False
        )
        self.returns, self.lengths, self.successes = [], [], []
        self.last_t, self.last_steps = now, steps

    def _on_training_end(self) -> None:
        self.bar.close()


@dataclasses.dataclass(frozen=True)
class TrainResult:
    """What :func:`train` did."""

    out: Path
    checkpoint: Path
    """The final checkpoint."""
    steps: int
    """Env steps of the final checkpoint."""
    resumed_from: int | None
    """Env steps of the checkpoint training resumed from (None: started fresh)."""
    ran_steps: int
    """Env steps trained by this call (0 when the run was already finished)."""
    wall_s: float
    """Seconds this call spent training."""


def _logger(out: Path) -> Logger:
    """SB3's logger: TensorBoard events under ``out/tb`` when tensorboard is installed, else
    nothing (progress.csv is written by the callback either way)."""
    if importlib.util.find_spec("tensorboard") is None:
        return Logger(folder=None, output_formats=[])
    tb = str(out / "tb")
    return Logger(folder=tb, output_formats=[make_output_format("tensorboard", tb)])


def _wall_offset(log: CsvLog, resumed_steps: int) -> float:
    rows = [r for r in log.rows() if r.get("steps") and int(r["steps"]) <= resumed_steps]
    return float(rows[-1]["wall_s"]) if rows else 0.0


def train(algo: Algo | str, args: RLArgs, out: Path | str, progress: bool = True) -> TrainResult:
    """Train (or resume training) one policy into ``out`` (see the module docstring).

    Args:
        algo: ``"ppo"`` or ``"sac"``.
        args: :class:`PPOArgs` or :class:`SACArgs`.
        out: The output directory; if it holds a checkpoint of the same run, training resumes
            from the newest one, and returns at once when that one already has ``total_steps``.
        progress: Show a progress bar.

    Raises:
        ValueError: for arguments of the wrong algorithm, an unknown env, or an output directory
            that holds another run.
    """
    if algo not in ARGS or not isinstance(args, ARGS[algo]):
        raise ValueError(
            f"algo {algo!r} needs {ARGS[algo].__name__ if algo in ARGS else 'ppo or sac'} "
            f"arguments, got {type(args).__name__}"
        )
    out = Path(out)
    res = resolve(algo, args)
    config = _config(algo, args, res)
    out.mkdir(parents=True, exist_ok=True)
    _check_or_write_config(out, config)
    # The checkpoints record the arguments with the env id resolved, as config.json does.
    args = dataclasses.replace(args, env_id=res.env_id)
    info = {
        **config["env"],
        "reward": args.reward,
        "seed": args.seed,
        "n_envs": res.n_envs,
        "hidden_size": res.hidden_size,
    }
    torch.set_num_threads(args.torch_threads)
    log = CsvLog(out / PROGRESS_FILE, COMMON_COLUMNS + ALGO_COLUMNS[algo])
    ckpt = latest_checkpoint(out)
    resumed = None if ckpt is None else read_checkpoint(ckpt, (algo,)).step
    if ckpt is not None and resumed is not None and resumed >= args.total_steps:
        return TrainResult(out, ckpt, resumed, resumed, 0, 0.0)

    venv = make_venv(algo, args, res)
    try:
        if ckpt is None or resumed is None:
            venv.seed(args.seed)
            env = VecNormalize(
                venv,
                norm_obs=args.norm_obs,
                norm_reward=args.norm_reward,
                clip_obs=10.0,
                clip_reward=10.0,
                gamma=args.gamma,
            )
            model = _build(algo, args, res, env)
        else:
            venv.seed(args.seed + resumed)
            env = VecNormalize.load(str(ckpt / VECNORM_FILE), venv)
            env.training = True
            model = ALGORITHMS[algo].load(ckpt / MODEL_FILE, env=env, device=args.device)
            set_random_seed(args.seed + resumed)
            model.action_space.seed(args.seed + resumed)
            if isinstance(model, SAC):
                model.load_replay_buffer(ckpt / REPLAY_FILE)
        model.set_logger(_logger(out))
        start = int(model.num_timesteps)
        monitor = _Monitor(
            algo, args, out, env, info, log, _wall_offset(log, start), progress=progress
        )
        t0 = time.perf_counter()
        model.learn(
            total_timesteps=args.total_steps - start,
            callback=monitor,
            reset_num_timesteps=False,
            log_interval=cast(int, None),  # SB3 accepts None: our callback does the logging
        )
        wall = time.perf_counter() - t0
        if monitor.stopped_at is not None:
            steps = read_checkpoint(monitor.stopped_at).step
            return TrainResult(out, monitor.stopped_at, steps, resumed, steps - start, wall)
        if int(model.num_timesteps) > monitor.last_steps:
            monitor.write_row()
        final = monitor.checkpoint()
        return TrainResult(
            out, final, int(model.num_timesteps), resumed, model.num_timesteps - start, wall
        )
    finally:
        venv.close()


def make_train_args(algo: str, values: dict[str, Any]) -> RLArgs:
    """``PPOArgs``/``SACArgs`` from a mapping; string values are parsed by the field's type.

    Raises:
        ValueError: naming an unknown algorithm or field, or a value that does not parse.
    """
    if algo not in ARGS:
        raise ValueError(f"Unknown algorithm {algo!r}; expected one of {sorted(ARGS)}")
    cls = ARGS[algo]
    hints = typing.get_type_hints(cls)
    fields = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(values) - fields)
    if unknown:
        raise ValueError(f"Unknown {algo} argument(s) {unknown}; known: {sorted(fields)}")
    parsed = {k: parse_value(v, hints[k], f"{algo} argument {k!r}") for k, v in values.items()}
    return cls(**parsed)
