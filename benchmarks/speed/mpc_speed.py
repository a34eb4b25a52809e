"""MPC (or MBRL) at the paper's settings: per-episode inference time with the plain rollout loop
and with the fast rollouts (``MPCArgs.batched``), on development seeds, beside the paper's
Inf-Time.

Every episode runs once per mode from the same env seed and agent seed (the runner's seeding of
run seed ``--seed``), so the two modes must take the same actions; the script checks that and
records a hash of each episode's actions. The agent's arguments and the step budget are the
paper's for each env (``kinder_bench/data/paper_settings.csv``: upstream's per-env
``replan_interval``); ``--max-steps`` cuts long episodes to a fixed number of steps (the time is
then per that many steps, and the table says so).

    uv run python benchmarks/speed/mpc_speed.py --env Motion2D-p0 --episodes 2 --seed 1000
    uv run python benchmarks/speed/mpc_speed.py --env Shelf3D-o1 --episodes 1 --max-steps 100
    uv run python benchmarks/speed/mpc_speed.py --agent mbrl --checkpoint RUN --env Motion2D-p0 \
        --episodes 1 --max-steps 20
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from kinder_bench.agents import make_agent
from kinder_bench.baselines.mpc import MPCAgent
from kinder_bench.evaluation.envs import make_env, resolve_env_id, short_id
from kinder_bench.evaluation.protocol import PAPER_MAX_STEPS
from kinder_bench.evaluation.runner import agent_seed, episode_seeds
from kinder_bench.reporting.paper import paper_settings

PAPER_RESULTS = (
    Path(__file__).resolve().parents[2]
    / "packages/kinder-bench/src/kinder_bench/data/paper_results.csv"
)


def paper_inf_time(env_id: str, agent: str) -> str:
    """The paper's Inf-Time of ``agent`` on ``env_id`` (``mean ± std`` as printed, or ``--``)."""
    lines = [ln for ln in PAPER_RESULTS.read_text().splitlines() if not ln.startswith("#")]
    for row in csv.DictReader(lines):
        if row["env_id"] == env_id and row["agent"] == agent and row["metric"] == "Inf-Time":
            return "--" if row["mean"] == "--" else f"{row['mean']} ± {row['std']}"
    return "--"


def episode(
    agent_name: str,
    extra: dict[str, Any],
    env_id: str,
    seed: int,
    index: int,
    batched: bool,
    cap: int | None,
) -> dict[str, Any]:
    """One episode of the agent at the paper's settings (plus ``extra`` arguments); its
    inference time, steps and action hash."""
    settings = paper_settings(agent_name, env_id)
    budget = int(settings.get("max_steps", PAPER_MAX_STEPS[env_id]))
    steps = min(budget, cap) if cap else budget
    args = {k: v for k, v in settings.items() if k not in ("max_steps", "training")}
    env = make_env(env_id, max_steps=budget)
    agent = make_agent(
        agent_name, env, {**args, **extra, "batched": batched}, seed=agent_seed(seed, index)
    )
    assert isinstance(agent, MPCAgent)
    obs, info = env.reset(seed=episode_seeds(seed, index + 1)[index])
    digest = hashlib.sha256()
    t0 = time.perf_counter()
    agent.reset(obs, info)
    think = time.perf_counter() - t0
    success, n = False, 0
    while n < steps:
        n += 1
        t0 = time.perf_counter()
        action = agent.act(obs)
        think += time.perf_counter() - t0
        digest.update(np.asarray(action, dtype=np.float64).tobytes())
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            success = bool(terminated)
            break
    env.close()
    return {
        "agent": agent_name,
        "env_id": env_id,
        "mode": "fast" if batched else "plain",
        "fast_model": type(agent._fast).__name__ if agent._fast is not None else "none",
        "seed": seed,
        "episode": index,
        "steps": n,
        "step_cap": steps if steps < budget else None,
        "success": success,
        "inference_s": round(think, 3),
        "solves": agent.num_solves,
        "model_steps": agent.num_model_steps,
        "actions_sha256": digest.hexdigest()[:16],
        "replan_interval": args.get("replan_interval", 1),
    }


def table(rows: list[dict[str, Any]]) -> str:
    """Markdown: per (agent, env, step cap, machine) and mode, the mean inference time per
    episode, beside the paper's Inf-Time."""
    out = [
        "| agent | env | machine | mode (fast model) | episodes | steps (mean) | solves (mean) "
        "| inference s / episode | paper Inf-Time (s) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    groups: dict[tuple[Any, ...], list[dict[str, Any]]] = {}
    for r in rows:
        key = (r.get("agent", "mpc"), r["env_id"], r["machine"], r["step_cap"], r["mode"])
        groups.setdefault(key, []).append(r)
    for (agent, env_id, machine, cap, mode), rs in groups.items():
        t = np.array([r["inference_s"] for r in rs])
        steps = f"{np.mean([r['steps'] for r in rs]):.0f}" + (f" (first {cap})" if cap else "")
        out.append(
            f"| {agent} | {short_id(env_id)} | {machine} | {mode} ({rs[0]['fast_model']}) | "
            f"{len(rs)} | {steps} | {np.mean([r['solves'] for r in rs]):.0f} | "
            f"{t.mean():.2f} ± {t.std():.2f} | {paper_inf_time(env_id, agent)} |"
        )
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env", action="append", default=[], help="Env id(s).")
    p.add_argument("--table", type=Path, default=None, help="Only print the table of a JSONL.")
    p.add_argument("--agent", default="mpc", choices=["mpc", "mbrl"], help="mpc or mbrl.")
    p.add_argument("--checkpoint", default="", help="MBRL: a `kinder train mbrl` run.")
    p.add_argument("--episodes", type=int, default=2, help="Episodes per env and mode.")
    p.add_argument("--seed", type=int, default=1000, help="Run seed (development: >= 1000).")
    p.add_argument("--max-steps", type=int, default=None, help="Cut episodes at this many steps.")
    p.add_argument("--modes", default="plain,fast", help="plain, fast or both.")
    p.add_argument("--out", type=Path, default=None, help="Append the records to this JSONL.")
    args = p.parse_args(argv)
    if args.table is not None:
        print(table([json.loads(line) for line in args.table.read_text().splitlines() if line]))
        return 0
    if not args.env:
        p.error("give at least one --env (or --table JSONL)")
    if args.seed < 1000:
        p.error("--seed: evaluation seeds (0-4) are for the results table; use >= 1000")
    modes = [m.strip() for m in args.modes.split(",")]
    if not set(modes) <= {"plain", "fast"}:
        p.error(f"--modes {args.modes!r}: expected plain, fast or plain,fast")
    extra = {"checkpoint": args.checkpoint} if args.agent == "mbrl" else {}
    machine = f"{platform.node()} ({os.cpu_count()} CPUs)"
    rows = []
    for env in args.env:
        env_id = resolve_env_id(env)
        for i in range(args.episodes):
            recs = [
                episode(args.agent, extra, env_id, args.seed, i, m == "fast", args.max_steps)
                for m in modes
            ]
            if len({r["actions_sha256"] for r in recs}) != 1:
                print(f"MISMATCH: {env_id} episode {i}: {recs}", file=sys.stderr)
                return 1
            for r in recs:
                r["machine"] = machine
                print(json.dumps(r), flush=True)
                if args.out:
                    with args.out.open("a") as f:
                        f.write(json.dumps(r) + "\n")
            rows += recs
    print()
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
