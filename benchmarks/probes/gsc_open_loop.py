"""GSC's sampler alone: open-loop success of the top-ranked sample vs uniform random parameters,
and the sampling time per plan, on fresh instances of a trained checkpoint's env.

For each instance (reset seeds ``--seed-start …``), BP's abstract search gives the skeleton; the
chain is sampled once (``--samples`` chains, ``--steps`` denoising steps, ``--gamma``) and the
top sample's parameters are executed open loop through the env model (no re-planning), as are
uniform random parameters for the same skeleton. Prints one markdown row.

    uv run python benchmarks/probes/gsc_open_loop.py runs/gsc/ckpt/kinder_StickButton2D-b1-v0 --n 30
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from kinder_bench.baselines.gsc.agent import (
    chain_steps,
    execute_chain,
    find_skeleton,
    load_model,
    random_params,
)
from kinder_bench.baselines.gsc.sampler import sample_chain
from kinder_core import make_object_centric
from kinder_gym.models import model_for


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoint")
    parser.add_argument("--n", type=int, default=30, help="instances")
    parser.add_argument("--seed-start", type=int, default=5000)
    parser.add_argument("--min-skills", type=int, default=1, help="skip shorter skeletons")
    parser.add_argument("--samples", type=int, default=40)
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--gamma", type=float, default=0.5)
    a = parser.parse_args()
    torch.set_num_threads(1)
    model = load_model(a.checkpoint)
    env = make_object_centric(model.env_id)
    planning = model_for(env)
    gsc = rand = n = 0
    seconds: list[float] = []
    lengths: list[int] = []
    seed = a.seed_start
    while n < a.n and seed < a.seed_start + 50 * a.n:
        x0, _ = env.reset(seed=seed)
        sk = find_skeleton(planning, x0, list(model.skills), np.random.default_rng(seed))
        seed += 1
        if sk is None or len(sk) < a.min_skills:
            continue
        start = time.perf_counter()
        samples = sample_chain(
            model, env.box_space.vectorize(x0), chain_steps(sk), a.samples, a.steps, a.gamma, seed
        )
        seconds.append(time.perf_counter() - start)
        gsc += execute_chain(planning, x0, sk, samples.best_params())[0]
        rand += execute_chain(
            planning, x0, sk, random_params(planning, sk, np.random.default_rng(seed))
        )[0]
        lengths.append(len(sk))
        n += 1
    print(
        "| env | instances | skeleton length | GSC top sample | random params | sampling s/plan |"
    )
    print("|---|---|---|---|---|---|")
    print(
        f"| {model.env_id} | {n} | {np.mean(lengths):.1f} | {gsc}/{n} | {rand}/{n} | "
        f"{np.mean(seconds):.2f} |"
    )


if __name__ == "__main__":
    main()
