"""Training throughput of the RL baselines (env steps/s), and what bounds it.

For each (algorithm, env, vector-env kind, torch threads) this trains a fresh policy for
``--steps`` env steps in a temporary directory (checkpointing only at the end) and reports the
steps/s of ``train`` (model construction excluded). Next to it, ``env only`` is the same vector env
stepped with random actions (no learner): the ceiling the env sets. Prints one JSON line per
measurement, then a markdown table.

    nice -n 10 uv run python benchmarks/speed/rl_throughput.py --algo ppo --env Motion2D-p0 \\
        --vec dummy --vec subproc --threads 1 --threads 0 --steps 16384

``--threads 0`` means torch's default thread count.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time

import numpy as np
import torch

from kinder_bench.baselines.rl.train import make_train_args, make_venv, resolve, train


def env_only_rate(algo: str, env: str, vec: str, steps: int) -> float:
    """Random-action steps/s of the training vector env (no learner)."""
    args = make_train_args(algo, {"env_id": env, "vec_env": vec})
    res = resolve(algo, args)
    venv = make_venv(algo, args, res)
    try:
        venv.seed(0)
        venv.reset()
        rng = np.random.default_rng(0)
        shape = (venv.num_envs, *venv.action_space.shape)  # type: ignore[misc]
        t0 = time.perf_counter()
        n = 0
        while n < steps:
            venv.step(rng.uniform(-1, 1, size=shape).astype(np.float32))
            n += venv.num_envs
        return n / (time.perf_counter() - t0)
    finally:
        venv.close()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--algo", action="append", choices=["ppo", "sac"])
    p.add_argument("--env", action="append")
    p.add_argument("--vec", action="append", choices=["dummy", "subproc"])
    p.add_argument("--threads", action="append", type=int)
    p.add_argument("--steps", type=int, default=16384)
    p.add_argument("--learning-starts", type=int, default=2048, help="SAC only")
    a = p.parse_args()
    default_threads = torch.get_num_threads()
    rows = []
    for algo in a.algo or ["ppo"]:
        for env in a.env or ["Motion2D-p0"]:
            for vec in a.vec or ["dummy"]:
                env_rate = env_only_rate(algo, env, vec, a.steps)
                for threads in a.threads or [1]:
                    values: dict[str, object] = {
                        "env_id": env,
                        "vec_env": vec,
                        "total_steps": a.steps,
                        "checkpoint_every": 10**9,
                        "log_every": 10**9,
                        "torch_threads": threads or default_threads,
                    }
                    if algo == "sac":
                        values["learning_starts"] = a.learning_starts
                        values["buffer_size"] = max(a.steps, 10_000)
                    args = make_train_args(algo, values)
                    with tempfile.TemporaryDirectory() as tmp:
                        result = train(algo, args, tmp, progress=False)
                    row = {
                        "algo": algo,
                        "env": env,
                        "vec_env": vec,
                        "n_envs": resolve(algo, args).n_envs,
                        "torch_threads": args.torch_threads,
                        "steps": result.ran_steps,
                        "train_steps_per_s": round(result.ran_steps / result.wall_s, 1),
                        "env_only_steps_per_s": round(env_rate, 1),
                        **({"learning_starts": a.learning_starts} if algo == "sac" else {}),
                    }
                    rows.append(row)
                    print(json.dumps(row), flush=True)
    torch.set_num_threads(default_threads)
    print()
    print("| algo | env | vec env | n_envs | torch threads | train steps/s | env only steps/s |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['algo']} | {r['env']} | {r['vec_env']} | {r['n_envs']} | "
            f"{r['torch_threads']} | {r['train_steps_per_s']} | {r['env_only_steps_per_s']} |"
        )


if __name__ == "__main__":
    main()
