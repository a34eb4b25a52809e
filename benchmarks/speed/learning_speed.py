"""Training throughput and per-step inference latency of DP, DPES and MBRL on this machine.

For each method (and, for DP/DPES, each preset) it trains a few steps on a demonstration dataset
(samples/s from ``progress.csv``: the optimiser loop only, data loading included, start-up not),
then runs the trained agent for ``--act-steps`` steps of one episode and times every ``act`` call
(DP/DPES: rendering, preprocessing and one 16-step DDIM denoising every 8 steps; MBRL: one MPC
solve per step, ``num_rollouts × horizon`` model steps). Prints a markdown table and one JSON
line per row. Figures are machine- and load-dependent: state the machine with them.

Usage::

    uv run python benchmarks/speed/learning_speed.py --dataset datasets/Motion2D-p0/data/lerobot
    uv run python benchmarks/speed/learning_speed.py --dataset DIR --device cuda --batch-size 64
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
FIXTURE = ROOT / "packages/kinder-gym/tests/data/demos/Motion2D-p0"


def _samples_per_s(run: Path) -> float:
    rows = list(csv.DictReader((run / "progress.csv").open()))
    return float(rows[-1]["samples_per_s"])


def _latency(
    agent_name: str, env_id: str, agent_args: dict[str, object], steps: int
) -> list[float]:
    from kinder_bench.agents import make_agent
    from kinder_bench.evaluation.envs import make_env

    env = make_env(env_id)
    agent = make_agent(agent_name, env, agent_args, seed=0)
    obs, info = env.reset(seed=0)
    agent.reset(obs, info)
    times = []
    for _ in range(steps):
        t = time.perf_counter()
        action = agent.act(obs)
        times.append(time.perf_counter() - t)
        obs, _, terminated, _, _ = env.step(action)
        if terminated:
            obs, info = env.reset(seed=len(times))
            agent.reset(obs, info)
    return times


def main() -> None:
    import torch

    from kinder_bench.baselines.demo_data import read_dataset_spec
    from kinder_bench.baselines.diffusion import DiffusionTrainArgs, train_diffusion
    from kinder_bench.baselines.mbrl import MBRLTrainArgs, train_mbrl

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dataset", type=Path, default=FIXTURE)
    p.add_argument("--methods", default="dp,dpes,mbrl")
    p.add_argument("--presets", default="cpu,paper")
    p.add_argument("--steps", type=int, default=5, help="DP/DPES training steps to time.")
    p.add_argument("--batch-size", type=int, default=16, help="DP/DPES batch (paper: 64).")
    p.add_argument("--epochs", type=int, default=5, help="MBRL epochs to time.")
    p.add_argument("--act-steps", type=int, default=16)
    p.add_argument("--device", default="cpu")
    p.add_argument("--threads", type=int, default=1)
    args = p.parse_args()
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    torch.set_num_threads(args.threads)
    spec = read_dataset_spec(args.dataset)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for method in args.methods.split(","):
            presets = args.presets.split(",") if method != "mbrl" else ["-"]
            for preset in presets:
                run = Path(tmp) / f"{method}-{preset}"
                if method == "mbrl":
                    train_mbrl(
                        MBRLTrainArgs(dataset=args.dataset, out=run, epochs=args.epochs,
                                      save_every=args.epochs), progress=False,
                    )  # fmt: skip
                    agent_args: dict[str, object] = {"checkpoint": str(run)}
                    budget = f"{args.epochs} epochs × batch 512"
                else:
                    train_diffusion(
                        DiffusionTrainArgs(
                            dataset=args.dataset, out=run, method=method, steps=args.steps,
                            preset=preset, batch_size=args.batch_size, save_every=args.steps,
                            log_every=args.steps, device=args.device, warmup_steps=1,
                        ), progress=False,
                    )  # fmt: skip
                    agent_args = {"checkpoint": str(run), "device": args.device}
                    budget = f"{args.steps} steps × batch {args.batch_size}"
                times = np.asarray(_latency(method, spec.env_id, agent_args, args.act_steps))
                row = {
                    "method": method,
                    "preset": preset,
                    "env": spec.env_id,
                    "device": args.device,
                    "threads": args.threads,
                    "timed": budget,
                    "train_samples_per_s": round(_samples_per_s(run), 1),
                    "act_mean_ms": round(1000 * float(times.mean()), 2),
                    "act_max_ms": round(1000 * float(times.max()), 2),
                    "act_median_ms": round(1000 * float(np.median(times)), 2),
                }
                rows.append(row)
                print(json.dumps(row), flush=True)
    print(
        "| method | preset | timed | train samples/s | act mean ms | act median ms | act max ms |"
    )
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['method']} | {r['preset']} | {r['timed']} | {r['train_samples_per_s']} | "
              f"{r['act_mean_ms']} | {r['act_median_ms']} | {r['act_max_ms']} |")  # fmt: skip


if __name__ == "__main__":
    main()
