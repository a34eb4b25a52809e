"""Train and evaluate PPO and SAC on the paper's benchmark envs, one (algorithm, env, seed) cell at
a time, resumably; then write the results table through ``kinder bench report``.

Every cell trains ``kinder train <algo> --env ENV --seed S --steps STEPS`` into
``OUT/train/<algo>/<env>/<reward>/<steps>/seed<S>`` (resuming from its newest checkpoint when
interrupted, skipped when finished), then evaluates that policy with the runner on the episodes
of run seed ``S`` (``--episodes`` of them, the paper's step budget) into ``OUT/eval``: one run per
(algorithm, env, reward, budget), whose checkpoint argument ends in ``seed{seed}``, so the
report aggregates the seeds of a method (mean ± std across seeds). Finished episodes are skipped
on a rerun, so the same command continues where it stopped. ``OUT/cells.json`` records each
cell's status, budget and training throughput; ``--summary`` writes them with the table as
markdown.

    # the issue's core cells (5 seeds × 1M steps × 50 episodes, both algorithms)
    nice -n 10 uv run python benchmarks/experiments/rl_bench.py --algo ppo --algo sac \\
        --env Motion2D-p0 --env StickButton2D-b1 --env BaseMotion3D --seeds 0-4
    # every cell of the paper's eight envs
    nice -n 10 uv run python benchmarks/experiments/rl_bench.py --algo ppo --algo sac --suite paper
    # the appendix's sparse-vs-dense comparison on BaseMotion3D
    nice -n 10 uv run python benchmarks/experiments/rl_bench.py --dense-comparison \\
        --out runs/rl-dense

Cells run one after another in this process (training is bound by the learner, see
``rl_throughput.py``); ``--stop-after-minutes`` stops starting new cells after a time budget.
Changing ``--steps`` starts new cells (the budget is part of the directory and of the run id).
"""

from __future__ import annotations

import argparse
import csv
import datetime
import json
import sys
import time
from pathlib import Path
from typing import Any

from kinder_bench.baselines.rl.train import make_train_args, train
from kinder_bench.evaluation.envs import resolve_env_id, short_id
from kinder_bench.evaluation.protocol import PAPER_ENVS
from kinder_bench.evaluation.results import write_json
from kinder_bench.evaluation.runner import RunConfig, run_benchmark
from kinder_bench.reporting.report import write_report
from kinder_bench.training.checkpoints import list_checkpoints

CELLS_FILE = "cells.json"


def parse_seeds(text: str) -> list[int]:
    """``0-4`` or ``0,2,7``."""
    if "-" in text:
        lo, hi = text.split("-")
        return list(range(int(lo), int(hi) + 1))
    return [int(s) for s in text.split(",")]


def budget_name(steps: int) -> str:
    """``1000000`` → ``1000k``; ``2048`` → ``2048``."""
    return f"{steps // 1000}k" if steps % 1000 == 0 else str(steps)


def label(algo: str, reward: str) -> str:
    """The method's name in the table."""
    return algo if reward == "sparse" else f"{algo}-{reward}"


def train_root(out: Path, algo: str, env_id: str, reward: str, steps: int) -> Path:
    """The directory holding a method's ``seed<S>`` training directories."""
    return out / "train" / algo / short_id(env_id) / reward / budget_name(steps)


def load_cells(out: Path) -> dict[str, dict[str, Any]]:
    path = out / CELLS_FILE
    cells: dict[str, dict[str, Any]] = json.loads(path.read_text()) if path.exists() else {}
    return cells


def run_cell(
    out: Path,
    algo: str,
    env_id: str,
    reward: str,
    seed: int,
    a: argparse.Namespace,
    cells: dict[str, dict[str, Any]],
) -> None:
    key = cell_key(algo, env_id, reward, a.steps, seed)
    root = train_root(out, algo, env_id, reward, a.steps)
    values: dict[str, Any] = {
        "env_id": env_id,
        "seed": seed,
        "total_steps": a.steps,
        "reward": reward,
        "vec_env": a.vec,
        "checkpoint_every": a.checkpoint_every,
    }
    cell = cells.setdefault(key, {"algo": algo, "env_id": env_id, "reward": reward, "seed": seed})
    cell.update(budget_steps=a.steps, status="training")
    write_json(out / CELLS_FILE, cells)
    result = train(algo, make_train_args(algo, values), root / f"seed{seed}", progress=a.progress)
    if result.ran_steps:
        cell["train_wall_s"] = round(cell.get("train_wall_s", 0.0) + result.wall_s, 1)
        cell["last_chunk_steps_per_s"] = round(result.ran_steps / result.wall_s, 1)
    cell.update(trained_steps=result.steps, status="evaluating")
    write_json(out / CELLS_FILE, cells)
    run = RunConfig(
        env_id,
        algo,
        {"checkpoint": str(root / "seed{seed}")},
        seeds=(seed,),
        episodes=a.episodes,
        label=label(algo, reward),
    )
    outcome = run_benchmark([run], out / "eval", executor="inline", progress=a.progress)
    recs = [r for r in outcome.records if r["seed"] == seed]
    cell.update(
        status="done",
        episodes=len(recs),
        success_rate=round(sum(r["success"] for r in recs) / max(len(recs), 1), 4),
        finished_at=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    )
    write_json(out / CELLS_FILE, cells)
    print(f"{key}: {cell}", file=sys.stderr, flush=True)


def cell_key(algo: str, env_id: str, reward: str, steps: int, seed: int) -> str:
    """``ppo/Motion2D-p0/sparse/1000k/seed0``."""
    return f"{algo}/{short_id(env_id)}/{reward}/{budget_name(steps)}/seed{seed}"


def summary_markdown(out: Path, planned: list[str], table: str, command: str) -> str:
    """The results table and one row per planned cell (its status, budget and throughput)."""
    cells = load_cells(out)
    lines = [
        "| cell (algo/env/reward/budget/seed) | status | trained steps | train wall s | "
        "mean steps/s | eval episodes | SR |",
        "|---|---|---|---|---|---|---|",
    ]
    for key in planned + sorted(set(cells) - set(planned)):
        c = cells.get(key)
        if c is None:
            lines.append(f"| {key} | not started | 0 | | | | |")
            continue
        run_dir = train_root(out, c["algo"], c["env_id"], c["reward"], c["budget_steps"])
        run_dir = run_dir / f"seed{c['seed']}"
        steps = c.get("trained_steps")
        if steps is None:  # interrupted while training: the newest checkpoint
            found = list_checkpoints(run_dir)
            steps = found[-1][0] if found else 0
        # Wall time and rate from progress.csv: they cover every chunk of a resumed run.
        wall, rate = "", ""
        if (run_dir / "progress.csv").exists():
            with (run_dir / "progress.csv").open(newline="") as f:
                rows = list(csv.DictReader(f))
            if rows:
                last = rows[-1]
                wall = last["wall_s"]
                rate = f"{int(last['steps']) / max(float(last['wall_s']), 1e-9):.0f}"
        status = "interrupted while training" if c["status"] == "training" else c["status"]
        lines.append(
            f"| {key} | {status} | {steps} | {wall} | {rate} | {c.get('episodes', '')} | "
            f"{c.get('success_rate', '')} |"
        )
    return (
        f"Generated by `{command}`; rerun the same command (without `--report-only`) to "
        "continue.\n\n"
        f"## Results table (`kinder bench report {out / 'eval'}`)\n\n"
        + (table or "(no cell evaluated yet)")
        + "\n\n## Cells\n\n"
        + "\n".join(lines)
        + "\n"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--algo", action="append", choices=["ppo", "sac"])
    p.add_argument("--env", action="append", help="env id (repeatable)")
    p.add_argument("--suite", choices=["paper"], help="the paper's eight envs")
    p.add_argument("--reward", action="append", choices=["sparse", "dense"])
    p.add_argument(
        "--dense-comparison",
        action="store_true",
        help="BaseMotion3D, PPO and SAC, sparse and dense (the appendix's table)",
    )
    p.add_argument("--seeds", default="0-4")
    p.add_argument("--steps", type=int, default=1_000_000, help="training env steps per cell")
    p.add_argument("--episodes", type=int, default=50, help="evaluation episodes per seed")
    p.add_argument("--vec", default="dummy", choices=["dummy", "subproc"])
    p.add_argument("--checkpoint-every", type=int, default=50_000)
    p.add_argument("--out", type=Path, default=Path("runs/rl"))
    p.add_argument("--stop-after-minutes", type=float, default=None)
    p.add_argument("--summary", type=Path, help="write the table and the cells as markdown")
    p.add_argument("--report-only", action="store_true", help="train nothing: write the report")
    p.add_argument("--no-progress", dest="progress", action="store_false")
    a = p.parse_args()
    algos = a.algo or ["ppo", "sac"]
    envs = list(a.env or [])
    rewards = a.reward or ["sparse"]
    if a.suite == "paper":
        envs += list(PAPER_ENVS)
    if a.dense_comparison:
        envs, rewards = ["BaseMotion3D"], ["sparse", "dense"]
    if not envs:
        p.error("give --env, --suite paper or --dense-comparison")
    envs = [resolve_env_id(e) for e in envs]
    a.out.mkdir(parents=True, exist_ok=True)
    plan = [
        (algo, env_id, reward, seed)
        for env_id in envs
        for algo in algos
        for reward in rewards
        for seed in parse_seeds(a.seeds)
    ]
    cells = load_cells(a.out)
    t0 = time.monotonic()
    for algo, env_id, reward, seed in [] if a.report_only else plan:
        if a.stop_after_minutes is not None and (time.monotonic() - t0) / 60 > a.stop_after_minutes:
            print(
                f"stopped after {a.stop_after_minutes} minutes; rerun to continue", file=sys.stderr
            )
            break
        if cells.get(cell_key(algo, env_id, reward, a.steps, seed), {}).get("status") == "done":
            continue  # trained and evaluated in an earlier run
        run_cell(a.out, algo, env_id, reward, seed, a, cells)
    table = ""
    if (a.out / "eval" / "results.jsonl").exists():
        table, _ = write_report([a.out / "eval"])
        print(table)
    if a.summary:
        argv = [x for x in sys.argv[1:] if x != "--report-only"]
        command = "python benchmarks/experiments/rl_bench.py " + " ".join(argv)
        planned = [cell_key(al, e, r, a.steps, s) for al, e, r, s in plan]
        a.summary.write_text(summary_markdown(a.out, planned, table, command))
        print(f"wrote {a.summary}", file=sys.stderr)


if __name__ == "__main__":
    main()
