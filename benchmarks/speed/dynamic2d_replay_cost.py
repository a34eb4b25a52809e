"""What exact replay costs in the Dynamic2D envs: per action, the time to build the Chipmunk space
from the state (and take it apart), the priming substep (``warm_start``), and the whole transition.

Usage:
    uv run python benchmarks/speed/dynamic2d_replay_cost.py \
        [--out benchmarks/results/dynamic2d_replay_cost.json]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import kinder_core
from kinder_garden2d.dynamic2d.physics import Simulation

IDS = [
    "kinder/DynObstruction2D-o1-v0",
    "kinder/DynPushT2D-t1-v0",
    "kinder/DynPushPullHook2D-o5-v0",
    "kinder/DynScoopPour2D-o10-v0",
    "kinder/DynScoopPour2D-o50-v0",
]


def measure(env_id: str, n: int = 300) -> dict[str, float | str]:
    env = kinder_core.make_object_centric(env_id)
    u = env.unwrapped
    s, _ = env.reset(seed=0)
    env.action_space.seed(0)
    states = []
    for _ in range(n):
        states.append(s)
        s, *_ = env.step(env.action_space.sample())
    u.scene.index(states[0])

    def per_call(fn) -> float:  # type: ignore[no-untyped-def]
        best = float("inf")
        for _ in range(5):  # best of 5: the machine is shared
            t0 = time.perf_counter()
            for st in states:
                fn(st)
            best = min(best, (time.perf_counter() - t0) / len(states))
        return best

    def build(st) -> None:  # type: ignore[no-untyped-def]
        Simulation(u.scene, st.data.copy()).close()

    def build_warm(st) -> None:  # type: ignore[no-untyped-def]
        with Simulation(u.scene, st.data.copy()) as sim:
            sim.warm_start()

    a = np.zeros(env.action_space.shape)
    build_s = per_call(build)
    warm_s = max(0.0, per_call(build_warm) - build_s)
    step_s = per_call(lambda st: env.transition(st, a))
    return {
        "env": env_id,
        "transition_ms": 1e3 * step_s,
        "build_ms": 1e3 * build_s,
        "warm_start_ms": 1e3 * warm_s,
        "build_share": build_s / step_s,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    recs = [measure(i) for i in IDS]
    print("| env | transition ms | space build + teardown ms | priming substep ms | build share |")
    print("|---|---|---|---|---|")
    for r in recs:
        print(
            f"| {r['env']} | {r['transition_ms']:.3f} | {r['build_ms']:.3f} | "
            f"{r['warm_start_ms']:.3f} | {100 * float(r['build_share']):.0f}% |"
        )
    if args.out:
        args.out.write_text(json.dumps(recs, indent=1))


if __name__ == "__main__":
    main()
