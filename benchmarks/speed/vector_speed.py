"""Steps/s of the batched Kinematic2D vector env, beside the single env and upstream's.

For each id, the batched env (``gymnasium.make_vec(id, N, vectorization_mode=
"vector_entry_point")``) is stepped with seeded uniform random actions (autoresets included) for
each N; steps/s counts sub-env steps (N per call). Beside it: our single env and upstream
``kindergarden`` 0.2.5's single env, measured by ``env_speed.py`` (random actions, resets on
episode end) under each interpreter, as ``upstream.py`` does. Run it on one core::

    taskset -c 1 nice -n 10 .venv/bin/python benchmarks/speed/vector_speed.py \\
        --out benchmarks/results/kinematic2d_batched.json

``--ppo`` instead times PPO training (env steps/s of the whole ``train`` loop, SB3) with the
training stack's ``DummyVecEnv`` (8 envs × 256 steps per rollout, the paper's settings) and with
``--vec-env batched`` at the same rollout size, network and update (``n_envs × n_steps`` = 2048,
minibatch 64, 10 epochs), and with more envs per rollout.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from upstream import ensure_upstream_venv, run_speed

import kinder_core

IDS = [
    "kinder/Motion2D-p0-v0",
    "kinder/Obstruction2D-o2-v0",
    "kinder/StickButton2D-b1-v0",
    "kinder/ClutteredRetrieval2D-o25-v0",
    "kinder/ClutteredStorage2D-b15-v0",
    "kinder/PushPullHook2D-v0",
]
NS = [1, 16, 256, 1024, 4096]


def batched_rate(env_id: str, n: int, seconds: float, seed: int = 1000) -> dict[str, Any]:
    """Sub-env steps/s of the batched env with ``n`` sub-envs (random actions, autoresets)."""
    kinder_core.registration.ensure_registered(env_id)
    env = gymnasium.make_vec(env_id, n, vectorization_mode="vector_entry_point")
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    space = env.single_action_space
    actions = [rng.uniform(space.low, space.high, (n, 5)).astype(np.float32) for _ in range(16)]
    for a in actions[:3]:  # warm-up
        env.step(a)
    calls = 0
    t0, c0 = time.perf_counter(), time.process_time()
    while calls < 5 or time.perf_counter() - t0 < seconds:
        env.step(actions[calls % len(actions)])
        calls += 1
    dt, cpu = time.perf_counter() - t0, time.process_time() - c0
    env.close()
    return {
        "env": env_id,
        "n": n,
        "steps_per_s": calls * n / dt,
        "steps_per_cpu_s": calls * n / cpu,
        "ms_per_call": dt / calls * 1e3,
    }


def speed_table(a: argparse.Namespace) -> dict[str, Any]:
    upstream_py = None if a.no_upstream else ensure_upstream_venv()
    speed_args = argparse.Namespace(steps=a.single_steps, seconds=a.seconds * 2, render=False)
    rows: dict[str, Any] = {}
    for env_id in a.ids:
        single = run_speed(sys.executable, env_id, speed_args, "{}")
        up = (
            run_speed(upstream_py, env_id, speed_args, "{}")
            if upstream_py
            else {"error": "not measured (--no-upstream)"}
        )
        batched = [batched_rate(env_id, n, a.seconds) for n in a.n]
        rows[env_id] = {"single": single, "upstream": up, "batched": batched}
        print(json.dumps(rows[env_id]), flush=True)
    return rows


def markdown(rows: dict[str, Any], ns: list[int], key: str = "steps_per_s") -> str:
    """The table of one rate (``steps_per_s``: wall clock; ``steps_per_cpu_s``: process CPU
    time) of the batched env per N, beside the single envs (wall clock)."""
    head = " | ".join(f"N={n}" for n in ns)
    lines = [
        f"| id | upstream 0.2.5 single | ours single | {head} | best / ours single | "
        f"best / upstream |",
        "|---|---|---|" + "---|" * len(ns) + "---|---|",
    ]
    for env_id, r in rows.items():
        up = r["upstream"].get("steps_per_s")
        ours = r["single"].get("steps_per_s")
        rates = [b[key] for b in r["batched"]]
        best = max(rates)
        cells = " | ".join(f"{v:,.0f}" for v in rates)
        ratio_up = f"{best / up:,.0f}×" if up else "n/a"
        ratio_ours = f"{best / ours:,.0f}×" if ours else "n/a"
        up_s = f"{up:,.0f}" if up else r["upstream"].get("error", "n/a")[:40]
        ours_s = f"{ours:,.0f}" if ours else "n/a"
        lines.append(f"| {env_id} | {up_s} | {ours_s} | {cells} | {ratio_ours} | {ratio_up} |")
    return "\n".join(lines)


def ppo_rate(env: str, vec: str, n_envs: int, n_steps: int, steps: int) -> dict[str, Any]:
    """Env steps/s of a PPO training run (model construction excluded)."""
    from kinder_bench.baselines.rl.train import make_train_args, train

    values: dict[str, object] = {
        "env_id": env,
        "vec_env": vec,
        "n_envs": n_envs,
        "n_steps": n_steps,
        "total_steps": steps,
        "checkpoint_every": 10**9,
        "log_every": 10**9,
        "seed": 1000,
    }
    args = make_train_args("ppo", values)
    env_rate = env_only_rate(args, steps)
    with tempfile.TemporaryDirectory() as tmp:
        result = train("ppo", args, tmp, progress=False)
    rate = result.ran_steps / result.wall_s
    return {
        "env": env,
        "vec_env": vec,
        "n_envs": n_envs,
        "n_steps": n_steps,
        "steps": result.ran_steps,
        "train_steps_per_s": rate,
        "env_only_steps_per_s": env_rate,
        # Seconds per env step spent outside the env (the learner and SB3's loop).
        "learner_share": 1.0 - rate / env_rate,
    }


def env_only_rate(args: Any, steps: int) -> float:
    """Random-action steps/s of the training vector env of ``args`` (no learner)."""
    from kinder_bench.baselines.rl.train import make_venv, resolve

    venv = make_venv("ppo", args, resolve("ppo", args))
    try:
        venv.seed(1000)
        venv.reset()
        rng = np.random.default_rng(1000)
        shape = (venv.num_envs, *venv.action_space.shape)  # type: ignore[misc]
        actions = [rng.uniform(-1, 1, size=shape).astype(np.float32) for _ in range(16)]
        t0 = time.perf_counter()
        n = k = 0
        while n < steps:
            venv.step(actions[k % 16])
            n += venv.num_envs
            k += 1
        return n / (time.perf_counter() - t0)
    finally:
        venv.close()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("ids", nargs="*", default=IDS)
    p.add_argument("--n", type=int, action="append", help=f"batch sizes (default {NS})")
    p.add_argument("--seconds", type=float, default=3.0, help="stepping time per measurement")
    p.add_argument("--single-steps", type=int, default=20_000)
    p.add_argument("--ppo", action="store_true", help="time PPO training instead")
    p.add_argument("--ppo-env", default="Obstruction2D-o2")
    p.add_argument("--ppo-steps", type=int, default=16_384)
    p.add_argument("--out", type=Path, help="write the JSON records here")
    p.add_argument(
        "--no-upstream",
        action="store_true",
        help="leave out upstream's single env (a machine without the upstream venv)",
    )
    a = p.parse_args()
    a.n = a.n or NS
    if a.ppo:
        runs = [
            ppo_rate(a.ppo_env, vec, n_envs, n_steps, a.ppo_steps)
            for vec, n_envs, n_steps in [
                ("dummy", 8, 256),
                ("batched", 8, 256),
                ("batched", 64, 32),
                ("batched", 256, 8),
            ]
        ]
        for r in runs:
            print(json.dumps(r), flush=True)
        print(
            "| vec env | n_envs × n_steps | train env steps/s | env only steps/s | learner share |"
        )
        print("|---|---|---|---|---|")
        for r in runs:
            print(
                f"| {r['vec_env']} | {r['n_envs']} × {r['n_steps']} | "
                f"{r['train_steps_per_s']:,.0f} | {r['env_only_steps_per_s']:,.0f} | "
                f"{r['learner_share']:.0%} |"
            )
        result: Any = runs
    else:
        rows = speed_table(a)
        print(markdown(rows, a.n))
        print()
        print(markdown(rows, a.n, "steps_per_cpu_s"))
        result = rows
    if a.out:
        a.out.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
