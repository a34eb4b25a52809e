"""Diffusion policy baselines DP and DPES, on lerobot 0.4.4's ``DiffusionPolicy``.

**DP** conditions on the camera images and the robot state (``observation.state``); **DPES** adds
the environment state (``observation.environment_state``). Both are trained on one KinDER
demonstration dataset (LeRobotDataset v3, see :mod:`kinder_bench.baselines.demo_data`) by
:func:`train_diffusion` (``kinder train dp|dpes``) and evaluated by the agents ``dp`` and
``dpes`` (``--arg checkpoint=DIR``).

The ``paper`` preset is the paper's configuration (appendix, "Diffusion Policy"): 2 observation
steps, horizon 16, 8 executed actions, a 1-D conditional UNet with channels 256/512/1024, kernel 5,
GroupNorm with 8 groups, a 128-d timestep embedding, DDIM with 100 training and 16 inference
steps, the squared-cosine schedule, epsilon prediction, ResNet-18 image encoders with GroupNorm
(one per camera, no pretrained weights, no crop), AdamW (lr 1e-4, betas 0.95/0.999, weight decay
1e-6) with a cosine schedule after 500 warm-up steps, batch 64, and an EMA of the weights (the
diffusion_policy schedule: decay ``1 - (1 + step)^-0.75`` capped at 0.9999), which the agents use.
Observations and actions are normalised to [-1, 1] by their min/max over the dataset.

Deviations and choices, written down:

* **The DPES normalisation trap.** lerobot's default ``normalization_mapping`` has no ``ENV``
  entry, so the environment state would reach the network unnormalised. Both presets map ``ENV``
  to MIN_MAX (:func:`diffusion_config`; tested).
* lerobot's ``DiffusionPolicy`` has no EMA; this trainer keeps one (see above).
* lerobot's default optimiser preset is Adam; the paper's is AdamW, used here.
* The paper trained "up to 5001 epochs" (about 1.2M steps at 100 demos of ~150 frames and batch
  64); here the budget is a number of optimiser steps, ``--steps``, 100k by default.
* As in lerobot, the last ``horizon - n_action_steps - n_obs_steps + 1 = 7`` frames of each
  episode are not used as sample starts, and actions past an episode's end are padded by
  repeating the last one.
* The ``cpu`` preset (smoke runs and tests, not for results) shrinks the UNet to 16/32/64 with a
  32-d timestep embedding, resizes images to 64×64 and uses batch 16. Everything else is the
  paper's. ``--lr`` and ``--warmup-steps`` default to the paper's 1e-4 and 500.
* At evaluation the camera images are rendered from the live state with the function that
  rendered the training images (``kinder_gym.demos.layout.camera_frames``); this rendering
  happens inside ``act`` and so counts as inference time.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_bench.agents.base import Agent, needs_checkpoint
from kinder_bench.baselines.demo_data import (
    ACTION_KEY,
    ENV_STATE_KEY,
    STATE_KEY,
    DatasetSpec,
    ObservationMap,
    read_dataset_spec,
    resolve_dataset_env,
)
from kinder_bench.baselines.diffusion_presets import (
    COMMON_FIELDS,
    METHODS,
    PAPER_EPOCHS,
    PRESET_BATCH,
    PRESET_FIELDS,
    PRESETS,
)
from kinder_bench.evaluation.results import package_versions, write_json
from kinder_bench.training.checkpoints import (
    METADATA_FILE,
    Checkpoint,
    check_resume_config,
    latest_checkpoint,
    load_checkpoint,
    read_checkpoint,
    save_checkpoint,
)
from kinder_bench.training.csvlog import CsvLog
from kinder_bench.training.ema import EMA

if TYPE_CHECKING:
    import torch
    from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy

os.environ.setdefault("HF_HUB_OFFLINE", "1")  # never reach the hub (datasets are local)


@dataclasses.dataclass(frozen=True)
class DiffusionTrainArgs:
    """Arguments of ``kinder train dp|dpes``."""

    dataset: Path
    """The demonstration dataset (a LeRobotDataset v3 directory)."""
    out: Path
    """The run directory (config.json, progress.csv, checkpoints/)."""
    method: str = "dp"
    """``dp`` (images + robot state) or ``dpes`` (adds the environment state)."""
    steps: int = 100_000
    """Optimiser steps in total (a resumed run continues up to this many)."""
    preset: str = "paper"
    """``paper`` (the paper's model) or ``cpu`` (a small model for smoke runs)."""
    batch_size: int | None = None
    """Samples per step; None: the preset's (paper 64, cpu 16)."""
    lr: float = 1e-4
    """Peak AdamW learning rate."""
    warmup_steps: int = 500
    """Linear warm-up steps before the cosine decay."""
    env: str | None = None
    """The env id (default: the one the dataset names)."""
    save_every: int = 1000
    """Write a checkpoint every this many steps (and at the end)."""
    log_every: int = 100
    """Append a row to progress.csv every this many steps."""
    seed: int = 0
    """Seeds the weights, the sample order and the diffusion noise."""
    device: str = "auto"
    """``cpu``, ``cuda`` or ``auto`` (cuda when available)."""
    num_workers: int = 0
    """Data-loading worker processes (video decoding); 0 decodes in the training process."""
    ema: bool = True
    """Keep an EMA of the weights (what the agents use)."""
    keep: int = 2
    """Checkpoints to keep."""

    def __post_init__(self) -> None:
        checks = [
            (self.method in METHODS, f"method must be one of {METHODS}"),
            (self.preset in PRESETS, f"preset must be one of {PRESETS}"),
            (self.steps >= 1, "steps must be >= 1"),
            (self.batch_size is None or self.batch_size >= 1, "batch_size must be >= 1"),
            (self.lr > 0 and self.warmup_steps >= 0, "lr must be > 0 and warmup_steps >= 0"),
            (self.save_every >= 1 and self.log_every >= 1, "save_every/log_every must be >= 1"),
            (self.device in ("auto", "cpu", "cuda"), "device must be auto, cpu or cuda"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ValueError(f"DiffusionTrainArgs: {msg}, got {self}")

    @property
    def batch(self) -> int:
        return self.batch_size or PRESET_BATCH[self.preset]


def resolve_device(device: str) -> str:
    import torch

    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device == "cuda" and not torch.cuda.is_available():
        raise ValueError("device 'cuda' requested but torch sees no CUDA device")
    return device


def diffusion_config(
    dataset: Path,
    method: str,
    preset: str = "paper",
    device: str = "cpu",
    **overrides: Any,
) -> Any:
    """lerobot's ``DiffusionConfig`` for a dataset: its features (DP: images + state; DPES: also
    the environment state), the preset's fields and the ENV normalisation entry."""
    from lerobot.configs.types import FeatureType, NormalizationMode
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata
    from lerobot.datasets.utils import dataset_to_policy_features
    from lerobot.policies.diffusion.configuration_diffusion import DiffusionConfig

    spec = read_dataset_spec(dataset)
    meta = LeRobotDatasetMetadata(f"kinder/{spec.root.name}", root=spec.root)
    features = dataset_to_policy_features(meta.features)
    if method == "dp" and not spec.cameras:
        raise ValueError(f"{dataset}: DP needs camera images; the dataset has none")
    if method == "dpes" and not spec.env_state_names:
        raise ValueError(f"{dataset}: DPES needs {ENV_STATE_KEY}; the dataset has none")
    inputs = {STATE_KEY: features[STATE_KEY]}
    inputs.update({k: features[k] for k in spec.image_keys})
    if method == "dpes":
        inputs[ENV_STATE_KEY] = features[ENV_STATE_KEY]
    if features[STATE_KEY].type is not FeatureType.STATE:
        raise ValueError(f"{dataset}: {STATE_KEY} is not a state feature")
    return DiffusionConfig(
        input_features=inputs,
        output_features={ACTION_KEY: features[ACTION_KEY]},
        normalization_mapping={
            "VISUAL": NormalizationMode.MEAN_STD,
            "STATE": NormalizationMode.MIN_MAX,
            "ENV": NormalizationMode.MIN_MAX,  # the DPES trap: absent, env state is not normalised
            "ACTION": NormalizationMode.MIN_MAX,
        },
        device=device,
        **{**COMMON_FIELDS, **PRESET_FIELDS[preset], **overrides},
    )


def lr_lambda(warmup: int, total: int) -> Any:
    """Linear warm-up over ``warmup`` steps, then a half cosine down to 0 at ``total``."""

    def f(step: int) -> float:
        if step < warmup and warmup > 0:
            return (step + 1) / warmup
        progress = (step - warmup) / max(1, total - warmup)
        return 0.5 * (1.0 + math.cos(math.pi * min(progress, 1.0)))

    return f


def sample_starts(episode_index: NDArray[np.int64], drop_last: int) -> NDArray[np.int64]:
    """Row indices usable as sample starts: all but the last ``drop_last`` frames of each episode
    (episodes shorter than that keep their first frame)."""
    starts: list[int] = []
    boundaries = np.flatnonzero(np.diff(episode_index)) + 1
    for lo, hi in zip(np.r_[0, boundaries], np.r_[boundaries, len(episode_index)], strict=True):
        starts += range(int(lo), int(max(lo + 1, hi - drop_last)))
    return np.asarray(starts, dtype=np.int64)


def dataset_sample_starts(root: Path) -> int:
    """How many sample starts (:func:`sample_starts`) the trainer draws from the LeRobot
    dataset at ``root``, from its episodes' lengths."""
    from kinder_gym.demos.lerobot_format import load_records

    lengths = [r.num_steps for r in load_records(root)]
    episode = np.repeat(np.arange(len(lengths)), lengths)
    return len(sample_starts(episode, COMMON_FIELDS["drop_n_last_frames"]))


def paper_budget_steps(spec: DatasetSpec, batch_size: int) -> int:
    """Optimiser steps of the paper's budget on a dataset: :data:`PAPER_EPOCHS` epochs, each
    the dataset's sample starts (:func:`dataset_sample_starts`) in full batches, as
    :class:`StepBatches` draws them."""
    return PAPER_EPOCHS * (dataset_sample_starts(spec.root) // batch_size)


def training_budget(
    method: str, env_id: str, preset: str, batch: int, steps: int, paper_epochs: bool
) -> str:
    """The training budget an evaluation of DP/DPES records (``RunConfig.training``): the
    paper's own words (``paper_settings.csv``) when the policy trained the paper's epochs with
    the paper preset and batch, else what it trained."""
    from kinder_bench.reporting.paper import paper_settings

    if paper_epochs and preset == "paper" and batch == PRESET_BATCH["paper"]:
        return str(paper_settings(method, env_id)["training"])
    return f"{steps} steps × batch {batch}, preset {preset}"


def checkpoint_training(ckpt: Checkpoint) -> str:
    """:func:`training_budget` of a DP/DPES checkpoint: the steps it has trained, and the
    paper's epochs only when those are :func:`paper_budget_steps` of its dataset (which must be
    at the path the trainer recorded: where it is not, the paper's budget cannot be checked and
    the steps are recorded as such)."""
    preset = str(ckpt.args["preset"])
    batch = int(ckpt.args["batch_size"] or PRESET_BATCH[preset])
    paper = preset == "paper" and batch == PRESET_BATCH["paper"]
    if paper:
        try:
            spec = read_dataset_spec(ckpt.info["dataset"])
        except FileNotFoundError:
            paper = False
        else:
            paper = ckpt.step == paper_budget_steps(spec, batch)
    return training_budget(ckpt.method, ckpt.info["env_id"], preset, batch, ckpt.step, paper)


class StepBatches:
    """The batches of steps ``[start, stop)``: epoch ``e`` is a permutation of ``indices`` drawn
    from ``default_rng([seed, e])``, cut into full batches, so batch ``k`` depends only on
    ``(seed, k)`` and resuming at step ``k`` continues the same sequence."""

    def __init__(
        self, indices: NDArray[np.int64], batch_size: int, seed: int, start: int, stop: int
    ) -> None:
        if len(indices) < batch_size:
            raise ValueError(
                f"The dataset has {len(indices)} usable samples, fewer than one batch of "
                f"{batch_size}; use a smaller --batch-size or more demonstrations"
            )
        self.indices, self.batch_size, self.seed = indices, batch_size, seed
        self.start, self.stop = start, stop
        self.per_epoch = len(indices) // batch_size

    def batch(self, k: int) -> list[int]:
        epoch, pos = divmod(k, self.per_epoch)
        perm = np.random.default_rng([self.seed, epoch]).permutation(self.indices)
        return [int(i) for i in perm[pos * self.batch_size : (pos + 1) * self.batch_size]]

    def __iter__(self) -> Iterator[list[int]]:
        for k in range(self.start, self.stop):
            yield self.batch(k)

    def __len__(self) -> int:
        return self.stop - self.start


class DemoWindows:
    """Training samples as lerobot's ``delta_timestamps`` windows would give them, read from
    memory: for frame ``i``, the observations of frames ``i - n_obs_steps + 1 .. i`` and the
    actions of ``i - n_obs_steps + 1 .. i - n_obs_steps + horizon``, indices clamped to the
    episode, with ``action_is_pad`` marking the clamped actions. The state columns are held in
    memory (lerobot's per-item dataset queries cost more than a small model's step); only the
    camera frames are decoded per item, through ``LeRobotDataset``.
    """

    def __init__(self, spec: DatasetSpec, cfg: Any) -> None:
        from kinder_gym.demos.lerobot_format import load_dataset, load_records

        records = load_records(spec.root)
        observations = np.concatenate([r.observations[:-1] for r in records])
        state, env_state = spec.split.split(observations.astype(np.float32))
        self.columns = {
            STATE_KEY: np.ascontiguousarray(state),
            ENV_STATE_KEY: np.ascontiguousarray(env_state),
            ACTION_KEY: np.concatenate([r.actions for r in records]).astype(np.float32),
        }
        self.episode = np.repeat(np.arange(len(records)), [r.num_steps for r in records])
        n = len(self.episode)
        change = np.flatnonzero(np.diff(self.episode)) + 1
        lo = np.r_[0, change]
        hi = np.r_[change, n]
        self.lo = np.repeat(lo, hi - lo)
        self.hi = np.repeat(hi, hi - lo)
        self.obs_offsets = np.asarray(cfg.observation_delta_indices, dtype=np.int64)
        self.action_offsets = np.asarray(cfg.action_delta_indices, dtype=np.int64)
        self.env_state = ENV_STATE_KEY in cfg.input_features
        self.video = None
        self.image_keys = spec.image_keys
        if self.image_keys:
            fps = _meta(spec.root).fps
            deltas = {k: [i / fps for i in cfg.observation_delta_indices] for k in self.image_keys}
            self.video = load_dataset(spec.root, delta_timestamps=deltas)
            if len(self.video) != n:
                raise ValueError(f"{spec.root}: {len(self.video)} frames, but {n} in the records")

    def __len__(self) -> int:
        return len(self.episode)

    def __getitem__(self, i: int) -> dict[str, Any]:
        import torch

        lo, hi = self.lo[i], self.hi[i]
        obs = np.clip(i + self.obs_offsets, lo, hi - 1)
        raw = i + self.action_offsets
        act = np.clip(raw, lo, hi - 1)
        item: dict[str, Any] = {
            STATE_KEY: torch.from_numpy(self.columns[STATE_KEY][obs]),
            ACTION_KEY: torch.from_numpy(self.columns[ACTION_KEY][act]),
            "action_is_pad": torch.from_numpy((raw < lo) | (raw >= hi)),
        }
        if self.env_state:
            item[ENV_STATE_KEY] = torch.from_numpy(self.columns[ENV_STATE_KEY][obs])
        if self.video is not None:
            frames = self.video[int(i)]
            item.update({k: frames[k] for k in self.image_keys})
        return item


def _stats_tensors(stats: Mapping[str, Mapping[str, Any]]) -> dict[str, torch.Tensor]:
    import torch

    flat = {}
    for key, values in stats.items():
        for stat, value in values.items():
            flat[f"{key}/{stat}"] = torch.as_tensor(np.asarray(value, dtype=np.float32))
    return flat


def _unflatten_stats(flat: Mapping[str, torch.Tensor]) -> dict[str, dict[str, torch.Tensor]]:
    stats: dict[str, dict[str, torch.Tensor]] = {}
    for name, value in flat.items():
        key, _, stat = name.rpartition("/")
        stats.setdefault(key, {})[stat] = value
    return stats


def _policy_stats(stats: Mapping[str, Any], cfg: Any) -> dict[str, dict[str, Any]]:
    keys = {*cfg.input_features, *cfg.output_features}
    return {k: dict(v) for k, v in stats.items() if k in keys}


def train_diffusion(args: DiffusionTrainArgs, progress: bool = True) -> Path:
    """Train (or resume) DP/DPES into ``args.out``; returns the last checkpoint.

    Writes ``config.json`` (the arguments and versions), ``progress.csv`` (step, loss, lr,
    samples/s) and ``checkpoints/step_*/`` every ``save_every`` steps and at the end. Rerunning
    with the same ``out`` resumes from the newest checkpoint (bit-identical on the CPU). The
    learning-rate schedule spans ``steps``: raising ``steps`` to extend a run changes the schedule
    from the resume point on.
    """
    import torch
    from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy
    from lerobot.policies.diffusion.processor_diffusion import make_diffusion_pre_post_processors
    from safetensors.torch import load_file
    from tqdm import tqdm

    spec = read_dataset_spec(args.dataset)
    env_id = resolve_dataset_env(spec, args.env)
    device = resolve_device(args.device)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    config_record = {
        "trainer": "diffusion",
        "args": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
        "env_id": env_id,
        "versions": package_versions(),
    }
    check_resume_config(out, config_record, ("dataset", "method", "preset", "seed", "batch_size"))
    write_json(out / "config.json", config_record)

    torch.manual_seed(args.seed)
    cfg = diffusion_config(
        spec.root,
        args.method,
        args.preset,
        device,
        optimizer_lr=args.lr,
        scheduler_warmup_steps=args.warmup_steps,
    )
    dataset = DemoWindows(spec, cfg)
    stats = _policy_stats(_meta(spec.root).stats, cfg)
    policy = DiffusionPolicy(cfg).to(device)
    preprocess, _ = make_diffusion_pre_post_processors(cfg, stats)
    optimizer = torch.optim.AdamW(
        policy.get_optim_params(),
        lr=cfg.optimizer_lr,
        betas=cfg.optimizer_betas,
        eps=cfg.optimizer_eps,
        weight_decay=cfg.optimizer_weight_decay,
    )
    scheduler = torch.optim.lr_scheduler.LambdaLR(
        optimizer, lr_lambda(cfg.scheduler_warmup_steps, args.steps)
    )
    ema = EMA(policy) if args.ema else None
    step = 0
    resume = latest_checkpoint(out)
    if resume is not None:
        read_checkpoint(resume, (args.method,))  # this format and method, or a clear error
        state = torch.load(resume / "training_state.pt", map_location=device, weights_only=False)
        policy.load_state_dict(state["policy"])
        optimizer.load_state_dict(state["optimizer"])
        scheduler.load_state_dict(state["scheduler"])
        torch.set_rng_state(state["torch_rng"])
        if state.get("cuda_rng") is not None and torch.cuda.is_available():
            torch.cuda.set_rng_state_all(state["cuda_rng"])
        step = int(state["step"])
        if ema is not None:
            ema.module.load_state_dict(load_file(str(resume / "model.safetensors")), strict=False)
            ema.step = int(state["ema_step"])
    if step >= args.steps:
        return resume if resume is not None else out

    starts = sample_starts(dataset.episode, cfg.drop_n_last_frames)
    batches = StepBatches(starts, args.batch, args.seed, step, args.steps)
    loader: Any = torch.utils.data.DataLoader(
        dataset,  # type: ignore[arg-type]
        batch_sampler=batches,
        num_workers=args.num_workers,
        pin_memory=device == "cuda",
        persistent_workers=False,
        generator=torch.Generator().manual_seed(args.seed),  # keeps the global RNG untouched
    )
    log = CsvLog(out / "progress.csv", ("step", "loss", "lr", "samples_per_s", "elapsed_s"))

    def write(ckpt: Path) -> None:
        _write_checkpoint(ckpt, policy, ema, optimizer, scheduler, step, stats)

    policy.train()
    losses: list[float] = []
    last = None
    t_log = time.perf_counter()
    t0 = t_log
    bar = tqdm(total=args.steps, initial=step, disable=not progress, desc=f"{args.method} {env_id}")
    for batch in loader:
        batch = preprocess(batch)
        loss, _ = policy.forward(batch)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        scheduler.step()
        if ema is not None:
            ema.update(policy)
        step += 1
        losses.append(float(loss.detach()))
        bar.update(1)
        bar.set_postfix(loss=f"{losses[-1]:.4f}")
        if step % args.log_every == 0 or step == args.steps:
            now = time.perf_counter()
            log.write(
                {
                    "step": step,
                    "loss": float(np.mean(losses)),
                    "lr": scheduler.get_last_lr()[0],
                    "samples_per_s": len(losses) * args.batch / max(now - t_log, 1e-9),
                    "elapsed_s": now - t0,
                }
            )
            losses, t_log = [], now
        if step % args.save_every == 0 or step == args.steps:
            last = save_checkpoint(
                out, step, args.method, args, write, info=_info(spec, env_id, args), keep=args.keep
            )
    bar.close()
    assert last is not None
    return last


def _meta(dataset_root: Path) -> Any:
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata

    return LeRobotDatasetMetadata(f"kinder/{dataset_root.name}", root=dataset_root)


def _write_checkpoint(
    ckpt: Path,
    policy: DiffusionPolicy,
    ema: EMA | None,
    optimizer: Any,
    scheduler: Any,
    step: int,
    stats: Mapping[str, Any],
) -> None:
    """The trainer's files of a checkpoint: the (EMA) policy as lerobot saves it, the dataset
    statistics, and ``training_state.pt`` (the raw weights, optimiser, scheduler, RNGs)."""
    import torch
    from safetensors.torch import save_file

    saved: Any = ema.module if ema is not None else policy
    saved.save_pretrained(ckpt)
    save_file(_stats_tensors(stats), str(ckpt / "stats.safetensors"))
    torch.save(
        {
            "policy": policy.state_dict(),
            "optimizer": optimizer.state_dict(),
            "scheduler": scheduler.state_dict(),
            "step": step,
            "ema_step": ema.step if ema is not None else 0,
            "torch_rng": torch.get_rng_state(),
            "cuda_rng": torch.cuda.get_rng_state_all() if torch.cuda.is_available() else None,
        },
        ckpt / "training_state.pt",
    )


def _info(spec: DatasetSpec, env_id: str, args: DiffusionTrainArgs) -> dict[str, Any]:
    """The checkpoint's ``info``: what the agents need to build the policy's inputs."""
    return {
        "env_id": env_id,
        "preset": args.preset,
        "dataset": str(spec.root),
        "state_names": list(spec.state_names),
        "env_state_names": list(spec.env_state_names) if args.method == "dpes" else [],
        "cameras": list(spec.cameras),
        "image_size": spec.image_size,
    }


@dataclasses.dataclass(frozen=True)
class LoadedPolicy:
    """A trained DP/DPES policy with its processors and observation layout."""

    policy: Any
    preprocess: Any
    postprocess: Any
    checkpoint: Checkpoint

    @property
    def path(self) -> Path:
        return self.checkpoint.path


_CACHE: dict[tuple[str, float, str], LoadedPolicy] = {}


def load_policy(path: Path | str, device: str = "cpu") -> LoadedPolicy:
    """The policy of a checkpoint (or of a run directory's latest one), cached per process.

    Raises:
        FileNotFoundError: no checkpoint at ``path``.
        CheckpointError: not a DP/DPES checkpoint of this format.
    """
    from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy
    from lerobot.policies.diffusion.processor_diffusion import make_diffusion_pre_post_processors
    from safetensors.torch import load_file

    checkpoint = load_checkpoint(path, METHODS)
    ckpt = checkpoint.path
    device = resolve_device(device)
    key = (str(ckpt.resolve()), (ckpt / METADATA_FILE).stat().st_mtime, device)
    if key not in _CACHE:
        policy = DiffusionPolicy.from_pretrained(ckpt, local_files_only=True)
        policy.config.device = device
        policy.to(device).eval()
        stats = _unflatten_stats(load_file(str(ckpt / "stats.safetensors")))
        pre, post = make_diffusion_pre_post_processors(policy.config, stats)
        _CACHE.clear()  # one policy per process is enough for the runner
        _CACHE[key] = LoadedPolicy(policy, pre, post, checkpoint)
    return _CACHE[key]


@dataclasses.dataclass(frozen=True)
class DiffusionAgentArgs:
    """Arguments of the DP/DPES agents."""

    checkpoint: str = ""
    """A run directory of ``kinder train dp|dpes`` (its latest checkpoint) or one checkpoint."""
    device: str = "cpu"
    """Where the policy runs: ``cpu``, ``cuda`` or ``auto``."""


class DiffusionAgent(Agent[DiffusionAgentArgs]):
    """A trained diffusion policy (DP: camera images and the robot state).

    Keeps the last 2 observations and the queue of the 8 actions still to execute per episode;
    the denoising noise comes from the agent's seed."""

    name = "dp"
    Args = DiffusionAgentArgs

    @classmethod
    def unavailable(cls, args: Any, env_id: str) -> str | None:
        """Needs a trained checkpoint."""
        del env_id
        return needs_checkpoint(args, cls.name)

    method = "dp"

    def __init__(self, env: gymnasium.Env[Any, Any], args: DiffusionAgentArgs, seed: int) -> None:
        super().__init__(env, args, seed)
        import torch

        if not args.checkpoint:
            raise ValueError(f"Agent {self.name!r} needs --arg checkpoint=DIR (a trained run)")
        self.loaded = load_policy(args.checkpoint, args.device)
        method, meta = self.loaded.checkpoint.method, self.loaded.checkpoint.info
        if method != self.method:
            raise ValueError(f"{self.loaded.path} is a {method!r} checkpoint; use --agent {method}")
        self.obs_map = ObservationMap(
            env,
            meta["state_names"],
            meta["env_state_names"],
            meta["cameras"],
            int(meta["image_size"]),
        )
        cfg = self.loaded.policy.config
        self._noise_shape = (1, cfg.horizon, cfg.action_feature.shape[0])
        self._generator = torch.Generator().manual_seed(int(seed))

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        self.loaded.policy.reset()  # clears the observation history and the action queue

    def act(self, obs: Any) -> NDArray[np.float64]:
        import torch

        features = self.obs_map.features(self.observed_state(obs))
        batch: dict[str, Any] = {}
        for key, value in features.items():
            tensor = torch.from_numpy(np.array(value))  # a writable copy
            if value.dtype == np.uint8:
                tensor = tensor.permute(2, 0, 1).float() / 255.0
            batch[key] = tensor
        batch = self.loaded.preprocess(batch)
        noise = torch.randn(self._noise_shape, generator=self._generator)
        noise = noise.to(self.loaded.policy.config.device)
        with torch.inference_mode():
            action = self.loaded.policy.select_action(batch, noise=noise)
        action = self.loaded.postprocess(action)
        return self.clip(action.detach().cpu().numpy().reshape(-1))


class DPESAgent(DiffusionAgent):
    """A trained diffusion policy with environment states (DPES: images, robot and env state)."""

    name = "dpes"
    method = "dpes"
