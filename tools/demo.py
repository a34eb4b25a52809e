"""The main job: ``kinder demo`` when kinder-bench provides it, else a random-policy rollout.

Lists the registered environments, runs the benchmark demo of kinder-bench (a few agents on a few
fast envs, results table and GIF under runs/demo); when the bench CLI is not available it rolls out
a random policy in the first registered env, writes runs/demo/random.gif and prints statistics.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np

import kinder_core

OUT = Path("runs/demo")


def random_rollout(env_id: str, seed: int = 0, steps: int = 100) -> None:
    """Roll out random actions, write a GIF and print episode statistics."""
    env = kinder_core.make(env_id, render_mode="rgb_array")
    env.action_space.seed(seed)
    env.reset(seed=seed)
    frames = [env.render()]
    total, n, success = 0.0, 0, False
    for n in range(1, steps + 1):  # noqa: B007 (n is the episode length afterwards)
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        total += float(reward)
        frames.append(env.render())
        success = bool(info.get("success", terminated))
        if terminated or truncated:
            break
    OUT.mkdir(parents=True, exist_ok=True)
    gif = OUT / "random.gif"
    iio.imwrite(gif, np.stack(frames), duration=50, loop=0)
    print(f"{env_id}: {n} steps, return {total:.1f}, success {success}; GIF: {gif}")


def main() -> None:
    ids = kinder_core.list_envs()
    print(f"{len(ids)} registered KinDER environments:")
    for env_id in ids:
        print(f"  {env_id}")
    if importlib.util.find_spec("kinder_bench.cli") is not None:
        sys.exit(subprocess.call([sys.executable, "-m", "kinder_bench.cli", "demo"]))
    if not ids:
        sys.exit("no environments are registered: install kinder-garden2d or kinder-garden3d")
    random_rollout(ids[0])


if __name__ == "__main__":
    main()
