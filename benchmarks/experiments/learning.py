"""Train and evaluate one learning baseline (DP, DPES or MBRL) on the paper's benchmark envs.

Usage (resumable; the method is the first argument, its options follow)::

    # the paper's budget on all eight envs
    uv run python benchmarks/experiments/learning.py dp
    uv run python benchmarks/experiments/learning.py dpes --env Motion2D-p0 --preset cpu \\
        --steps 1500
    uv run python benchmarks/experiments/learning.py mbrl --env Motion2D-p0 --seeds 0 --episodes 10

The paper's protocol for every baseline at once is the campaign driver (``uv run kinder bench
campaign benchmarks/campaigns/paper.toml --only mbrl``; benchmarks/README.md, "Campaigns").

For every env
(default: the paper's eight) it takes the demonstration dataset
``datasets/<Env>/data/lerobot`` (made by ``make datasets DATASETS=<Env>``; a missing one is
reported and skipped), trains into ``<out>/train/<Env>`` and evaluates with the standard runner
into ``<out>/eval``; then it writes the report (``kinder bench report``) and ``<out>/cells.md``,
which states the training budget of every cell (demos, steps or epochs, batch, preset, training
wall time and samples/s from ``progress.csv``). Everything resumes: training continues from its
last checkpoint, evaluation skips the episodes already in ``results.jsonl``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


METHODS = ("dp", "dpes", "mbrl")


def parse_args(method: str, argv: list[str] | None = None) -> argparse.Namespace:
    from kinder_bench.evaluation.protocol import PAPER_ENVS

    diffusion = method in ("dp", "dpes")
    p = argparse.ArgumentParser(
        prog=f"learning.py {method}", description=f"Train and evaluate {method.upper()}."
    )
    p.add_argument("--env", action="append", help="Env id(s); default: the paper's eight.")
    p.add_argument("--datasets", type=Path, default=ROOT / "datasets", help="Datasets root.")
    p.add_argument("--out", type=Path, default=ROOT / "runs" / "learning" / method)
    p.add_argument("--seeds", default="0-4", help="Evaluation run seeds (paper: 0-4).")
    p.add_argument("--episodes", type=int, default=50, help="Episodes per seed (paper: 50).")
    p.add_argument("--workers", type=int, default=None, help="Evaluation worker processes.")
    p.add_argument("--executor", default="process", help="process, inline or ray.")
    p.add_argument("--skip-eval", action="store_true", help="Only train.")
    if diffusion:
        p.add_argument("--steps", type=int, default=100_000, help="Optimiser steps per env.")
        p.add_argument(
            "--paper-budget",
            action="store_true",
            help="Train the paper's budget (5001 epochs over the dataset; overrides --steps); "
            "with the paper preset the run fills the paper's cell.",
        )
        p.add_argument("--preset", default="paper", help="paper or cpu.")
        p.add_argument("--batch-size", type=int, default=None)
        p.add_argument("--device", default="auto")
        p.add_argument("--num-workers", type=int, default=0, help="Data-loading workers.")
        p.add_argument("--save-every", type=int, default=1000)
    else:
        p.add_argument("--epochs", type=int, default=1000, help="Epochs per env (paper: 1000).")
        p.add_argument("--horizon", type=int, default=None, help="MPC horizon (default 100).")
    args = p.parse_args(argv)
    args.env = args.env or list(PAPER_ENVS)
    return args


def dataset_dir(datasets: Path, env_id: str) -> Path:
    from kinder_bench.evaluation.envs import short_id

    return datasets / short_id(env_id) / "data" / "lerobot"


def _throughput(run: Path) -> str:
    rows = (
        list(csv.DictReader((run / "progress.csv").open()))
        if (run / "progress.csv").exists()
        else []
    )
    if not rows:
        return "--"
    return f"{sum(float(r['samples_per_s']) for r in rows) / len(rows):.0f}"


def main(argv: list[str] | None = None) -> int:
    """Run ``learning.py METHOD [OPTIONS]``; a missing or unknown method is a usage error."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] in (["-h"], ["--help"]):
        print(f"usage: learning.py {{{','.join(METHODS)}}} [OPTIONS]\n\n{__doc__}")
        print("Each method's options: learning.py METHOD --help")
        return 0
    if not argv or argv[0] not in METHODS:
        got = repr(argv[0]) if argv else "nothing"
        print(f"usage: learning.py {{{','.join(METHODS)}}} [OPTIONS]; got {got} as the method",
              file=sys.stderr)  # fmt: skip
        return 2
    method, argv = argv[0], argv[1:]
    import torch

    from kinder_bench.baselines.demo_data import read_dataset_spec
    from kinder_bench.cli.common import parse_seeds
    from kinder_bench.evaluation.envs import resolve_env_id, short_id
    from kinder_bench.evaluation.results import write_json
    from kinder_bench.evaluation.runner import RunConfig, run_benchmark
    from kinder_bench.reporting.report import write_report

    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    args = parse_args(method, argv)
    cells = []
    runs = []
    for env in args.env:
        env_id = resolve_env_id(env)
        data = dataset_dir(args.datasets, env_id)
        if not (data / "meta" / "info.json").exists():
            print(f"skip {env_id}: no dataset at {data}; make it with "
                  f"`make datasets DATASETS={short_id(env_id)}`", file=sys.stderr)  # fmt: skip
            continue
        spec = read_dataset_spec(data)
        run = args.out / "train" / short_id(env_id)
        t0 = time.perf_counter()
        if method == "mbrl":
            from kinder_bench.baselines.mbrl import MBRLTrainArgs, train_mbrl

            torch.set_num_threads(1)
            train_mbrl(MBRLTrainArgs(dataset=data, out=run, epochs=args.epochs))
            budget = f"{args.epochs} epochs, batch 512"
            agent_args: dict[str, object] = {"checkpoint": str(run)}
            if args.horizon is not None:
                agent_args["horizon"] = args.horizon
        else:
            from kinder_bench.baselines.diffusion import (
                DiffusionTrainArgs,
                paper_budget_steps,
                train_diffusion,
                training_budget,
            )
            from kinder_bench.baselines.diffusion_presets import PRESET_BATCH

            if args.device != "cuda" and not torch.cuda.is_available():
                torch.set_num_threads(1)
            batch = args.batch_size or PRESET_BATCH[args.preset]
            steps = paper_budget_steps(spec, batch) if args.paper_budget else args.steps
            train_diffusion(
                DiffusionTrainArgs(
                    dataset=data,
                    out=run,
                    method=method,
                    steps=steps,
                    preset=args.preset,
                    batch_size=args.batch_size,
                    device=args.device,
                    num_workers=args.num_workers,
                    save_every=args.save_every,
                )
            )
            budget = training_budget(method, env_id, args.preset, batch, steps, args.paper_budget)
            agent_args = {"checkpoint": str(run), "device": args.device}
        cells.append(
            {
                "env": env_id,
                "demos": spec.num_episodes,
                "frames": spec.num_frames,
                "budget": budget,
                "this_call_s": round(time.perf_counter() - t0, 1),
                "samples_per_s": _throughput(run),
            }
        )
        runs.append(
            RunConfig(env_id, method, agent_args, seeds=parse_seeds(args.seeds),
                      episodes=args.episodes, training=budget)
        )  # fmt: skip
    if not cells:
        print("no datasets found; nothing to do", file=sys.stderr)
        return 1
    args.out.mkdir(parents=True, exist_ok=True)
    # Cells of envs not named in this call (earlier calls) stay; this call's replace theirs.
    path = args.out / "cells.json"
    named = {c["env"] for c in cells}
    earlier = json.loads(path.read_text()) if path.exists() else []
    cells = [c for c in earlier if c["env"] not in named] + cells
    write_json(path, cells)
    lines = ["| env | demos | frames | training budget | samples/s |", "|---|---|---|---|---|"]
    lines += [
        f"| {c['env']} | {c['demos']} | {c['frames']} | {c['budget']} | {c['samples_per_s']} |"
        for c in cells
    ]
    (args.out / "cells.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    if not args.skip_eval:
        run_benchmark(runs, args.out / "eval", executor=args.executor, workers=args.workers)
        table, _ = write_report([args.out / "eval"])
        print(table)
    print(json.dumps({"out": str(args.out)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
