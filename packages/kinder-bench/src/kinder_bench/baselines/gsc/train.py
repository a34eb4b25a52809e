"""Training GSC for one env: data preparation, then the per-skill ε-models and classifiers.

Stages, each resumable, all files under the output directory:

1. ``demo_transitions.npz``: the skill transitions of the demonstrations: skill-labelled records
   from ``dataset`` (a LeRobot dataset written by ``kinder_gym.demos.lerobot_format``, or a demo
   collection directory of :mod:`kinder_bench.demos.collection`), records given directly, or,
   without either, ``demo_episodes`` successful bilevel-planner episodes collected into
   ``demos/`` (:func:`kinder_bench.demos.collection.collect`, collection seed ``demo_seed``,
   resumable). The default ``demo_seed`` (1000) keeps the training instances apart from the
   evaluation's: the runner's seed ``s`` and a collection with seed ``s`` draw the same
   instances. Written once; reused on resume.
2. ``transitions.npz``: those plus ``perturbations`` executions of perturbed parameters per
   successful demo transition, labelled by outcome (the classifier's negatives; the successes
   also train the ε-models). Written once; reused on resume.
3. Training: each step takes, for every skill, one minibatch of successful ``[s, a, s′]``
   windows for its ε-model (t ~ U(0.001, 1), MSE on ε) and one class-balanced minibatch of
   ``[s, a]`` with outcome labels for its classifier (BCE). Adam (lr ``lr``, GSC's 1e-3) with a
   cosine decay to 0 over ``steps``. A checkpoint in the trainers' format
   (:mod:`kinder_bench.training.checkpoints`; method ``gsc``, step = optimiser steps) holding
   ``model.pt`` (what the agent loads) and ``train_state.pt`` (optimiser, step, RNG) is written
   every ``checkpoint_every`` steps and at the end under ``checkpoints/step_*/``; rerunning the
   same command resumes from the newest one, and a larger ``steps`` continues a finished run.
   ``progress.csv`` (:class:`~kinder_bench.training.csvlog.CsvLog`) gets one row per skill
   every ``log_every`` steps; ``summary.json`` the data sizes and times.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import torch
import tqdm
from numpy.typing import NDArray

from kinder_bench.baselines.gsc.config import GSCTrainConfig
from kinder_bench.baselines.gsc.data import (
    SkillTransition,
    load_transitions,
    perturbed_transitions,
    save_transitions,
    transitions_from_records,
)
from kinder_bench.baselines.gsc.model import (
    MODEL_FILE,
    GSCModel,
    Layout,
    NetConfig,
    SkillSpec,
    alpha_bar,
    state_scaler,
)
from kinder_bench.demos.collection import CONFIG_FILE as COLLECT_CONFIG
from kinder_bench.demos.collection import CollectConfig, collect, kept_files
from kinder_bench.evaluation.envs import resolve_env_id
from kinder_bench.evaluation.results import write_json
from kinder_bench.training.checkpoints import latest_checkpoint, read_checkpoint, save_checkpoint
from kinder_bench.training.csvlog import CsvLog
from kinder_core import ObjectCentricEnv, make_object_centric
from kinder_gym.demos.record import EpisodeRecord
from kinder_gym.demos.store import load_record
from kinder_gym.models import model_for

FloatArray = NDArray[np.float64]

TRAIN_STATE_FILE = "train_state.pt"
LOG_COLUMNS = ("step", "operator", "score_loss", "classifier_loss", "classifier_acc", "seconds")


@dataclasses.dataclass
class _SkillData:
    windows: torch.Tensor  # successful [s, a, s'] (normalised, skill order)
    cls_x: torch.Tensor  # [s, a] of every execution
    cls_y: torch.Tensor  # outcome labels
    pos: torch.Tensor  # indices of cls_y == 1
    neg: torch.Tensor  # indices of cls_y == 0


def prepare_transitions(
    config: GSCTrainConfig,
    env: ObjectCentricEnv,
    records: Sequence[EpisodeRecord] | None = None,
    show_progress: bool = True,
) -> list[SkillTransition]:
    """Stages 1 and 2 of the module docstring (cached in the output directory)."""
    out = Path(config.out)
    full = out / "transitions.npz"
    if full.is_file():
        return load_transitions(full)
    demo_file = out / "demo_transitions.npz"
    if demo_file.is_file():
        demos = load_transitions(demo_file)
    else:
        if records is None:
            if config.dataset is not None:
                records = load_demonstrations(config.dataset)
            else:
                collect(
                    CollectConfig(
                        config.env_id,
                        "bilevel_planning",
                        episodes=config.demo_episodes,
                        seed=config.demo_seed,
                    ),
                    out / "demos",
                    executor="inline",
                    progress=show_progress,
                )
                records = load_demonstrations(out / "demos")
        demos = transitions_from_records(records, env)
        save_transitions(demo_file, demos)
    rng = np.random.default_rng([config.seed, 1])
    with tqdm.tqdm(total=len(demos), desc="perturbed executions", disable=not show_progress) as bar:
        extra = perturbed_transitions(
            env,
            demos,
            config.perturbations,
            config.perturb_noise,
            rng,
            config.perturb_uniform,
            progress=bar.update,
        )
    transitions = demos + extra
    save_transitions(full, transitions)
    return transitions


def load_demonstrations(root: Path | str) -> list[EpisodeRecord]:
    """The records of a demo collection directory (``collect.json``; its kept episodes) or of a
    LeRobot dataset (``meta/info.json``)."""
    root = Path(root)
    if (root / COLLECT_CONFIG).is_file():
        return [load_record(p) for p in kept_files(root)]
    if (root / "meta" / "info.json").is_file():
        os.environ.setdefault("HF_HUB_OFFLINE", "1")  # a local dataset never needs the hub
        try:
            from kinder_gym.demos import lerobot_format
        except ImportError as e:
            raise ImportError(
                f"Reading the LeRobot dataset {root} needs lerobot (`uv sync --all-extras`): {e}"
            ) from e
        return lerobot_format.load_records(root)
    raise FileNotFoundError(
        f"{root} is neither a demo collection (no {COLLECT_CONFIG}) nor a LeRobot dataset (no "
        "meta/info.json)"
    )


def build_model(
    config: GSCTrainConfig, env: ObjectCentricEnv, transitions: Sequence[SkillTransition]
) -> GSCModel:
    """An untrained model whose layout, scaling and static mask come from ``transitions``."""
    layout = Layout.of_env(env)
    states = np.concatenate(
        [np.stack([t.start for t in transitions]), np.stack([t.end for t in transitions])]
    )
    if states.shape[1] != layout.dim:
        raise ValueError(
            f"Transitions have {states.shape[1]}-dim states; {config.env_id} has {layout.dim}"
        )
    changed = np.zeros(layout.dim, dtype=bool)
    for t in transitions:
        changed |= t.start != t.end
    planning = model_for(env)
    specs = []
    for op in sorted({t.operator for t in transitions}):
        space = next(s for s in planning.skills if s.name == op).params_space
        lo, hi = space.low.astype(np.float64), space.high.astype(np.float64)
        data = [t.params for t in transitions if t.operator == op]
        if not np.all(np.isfinite(lo)) or not np.all(np.isfinite(hi)):
            arr = np.stack(data)
            lo = np.where(np.isfinite(lo), lo, arr.min(axis=0))
            hi = np.where(np.isfinite(hi), hi, arr.max(axis=0))
        specs.append(SkillSpec(op, int(space.shape[0]), lo, hi))
    net = NetConfig(config.hidden, config.depth, config.classifier_hidden, config.classifier_depth)
    return GSCModel(
        resolve_env_id(config.env_id), layout, state_scaler(layout, states), ~changed, specs, net
    )


def _skill_data(model: GSCModel, transitions: Sequence[SkillTransition]) -> dict[str, _SkillData]:
    out = {}
    for op, spec in model.skills.items():
        trs = [t for t in transitions if t.operator == op]
        perms = [model.layout.order(t.objects) for t in trs]
        s = np.stack([model.state.norm(t.start)[p] for t, p in zip(trs, perms, strict=True)])
        e = np.stack([model.state.norm(t.end)[p] for t, p in zip(trs, perms, strict=True)])
        a = np.stack([spec.scaler.norm(t.params) for t in trs]).reshape(len(trs), spec.param_dim)
        y = np.asarray([t.success for t in trs], dtype=np.float32)
        ok = y > 0.5
        if not ok.any():
            raise ValueError(f"No successful execution of {op} in the data; cannot train GSC")
        windows = np.concatenate([s, a, e], axis=1)[ok]
        out[op] = _SkillData(
            torch.as_tensor(windows, dtype=torch.float32),
            torch.as_tensor(np.concatenate([s, a], axis=1), dtype=torch.float32),
            torch.as_tensor(y),
            torch.as_tensor(np.flatnonzero(ok)),
            torch.as_tensor(np.flatnonzero(~ok)),
        )
    return out


def train_gsc(
    config: GSCTrainConfig,
    records: Sequence[EpisodeRecord] | None = None,
    show_progress: bool = True,
    on_step: Callable[[int], None] | None = None,
) -> GSCModel:
    """Prepare the data and train (or resume training) into ``config.out``; returns the model.

    ``on_step(step)`` is called after every step (tests use it to interrupt training).
    """
    torch.set_num_threads(config.threads)
    env_id = resolve_env_id(config.env_id)
    config = dataclasses.replace(config, env_id=env_id)
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    cfg_file = out / "config.json"
    if cfg_file.is_file():
        old = json.loads(cfg_file.read_text())
        if old.get("data") != config.data_dict():
            raise ValueError(
                f"{out} holds a GSC run with other settings ({old.get('data')}); use another "
                "output directory or the same settings"
            )
    write_json(cfg_file, {"data": config.data_dict(), "steps": config.steps})

    env = make_object_centric(env_id)
    t0 = time.perf_counter()
    transitions = prepare_transitions(config, env, records, show_progress)
    data_seconds = time.perf_counter() - t0

    torch.manual_seed(config.seed)  # network initialisation
    model = build_model(config, env, transitions)
    data = _skill_data(model, transitions)
    params = list(model.score_nets.parameters()) + list(model.classifiers.parameters())
    opt = torch.optim.Adam(params, lr=config.lr)
    gen = torch.Generator().manual_seed(config.seed)
    step, train_seconds = 0, 0.0
    resume = latest_checkpoint(out)
    if resume is not None:
        read_checkpoint(resume, ("gsc",))  # this format and method, or a clear error
        saved = torch.load(resume / MODEL_FILE, map_location="cpu", weights_only=True)
        model.score_nets.load_state_dict(saved["score_nets"])
        model.classifiers.load_state_dict(saved["classifiers"])
        st = torch.load(resume / TRAIN_STATE_FILE, map_location="cpu", weights_only=True)
        opt.load_state_dict(st["optimizer"])
        gen.set_state(st["generator"])
        step, train_seconds = int(st["step"]), float(st["seconds"])
    log = CsvLog(out / "progress.csv", LOG_COLUMNS)

    def write(ckpt: Path) -> None:
        model.save(ckpt)
        torch.save(
            {
                "optimizer": opt.state_dict(),
                "generator": gen.get_state(),
                "step": step,
                "seconds": train_seconds,
            },
            ckpt / TRAIN_STATE_FILE,
        )

    def save() -> None:
        info = {"env_id": env_id, "operators": sorted(model.skills)}
        save_checkpoint(out, step, "gsc", config, write, info=info, keep=config.keep)
        write_json(
            out / "summary.json",
            {
                "env_id": env_id,
                "steps": step,
                "train_seconds": round(train_seconds, 2),
                "data_seconds_this_run": round(data_seconds, 2),
                "transitions": {
                    op: {
                        "ok": int(d.pos.numel()),
                        "failed": int(d.neg.numel()),
                    }
                    for op, d in data.items()
                },
            },
        )

    model.score_nets.train()
    model.classifiers.train()
    bce = torch.nn.BCEWithLogitsLoss()
    sums: dict[str, list[float]] = {op: [0.0, 0.0, 0.0, 0.0] for op in data}
    last = time.perf_counter()
    with tqdm.tqdm(
        total=config.steps,
        initial=min(step, config.steps),
        desc=f"GSC {env_id}",
        disable=not show_progress,
    ) as bar:
        while step < config.steps:
            lr = 0.5 * config.lr * (1 + math.cos(math.pi * step / config.steps))
            for group in opt.param_groups:
                group["lr"] = lr
            opt.zero_grad()
            total = torch.zeros(())
            for op, d in data.items():
                idx = torch.randint(0, d.windows.shape[0], (config.batch_size,), generator=gen)
                x0 = d.windows[idx]
                t = torch.rand(config.batch_size, generator=gen) * 0.999 + 0.001
                ab = alpha_bar(t)[:, None]
                eps = torch.randn(x0.shape, generator=gen)
                xt = ab.sqrt() * x0 + (1 - ab).sqrt() * eps
                score_loss = ((model.score_nets[op](xt, t) - eps) ** 2).mean()
                half = config.batch_size // 2
                if d.neg.numel() and d.pos.numel():
                    ci = torch.cat(
                        [
                            d.pos[torch.randint(0, d.pos.numel(), (half,), generator=gen)],
                            d.neg[torch.randint(0, d.neg.numel(), (half,), generator=gen)],
                        ]
                    )
                else:
                    ci = torch.randint(0, d.cls_y.numel(), (config.batch_size,), generator=gen)
                logits = model.classifiers[op](d.cls_x[ci])
                cls_loss = bce(logits, d.cls_y[ci])
                total = total + score_loss + cls_loss
                acc = ((logits > 0).float() == d.cls_y[ci]).float().mean()
                s = sums[op]
                s[0] += float(score_loss.detach())
                s[1] += float(cls_loss.detach())
                s[2] += float(acc)
                s[3] += 1
            total.backward()  # type: ignore[no-untyped-call]
            opt.step()
            step += 1
            now = time.perf_counter()
            train_seconds += now - last
            last = now
            bar.update(1)
            if step % config.log_every == 0 or step == config.steps:
                for op, s in sums.items():
                    n = max(s[3], 1.0)
                    log.write(
                        {
                            "step": step,
                            "operator": op,
                            "score_loss": round(s[0] / n, 6),
                            "classifier_loss": round(s[1] / n, 6),
                            "classifier_acc": round(s[2] / n, 4),
                            "seconds": round(train_seconds, 2),
                        }
                    )
                    sums[op] = [0.0, 0.0, 0.0, 0.0]
                bar.set_postfix(loss=f"{float(total.detach()):.4f}")
            if step % config.checkpoint_every == 0 or step == config.steps:
                save()
                last = time.perf_counter()
            if on_step is not None:
                on_step(step)
    if latest_checkpoint(out) is None:
        save()
    return model.eval()


__all__ = [
    "LOG_COLUMNS",
    "TRAIN_STATE_FILE",
    "GSCTrainConfig",
    "build_model",
    "load_demonstrations",
    "prepare_transitions",
    "train_gsc",
]
