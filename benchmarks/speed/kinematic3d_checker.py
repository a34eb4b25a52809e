"""CPU milliseconds per collision check of the Kinematic3D motion planners' checker.

The models' motion planners (``kinder_gym.models.kinematic3d.tidybot.ConfigChecker``) test each
robot configuration in the env's pybullet scene; BP's planning on the larger KinematicShelf3D
variants spends most of its time there. This script checks ``--checks`` random configurations
(base within ±0.8 m and ±π of the reset's, arm joints within ±2 rad; seeded, so every run checks
the same ones) around the reset of a development seed, and prints the CPU time per check and a
digest of the verdicts: two versions of the code answer alike when their digests match.

Usage:
    python benchmarks/speed/kinematic3d_checker.py --env kinder/KinematicShelf3D-o10-v0 \
        [--seed 1000] [--checks 400]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time

import numpy as np

from kinder_bench.evaluation.protocol import DEVELOPMENT_SEED
from kinder_core import make_object_centric
from kinder_gym.models.kinematic3d.tidybot import ConfigChecker

#: Half-widths of the sampled box around the reset configuration (base x, y, yaw; 7 arm joints).
SPREAD = np.array([0.8, 0.8, np.pi, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0])


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="kinder/KinematicShelf3D-o10-v0")
    parser.add_argument("--seed", type=int, default=DEVELOPMENT_SEED, help="the env's reset seed")
    parser.add_argument("--checks", type=int, default=400)
    args = parser.parse_args(argv)
    env = make_object_centric(args.env)
    state, _ = env.reset(seed=args.seed)
    robot = env.robot  # type: ignore[attr-defined]
    q0 = np.asarray(state[robot][:10], dtype=np.float64)
    rng = np.random.default_rng(0)
    configs = [q0 + rng.uniform(-1.0, 1.0, 10) * SPREAD for _ in range(args.checks)]
    checker = ConfigChecker(env, state)
    start = time.process_time()
    verdicts = [checker(q) for q in configs]
    cpu = time.process_time() - start
    env.close()
    print(
        json.dumps(
            {
                "env": args.env,
                "seed": args.seed,
                "checks": args.checks,
                "valid": sum(verdicts),
                "cpu_ms_per_check": round(1000.0 * cpu / args.checks, 3),
                "verdict_digest": hashlib.sha256(bytes(verdicts)).hexdigest()[:12],
            }
        )
    )


if __name__ == "__main__":
    main()
