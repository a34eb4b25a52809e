"""What the paper's DP/DPES training budget costs: the paper preset's training step and action
chunk on a GPU, and the camera-frame decoding that feeds the trainer on one CPU core.

Subcommands:

* ``shapes`` (needs the project): the DP/DPES inputs of the paper's eight envs (cameras, image
  size, robot-state, environment-state and action sizes), each demonstration dataset's frames
  and episodes (``results/demo_datasets.json``) and, where the dataset is built here, its exact
  count of sample starts, written as JSON for ``gpu``.
* ``gpu`` (needs only torch and lerobot 0.4.4, so it runs on a GPU machine without the project
  installed; the paper preset and the EMA are loaded from their modules by file path): for each
  env and method, lerobot's ``DiffusionPolicy`` with the paper preset, timed over training steps
  as ``train_diffusion`` takes them (forward, backward, AdamW, the EMA update, the loss read back
  every step) on random batches of the env's shapes already in GPU memory, and over the 16-step
  DDIM generation of one action chunk at batch 1 (``select_action`` on an empty queue, what the
  agent does every 8 steps). The batches cost no loading here, so its samples/s is the model's
  ceiling: the trainer reaches it only where data loading keeps up.
* ``decode`` (needs the project and a dataset): samples/s of the trainer's data pipeline
  (``DemoWindows``: the state and action windows from memory, the camera frames decoded from the
  dataset's videos) on one CPU core, to set beside the GPU's ceiling.

Usage::

    uv run python benchmarks/speed/dp_gpu_cost.py shapes --out runs/dp_gpu/shapes.json
    python3 benchmarks/speed/dp_gpu_cost.py gpu --shapes runs/dp_gpu/shapes.json --out R.json
    uv run python benchmarks/speed/dp_gpu_cost.py decode \
        --dataset datasets/SweepIntoDrawer3D-o5/data/lerobot --out D.json

``benchmarks/device/dp_gpu_cost.sh`` runs ``gpu`` on a GPU machine; the figures are in
``results/learning.md`` ("The paper's DP/DPES budget on a GPU") and ``results/dp_gpu_cost.json``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path
from types import ModuleType, SimpleNamespace
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
BENCH_SRC = ROOT / "packages/kinder-bench/src/kinder_bench"
#: ``kinder train dp|dpes``'s default budget, in optimiser steps.
TRAINER_STEPS = 100_000


def _load(path: Path, name: str) -> ModuleType:
    """A module loaded from its file, without importing its package (see the module docstring)."""
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None, path
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def _write(path: Path, data: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n")
    os.replace(tmp, path)


def _sample_starts(root: Path) -> int | None:
    """The trainer's sample starts in a local dataset, or None where it is not built here."""
    if not (root / "meta/info.json").exists():
        return None
    from kinder_bench.baselines.diffusion import dataset_sample_starts

    return dataset_sample_starts(root)


def shapes(out: Path) -> None:
    from kinder_bench.evaluation.envs import make_env, short_id
    from kinder_bench.evaluation.protocol import PAPER_ENVS
    from kinder_gym.demos.layout import IMAGE_SIZE, StateSplit, camera_names

    built = {
        d["env_id"]: d
        for d in json.loads((ROOT / "benchmarks/results/demo_datasets.json").read_text())
    }
    rows = []
    for env_id in PAPER_ENVS:
        env = make_env(env_id)
        split = StateSplit.from_env(env)
        dataset = built.get(env_id, {})
        local = ROOT / "datasets" / short_id(env_id)
        rows.append(
            {
                "env_id": env_id,
                "cameras": list(camera_names(env)),
                "image_size": IMAGE_SIZE,
                "state_dim": len(split.state_names),
                "env_state_dim": len(split.env_names),
                "action_dim": int(env.action_space.shape[0]),  # type: ignore[index]
                "dataset_frames": dataset.get("build_frames"),
                "dataset_episodes": dataset.get("build_episodes"),
                "dataset_sample_starts": _sample_starts(local / "data/lerobot"),
            }
        )
        env.close()
    _write(out, rows)
    print(json.dumps(rows, indent=1))


def _policy(row: dict[str, Any], method: str, presets: ModuleType, device: str) -> Any:
    from lerobot.configs.types import FeatureType, NormalizationMode, PolicyFeature
    from lerobot.policies.diffusion.configuration_diffusion import DiffusionConfig
    from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy

    size = row["image_size"]
    inputs = {"observation.state": PolicyFeature(FeatureType.STATE, (row["state_dim"],))}
    for cam in row["cameras"]:
        inputs[f"observation.images.{cam}"] = PolicyFeature(FeatureType.VISUAL, (3, size, size))
    if method == "dpes":
        inputs["observation.environment_state"] = PolicyFeature(
            FeatureType.ENV, (row["env_state_dim"],)
        )
    cfg = DiffusionConfig(
        input_features=inputs,
        output_features={"action": PolicyFeature(FeatureType.ACTION, (row["action_dim"],))},
        normalization_mapping={
            "VISUAL": NormalizationMode.MEAN_STD,
            "STATE": NormalizationMode.MIN_MAX,
            "ENV": NormalizationMode.MIN_MAX,
            "ACTION": NormalizationMode.MIN_MAX,
        },
        device=device,
        **{**presets.COMMON_FIELDS, **presets.PRESET_FIELDS["paper"]},
    )
    return cfg, DiffusionPolicy(cfg).to(device)


def _train_batch(cfg: Any, batch: int, device: str) -> dict[str, Any]:
    import torch

    n_obs, horizon = cfg.n_obs_steps, cfg.horizon
    out: dict[str, Any] = {}
    for key, feature in cfg.input_features.items():
        shape = (batch, n_obs, *feature.shape)
        out[key] = torch.rand(shape, device=device) * 2 - 1
    (action,) = cfg.output_features.values()
    out["action"] = torch.rand((batch, horizon, *action.shape), device=device) * 2 - 1
    out["action_is_pad"] = torch.zeros((batch, horizon), dtype=torch.bool, device=device)
    return out


def _sync(device: str) -> None:
    import torch

    if device == "cuda":
        torch.cuda.synchronize()


def _time_train(
    cfg: Any, policy: Any, ema_cls: Any, batch: int, steps: int, warmup: int, device: str
) -> dict[str, float]:
    import torch

    optimizer = torch.optim.AdamW(
        policy.get_optim_params(),
        lr=cfg.optimizer_lr,
        betas=cfg.optimizer_betas,
        eps=cfg.optimizer_eps,
        weight_decay=cfg.optimizer_weight_decay,
    )
    ema = ema_cls(policy)
    data = _train_batch(cfg, batch, device)
    policy.train()
    times = []
    for i in range(warmup + steps):
        _sync(device)
        t = time.perf_counter()
        loss, _ = policy.forward(dict(data))
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        ema.update(policy)
        float(loss.detach())  # the trainer reads the loss back every step
        _sync(device)
        if i >= warmup:
            times.append(time.perf_counter() - t)
    median = statistics.median(times)
    return {
        "step_s_median": median,
        "step_s_mean": statistics.fmean(times),
        "samples_per_s": batch / median,
    }


def _time_chunk(cfg: Any, policy: Any, chunks: int, device: str) -> dict[str, float]:
    import torch

    policy.eval()
    obs = {k: torch.rand((1, *f.shape), device=device) for k, f in cfg.input_features.items()}
    times = []
    with torch.no_grad():
        for i in range(chunks + 2):
            policy.reset()  # an empty queue: the next call generates a chunk
            _sync(device)
            t = time.perf_counter()
            policy.select_action(dict(obs))
            _sync(device)
            if i >= 2:
                times.append(time.perf_counter() - t)
    return {"chunk_s_median": statistics.median(times), "chunk_s_mean": statistics.fmean(times)}


def paper_steps(row: dict[str, Any], presets: ModuleType, batch: int) -> int | None:
    """Optimiser steps of the paper's epochs (``PAPER_EPOCHS`` of the presets module) over the
    env's demonstration dataset. An epoch is the dataset's sample starts in full batches
    (``StepBatches``). Where ``shapes`` found the dataset built, it counted the starts exactly
    (``dataset_sample_starts``, as ``paper_budget_steps`` does); elsewhere they come from the
    frame and episode counts alone: every frame but the last ``drop_last`` of each episode, and
    the first frame of an episode no longer than that, so ``max(frames - drop_last * episodes,
    episodes)`` (exact when every episode is longer than ``drop_last`` frames, or none is)."""
    starts = row.get("dataset_sample_starts")
    if not starts:
        frames, episodes = row.get("dataset_frames"), row.get("dataset_episodes")
        if not frames or not episodes:
            return None
        drop_last = presets.COMMON_FIELDS["drop_n_last_frames"]
        starts = max(frames - drop_last * episodes, episodes)
    return int(presets.PAPER_EPOCHS * (starts // batch))


def _no_video_module() -> ModuleType:
    """A stand-in for PyAV, which lerobot imports at load time (and reads ``av.logging.WARNING``
    from) but this timing never calls: it decodes no video."""
    av = ModuleType("av")
    av.logging = SimpleNamespace(WARNING=30)  # type: ignore[attr-defined]
    return av


def gpu(args: argparse.Namespace) -> None:
    # This project installs lerobot without transformers; a GPU machine's own transformers would
    # make lerobot import its GR00T policy, which that transformers breaks. Hide it.
    sys.modules.setdefault("transformers", None)  # type: ignore[arg-type]
    import torch
    import torchvision  # noqa: F401  (before the stand-in: torchvision checks for PyAV itself)

    if importlib.util.find_spec("av") is None:
        sys.modules["av"] = _no_video_module()

    presets = _load(BENCH_SRC / "baselines/diffusion_presets.py", "kinder_diffusion_presets")
    ema_cls = _load(BENCH_SRC / "training/ema.py", "kinder_ema").EMA
    device = "cuda" if torch.cuda.is_available() else "cpu"
    if args.require_cuda and device != "cuda":
        raise SystemExit("gpu: torch sees no CUDA device (--require-cuda)")
    batch = presets.PRESET_BATCH["paper"]
    rows = json.loads(Path(args.shapes).read_text())
    if args.envs:
        rows = [r for r in rows if r["env_id"].split("/")[-1].removesuffix("-v0") in args.envs]
    results: list[dict[str, Any]] = []
    machine = {
        "device": torch.cuda.get_device_name(0) if device == "cuda" else platform.processor(),
        "torch": torch.__version__,
        "tf32_matmul": torch.backends.cuda.matmul.allow_tf32,
        "tf32_cudnn": torch.backends.cudnn.allow_tf32,
        "date": time.strftime("%Y-%m-%d", time.gmtime()),
    }
    for row in rows:
        for method in args.methods:
            torch.manual_seed(0)
            cfg, policy = _policy(row, method, presets, device)
            params = sum(p.numel() for p in policy.parameters())
            train = _time_train(cfg, policy, ema_cls, batch, args.steps, args.warmup, device)
            chunk = _time_chunk(cfg, policy, args.chunks, device)
            steps = paper_steps(row, presets, batch)
            result = {
                "env_id": row["env_id"],
                "method": method,
                "cameras": len(row["cameras"]),
                "params": params,
                "batch": batch,
                **train,
                **chunk,
                "paper_steps": steps,
                "paper_hours": None if steps is None else steps * train["step_s_median"] / 3600,
                "trainer_default_hours": TRAINER_STEPS * train["step_s_median"] / 3600,
                "peak_gib": torch.cuda.max_memory_allocated() / 2**30 if device == "cuda" else None,
            }
            results.append(result)
            print(json.dumps(result), flush=True)
            del policy
            if device == "cuda":
                torch.cuda.empty_cache()
                torch.cuda.reset_peak_memory_stats()
            _write(Path(args.out), {"machine": machine, "steps": args.steps, "rows": results})


def decode(args: argparse.Namespace) -> None:
    import numpy as np
    import torch

    from kinder_bench.baselines.demo_data import read_dataset_spec
    from kinder_bench.baselines.diffusion import DemoWindows, diffusion_config, sample_starts

    torch.set_num_threads(1)
    spec = read_dataset_spec(Path(args.dataset))
    cfg = diffusion_config(spec.root, args.method, "paper", "cpu")
    windows = DemoWindows(spec, cfg)
    starts = sample_starts(windows.episode, cfg.drop_n_last_frames)
    order = np.random.default_rng(0).permutation(starts)[: args.samples]
    windows[int(order[0])]  # open the decoders
    t = time.perf_counter()
    for i in order[1:]:
        windows[int(i)]
    elapsed = time.perf_counter() - t
    result = {
        "dataset": str(args.dataset),
        "env_id": spec.env_id,
        "method": args.method,
        "cameras": len(spec.cameras),
        "image_size": spec.image_size,
        "samples": len(order) - 1,
        "samples_per_s": (len(order) - 1) / elapsed,
        "frames_per_sample": len(spec.cameras) * cfg.n_obs_steps,
        "date": time.strftime("%Y-%m-%d", time.gmtime()),
    }
    _write(Path(args.out), result)
    print(json.dumps(result))


def table(args: argparse.Namespace) -> None:
    """The committed figures: the GPU rows with the paper's step budget recomputed from the
    shapes file (so that a fix to :func:`paper_steps` needs no GPU), the decode rows beside them,
    written to ``--out`` and printed as the markdown table of ``results/learning.md``."""
    presets = _load(BENCH_SRC / "baselines/diffusion_presets.py", "kinder_diffusion_presets")
    gpu_run = json.loads(Path(args.gpu).read_text())
    shapes_by_env = {r["env_id"]: r for r in json.loads(Path(args.shapes).read_text())}
    rows = []
    for r in gpu_run["rows"]:
        steps = paper_steps(shapes_by_env[r["env_id"]], presets, r["batch"])
        hours = None if steps is None else steps * r["step_s_median"] / 3600
        rows.append({**r, "paper_steps": steps, "paper_hours": hours})
    decodes = [json.loads(Path(d).read_text()) for d in args.decode]
    _write(Path(args.out), {**gpu_run, "rows": rows, "decode": decodes})
    print(
        f"| env | method | cameras | params (M) | samples/s | step (ms) | chunk (ms) | "
        f"paper steps | paper budget (h) | {TRAINER_STEPS // 1000}k steps (h) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        name = r["env_id"].removeprefix("kinder/").removesuffix("-v0")
        budget = "--" if r["paper_hours"] is None else f"{r['paper_hours']:.1f}"
        print(
            f"| {name} | {r['method'].upper()} | {r['cameras']} | {r['params'] / 1e6:.1f} | "
            f"{r['samples_per_s']:,.0f} | {1000 * r['step_s_median']:.1f} | "
            f"{1000 * r['chunk_s_median']:.0f} | {r['paper_steps']:,} | {budget} | "
            f"{r['trainer_default_hours']:.1f} |"
        )
    total = sum(r["paper_hours"] or 0.0 for r in rows)
    print(f"\nAll {len(rows)} cells at the paper's budget: {total:.0f} GPU-hours.")
    for d in decodes:
        print(
            f"Decoding ({d['env_id']}, {d['cameras']} cameras × 2 frames): "
            f"{d['samples_per_s']:.1f} samples/s on one core."
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("shapes")
    p.add_argument("--out", type=Path, required=True)
    p = sub.add_parser("gpu")
    p.add_argument("--shapes", type=Path, required=True)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--envs", nargs="*", help="short names (default: every env in --shapes)")
    p.add_argument("--methods", nargs="+", default=["dp", "dpes"], choices=["dp", "dpes"])
    p.add_argument("--steps", type=int, default=30, help="timed training steps")
    p.add_argument("--warmup", type=int, default=5)
    p.add_argument("--chunks", type=int, default=10, help="timed action-chunk generations")
    p.add_argument("--require-cuda", action="store_true")
    p = sub.add_parser("table")
    p.add_argument("--gpu", type=Path, required=True, help="the gpu subcommand's JSON")
    p.add_argument("--shapes", type=Path, required=True)
    p.add_argument("--decode", type=Path, nargs="*", default=[], help="decode JSONs")
    p.add_argument("--out", type=Path, required=True)
    p = sub.add_parser("decode")
    p.add_argument("--dataset", type=Path, required=True)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--method", default="dp", choices=["dp", "dpes"])
    p.add_argument("--samples", type=int, default=200)
    args = parser.parse_args()
    if args.command == "shapes":
        shapes(args.out)
    elif args.command == "gpu":
        gpu(args)
    elif args.command == "table":
        table(args)
    else:
        decode(args)


if __name__ == "__main__":
    main()
