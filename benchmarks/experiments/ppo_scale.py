"""PPO at 1M, 10M and 100M env steps on batched Kinematic2D envs: does RL fail for want of samples?

The paper trains PPO for 1M env steps and finds it fails on most envs. Whether that is the method
or the budget can be asked once the env is cheap: the batched Kinematic2D vector env steps
hundreds of thousands of sub-envs per second on one core, and a GPU learner updates on large
batches. One run per (env, seed) trains to ``--steps`` with

* ``kinder train ppo --vec-env batched`` (the same env, reward, episode limit, observation and
  reward normalisation and 4 × 128 tanh networks as the paper's PPO), learner on ``--device``;
* the update scaled to thousands of sub-envs (``HP``): 4096 sub-envs × 16 steps per rollout,
  2 minibatches of 32768, 4 epochs, a constant learning rate of 3e-4 (the paper: 8 × 256 steps,
  32 minibatches of 64, 10 epochs, the learning rate annealed to 0 over 1M steps);
* checkpoints kept at every budget of ``BUDGETS`` (``keep_steps``): with a constant learning
  rate the policy kept at 1M steps is the one a 1M-step run ends with, so one run serves all
  three budgets;
* ``max_wall_s``: a run that cannot reach ``--steps`` in the time stops at an update boundary
  with a checkpoint; its furthest budget is then the steps it reached, named as such.

Each kept policy is evaluated by the runner at the paper's protocol (run seeds 0–4 × 50
episodes; training seed ``s`` is evaluated on run seed ``s``), labelled ``ppo-batched-<budget>``
with its training budget, so the results page shows it as a variant beside the paper's PPO.

Usage (``train`` on a machine with a GPU and many cores; ``evaluate`` and ``report`` anywhere)::

    python benchmarks/experiments/ppo_scale.py train --out runs/ppo_scale --device cuda \\
        --max-wall-s 480
    python benchmarks/experiments/ppo_scale.py evaluate --out runs/ppo_scale --workers 2
    python benchmarks/experiments/ppo_scale.py report --out runs/ppo_scale

``train`` starts every (env, seed) run at once, each pinned to its own core (``--jobs`` at most);
rerunning resumes each run from its newest checkpoint.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from kinder_bench.training.checkpoints import (
    METADATA_FILE,
    checkpoint_name,
    list_checkpoints,
    read_checkpoint,
)

ENVS = ("StickButton2D-b1", "Obstruction2D-o2", "ClutteredRetrieval2D-o1")
BUDGETS = (1_000_000, 10_000_000, 100_000_000)
N_ENVS = 4096
#: The update at scale (see the module docstring); every other PPO argument is the paper's.
HP: dict[str, Any] = {
    "n_steps": 16,
    "batch_size": 32768,
    "n_epochs": 4,
    "anneal_lr": False,
    "learning_rate": 3e-4,
}
ROLLOUT = N_ENVS * HP["n_steps"]
RESULTS = Path(__file__).resolve().parents[1] / "results"


def budget_name(steps: int) -> str:
    """``1M``, ``10M``, ``100M``, ``37.4M``."""
    millions = steps / 1e6
    return f"{millions:.0f}M" if millions == round(millions) else f"{millions:.1f}M"


def kept_step(budget: int) -> int:
    """The env steps of the checkpoint kept for ``budget``: the first update boundary at or past
    it."""
    return math.ceil(budget / ROLLOUT) * ROLLOUT


def run_dir(out: Path, env: str, seed: int) -> Path:
    return out / "train" / env / f"seed{seed}"


def parse_seeds(text: str) -> list[int]:
    if "-" in text:
        lo, hi = text.split("-")
        return list(range(int(lo), int(hi) + 1))
    return [int(s) for s in text.split(",")]


def train(args: argparse.Namespace) -> None:
    jobs = [(env, seed) for env in args.envs for seed in parse_seeds(args.seeds)]
    cores = sorted(os.sched_getaffinity(0))
    width = min(args.jobs or len(cores), len(jobs))
    hp = {**HP, "keep_steps": list(BUDGETS), "device": args.device, "log_every": 1_000_000}
    if args.max_wall_s:
        hp["max_wall_s"] = args.max_wall_s
    env_vars = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    running: list[tuple[subprocess.Popen[bytes], str, int, int]] = []
    pending = list(jobs)
    free = list(cores[:width])
    t0 = time.perf_counter()
    while pending or running:
        while pending and free:
            env, seed = pending.pop(0)
            core = free.pop(0)
            out = run_dir(args.out, env, seed)
            out.mkdir(parents=True, exist_ok=True)
            cmd = [
                *("taskset", "-c", str(core), sys.executable, "-m", "kinder_bench", "train"),
                *("ppo", "--env", env, "--seed", str(seed), "--steps", str(args.steps)),
                *("--n-envs", str(N_ENVS), "--vec-env", "batched", "--out", str(out)),
                *("--checkpoint-every", "5000000", "--no-progress"),
                *(x for k, v in hp.items() for x in ("--hp", f"{k}={hp_text(v)}")),
            ]
            log = (out / "train.log").open("ab")
            proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env_vars)
            running.append((proc, env, seed, core))
            print(f"[{time.perf_counter() - t0:6.0f}s] start {env} seed {seed} on core {core}")
        time.sleep(2)
        for item in list(running):
            proc, env, seed, core = item
            if proc.poll() is not None:
                running.remove(item)
                free.append(core)
                print(f"[{time.perf_counter() - t0:6.0f}s] {env} seed {seed}: rc {proc.returncode}")
    print(f"all {len(jobs)} runs ended in {time.perf_counter() - t0:.0f} s")


def hp_text(value: Any) -> str:
    """A ``--hp`` value: strings as they are, everything else as JSON."""
    return value if isinstance(value, str) else json.dumps(value)


def reached(out: Path, env: str, seeds: list[int]) -> int:
    """The fewest env steps any seed's newest checkpoint holds (0: a seed has none)."""
    least = None
    for seed in seeds:
        steps = [s for s, _ in list_checkpoints(run_dir(out, env, seed))]
        least = min(least, max(steps, default=0)) if least is not None else max(steps, default=0)
    return least or 0


def evaluations(out: Path, seeds: list[int]) -> list[tuple[str, str, str, str]]:
    """(env, checkpoint template, label budget, training text) to evaluate: each budget every
    seed reached, and, when the largest budget was not reached, each seed's newest checkpoint
    (its furthest budget, which differs between seeds by a few rollouts)."""
    todo = []
    for env in ENVS:
        top = reached(out, env, seeds)
        template = str(out / "train" / env / "seed{seed}")
        for budget in BUDGETS:
            step = kept_step(budget)
            if step <= top:
                ckpt = f"{template}/checkpoints/{checkpoint_name(step)}"
                todo.append((env, ckpt, budget_name(budget), training_text(step)))
        if top and top < kept_step(BUDGETS[-1]) and all(kept_step(b) != top for b in BUDGETS):
            most = max(reached(out, env, [seed]) for seed in seeds)
            todo.append((env, template, "max", training_text(top, most)))
    return todo


def evaluate(args: argparse.Namespace) -> None:
    seeds = parse_seeds(args.seeds)
    suffix = "" if args.episodes == 50 else f"-{len(seeds)}x{args.episodes}"
    for env, ckpt, name, training in evaluations(args.out, seeds):
        if (args.only and name not in args.only) or (args.envs and env not in args.envs):
            continue
        cmd = [
            *(sys.executable, "-m", "kinder_bench", "bench", "run", "--env", env, "--agent", "ppo"),
            *("--arg", f"checkpoint={ckpt}", "--seeds", args.seeds),
            *("--episodes", str(args.episodes)),
            *("--label", f"ppo-batched-{name}", "--training", training),
            *("--executor", "process", "--workers", str(args.workers), "--record-episodes", "0"),
            *("--out", str(args.out / "eval" / f"{env}-{name}{suffix}"), "--no-progress"),
        ]
        print(" ".join(cmd), flush=True)
        subprocess.run(cmd, check=True)


def training_text(step: int, most: int | None = None) -> str:
    """The training budget in words, as the results page shows it."""
    steps = f"{budget_name(step)} env steps ({step:,})"
    if most is not None and most != step:
        steps = f"{budget_name(step)}-{budget_name(most)} env steps ({step:,}-{most:,}, per seed)"
    return (
        f"{steps}, batched {N_ENVS} envs x {HP['n_steps']} steps, "
        f"2 x {HP['batch_size']} minibatches x {HP['n_epochs']} epochs, constant lr "
        f"{HP['learning_rate']}"
    )


def report(args: argparse.Namespace) -> None:
    rows: list[dict[str, str]] = []
    for path in sorted((args.out / "eval").glob("*/summary.csv")):
        with path.open() as f:
            rows.extend(csv.DictReader(f))
    if not rows:
        raise SystemExit(f"no evaluations under {args.out / 'eval'}: run `evaluate` first")
    dest = args.results / "ppo_scale_summary.csv"
    tmp = dest.with_suffix(".tmp")
    with tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(dest)
    print(f"wrote {dest} ({len(rows)} rows)")
    plot_curves(args.out, parse_seeds(args.seeds), args.results / "ppo_scale_curves.png")


def plot_curves(out: Path, seeds: list[int], dest: Path, min_episodes: int = 100) -> None:
    """Training success rate (of the episodes that ended in each logging interval, where at least
    ``min_episodes`` ended) against env steps, one panel per env."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(ENVS), figsize=(4.2 * len(ENVS), 3.2), sharey=True)
    for ax, env in zip(axes, ENVS):
        ended = 0
        for seed in seeds:
            progress = run_dir(out, env, seed) / "progress.csv"
            if not progress.is_file():
                continue
            pts, before = [], 0
            with progress.open() as f:
                for r in csv.DictReader(f):
                    n, before = int(r["episodes"]) - before, int(r["episodes"])
                    if n >= min_episodes and r.get("success_rate"):
                        pts.append((int(r["steps"]), float(r["success_rate"])))
            ended += before
            if pts:
                ax.plot(*zip(*pts), label=f"seed {seed}", lw=1, marker=".")
        if not ax.lines:
            ax.text(
                0.5,
                0.5,
                f"{ended:,} training episodes ended\n"
                "(the episode limit is reached\nonce per sub-env)",
                ha="center",
                va="center",
                transform=ax.transAxes,
                fontsize=8,
            )
        ax.set_xscale("log")
        ax.set_xlim(5e5, 2e8)
        ax.set_title(env)
        ax.set_xlabel("env steps")
        for budget in BUDGETS:
            ax.axvline(budget, color="grey", lw=0.5, ls=":")
    axes[0].set_ylabel("training success rate")
    axes[0].set_ylim(-0.02, 1.02)
    for ax in axes:
        if ax.lines:
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(dest, dpi=110)
    print(f"wrote {dest}")


def pack(args: argparse.Namespace) -> None:
    """One ``<env>.tgz`` per env under ``--dest`` with what evaluation and the report need: each
    run's config, progress and log, and its kept and newest checkpoints with the optimizer state
    left out (about a third of the size; such a checkpoint evaluates but cannot resume)."""
    import tarfile

    import torch

    from kinder_bench.baselines.rl.train import KinderPPO

    args.dest.mkdir(parents=True, exist_ok=True)
    for env in ENVS:
        root = args.out / "train" / env
        if not root.is_dir():
            continue
        with tarfile.open(args.dest / f"{env}.tgz", "w:gz") as tar:
            for run in sorted(root.glob("seed*")):
                for name in ("config.json", "progress.csv", "train.log"):
                    if (run / name).is_file():
                        tar.add(run / name, str((run / name).relative_to(args.out)))
                ckpts = [c for _, c in list_checkpoints(run)]
                for c in ckpts:
                    if not read_checkpoint(c).kept and c != ckpts[-1]:
                        continue
                    model = KinderPPO.load(c / "model.zip", device="cpu")
                    policy = model.policy
                    policy.optimizer = torch.optim.Adam(policy.parameters(), lr=3e-4)
                    model.save(c / "model.zip")
                    meta = json.loads((c / METADATA_FILE).read_text())
                    meta["info"]["optimizer_state"] = "left out"
                    (c / METADATA_FILE).write_text(json.dumps(meta, indent=2, sort_keys=True))
                    tar.add(c, str(c.relative_to(args.out)))
        size = (args.dest / f"{env}.tgz").stat().st_size
        print(f"wrote {args.dest / f'{env}.tgz'} ({size / 1e6:.1f} MB)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    for name in ("train", "evaluate", "report", "pack"):
        p = sub.add_parser(name)
        p.add_argument("--out", type=Path, default=Path("runs/ppo_scale"))
        p.add_argument("--seeds", default="0-4")
        if name == "train":
            p.add_argument("--envs", nargs="+", default=list(ENVS))
            p.add_argument("--steps", type=int, default=BUDGETS[-1])
            p.add_argument("--device", default="cuda")
            p.add_argument("--max-wall-s", type=float, default=None)
            p.add_argument("--jobs", type=int, default=None)
        if name == "evaluate":
            p.add_argument("--workers", type=int, default=2)
            p.add_argument("--only", nargs="*", help="budget names to evaluate (1M 10M max)")
            p.add_argument("--envs", nargs="*", help="envs to evaluate (default: all)")
            p.add_argument(
                "--episodes", type=int, default=50, help="per seed (the paper's protocol: 50)"
            )
        if name == "report":
            p.add_argument("--results", type=Path, default=RESULTS)
        if name == "pack":
            p.add_argument("--dest", type=Path, required=True)
    args = parser.parse_args()
    {"train": train, "evaluate": evaluate, "report": report, "pack": pack}[args.cmd](args)


if __name__ == "__main__":
    main()
