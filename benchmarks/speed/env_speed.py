"""Time make, reset, random-action steps and render of registered gymnasium env ids.

Runs under our workspace *and* under the upstream ``kindergarden`` venv (see ``upstream.py``), so it
imports nothing of ours unconditionally: KinDER ids are registered through ``kinder_core`` when it
is installed, else through upstream's ``kinder.register_all_environments()``.

Usage:
    python benchmarks/speed/env_speed.py ID [ID ...] [--steps N] [--seconds S] [--render]
    python benchmarks/speed/env_speed.py --all            # every registered KinDER id of ours
    python benchmarks/speed/env_speed.py --category Kinematic2D

Prints one JSON object per id: make_s, reset_s (mean over seeded resets), steps_per_s (random
actions from a seeded action space, resetting on episode end), render_s (mean, with --render).
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from typing import Any

import gymnasium
import numpy as np


def _register(env_id: str) -> None:
    try:
        registration = importlib.import_module("kinder_core.registration")
    except ImportError:
        kinder = importlib.import_module("kinder")  # the upstream package
        kinder.register_all_environments()
    else:
        registration.ensure_registered(env_id)


def time_env(
    env_id: str,
    steps: int,
    seconds: float,
    resets: int,
    render: bool,
    make_kwargs: dict[str, Any],
) -> dict[str, Any]:
    """Measure one id; errors are reported in the record, not raised."""
    rec: dict[str, Any] = {"env": env_id}
    try:
        _register(env_id)
        t0 = time.perf_counter()
        kwargs = dict(make_kwargs)
        if render:
            kwargs["render_mode"] = "rgb_array"
        env = gymnasium.make(env_id, disable_env_checker=True, **kwargs)
        rec["make_s"] = time.perf_counter() - t0
        env.action_space.seed(0)
        t0 = time.perf_counter()
        n = 0
        while n < resets and (n == 0 or time.perf_counter() - t0 < seconds / 2):
            env.reset(seed=n)
            n += 1
        rec["reset_s"] = (time.perf_counter() - t0) / n
        rec["resets"] = n
        env.reset(seed=123)
        actions = [env.action_space.sample() for _ in range(min(steps, 10_000))]
        n = 0
        t0 = time.perf_counter()
        while n < steps and time.perf_counter() - t0 < seconds:
            _, _, term, trunc, _ = env.step(actions[n % len(actions)])
            n += 1
            if term or trunc:
                env.reset()
        dt = time.perf_counter() - t0
        rec["steps"] = n
        rec["steps_per_s"] = n / dt
        if render:
            env.reset(seed=7)
            frame = env.render()
            t0 = time.perf_counter()
            k = 0
            while k < 20 and (k == 0 or time.perf_counter() - t0 < seconds / 2):
                env.render()
                k += 1
            rec["render_s"] = (time.perf_counter() - t0) / k
            rec["frame_shape"] = list(np.asarray(frame).shape)
        rec["obs_shape"] = list(env.observation_space.shape or [])
        env.close()
    except Exception as e:  # a benchmark reports and keeps going
        rec["error"] = f"{type(e).__name__}: {e}"[:400]
    return rec


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("ids", nargs="*")
    parser.add_argument("--all", action="store_true", help="every registered KinDER id of ours")
    parser.add_argument("--category", help="Kinematic2D, Dynamic2D, Kinematic3D or Dynamic3D")
    parser.add_argument("--steps", type=int, default=2000, help="max steps per id")
    parser.add_argument("--seconds", type=float, default=10.0, help="max stepping time per id")
    parser.add_argument("--resets", type=int, default=20, help="max resets timed per id")
    parser.add_argument("--render", action="store_true", help="also time render()")
    parser.add_argument("--make-kwargs", default="{}", help="JSON kwargs for gymnasium.make")
    args = parser.parse_args(argv)
    ids = list(args.ids)
    if args.all or args.category:
        import kinder_core

        ids += kinder_core.list_envs(args.category)
    if not ids:
        parser.error("give env ids, --all or --category")
    for env_id in ids:
        rec = time_env(
            env_id, args.steps, args.seconds, args.resets, args.render, json.loads(args.make_kwargs)
        )
        print(json.dumps(rec), flush=True)


if __name__ == "__main__":
    sys.exit(main())
