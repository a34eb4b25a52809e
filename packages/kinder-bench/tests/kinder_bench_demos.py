"""Test fixture: tiny demonstration datasets of the toy env ``kinder/BenchReach-v0``.

The demos come from a scripted controller (a step of ``gain * (target - robot)``, gain 0.15 by
default, or with ``gain=None`` a constant-length step straight at the target; clipped to the
action box, plus small seeded noise), recorded with kinder-gym's
``EpisodeRecorder`` and written with its ``DemoWriter`` (LeRobotDataset v3; images: the env's
render at ``image_size`` pixels per side, as video).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from kinder_bench_toy import TOY_ID

from kinder_bench.evaluation.envs import make_env

os.environ.setdefault("HF_HUB_OFFLINE", "1")


def scripted_action(
    obs: np.ndarray, rng: np.random.Generator, noise: float, gain: float | None
) -> np.ndarray:
    """``gain * (target - robot)``, or (``gain=None``) a step of length 0.04 straight at the
    target; plus Gaussian noise of std ``noise``; clipped to the action box."""
    delta = obs[3:5] - obs[0:2]
    step = gain * delta if gain is not None else 0.04 * delta / max(np.linalg.norm(delta), 1e-9)
    return np.clip(step + rng.normal(0.0, noise, 2), -0.1, 0.1)


def write_toy_dataset(
    root: Path,
    episodes: int,
    images: bool = True,
    seed: int = 0,
    noise: float = 0.01,
    gain: float | None = 0.15,
    image_size: int = 32,
) -> Path:
    """Write ``episodes`` scripted toy episodes (reset seeds ``seed * 1000 + e``) to ``root``."""
    from kinder_gym.demos.lerobot_format import DemoWriter
    from kinder_gym.demos.record import EpisodeRecorder

    env = make_env(TOY_ID)
    rng = np.random.default_rng(seed)
    with DemoWriter(root, TOY_ID, images=images, image_size=image_size) as writer:
        for e in range(episodes):
            recorder = EpisodeRecorder(env, TOY_ID, "scripted")
            obs = recorder.reset(seed * 1000 + e)
            while not recorder.done and recorder.num_steps < 40:
                obs = recorder.step(scripted_action(obs, rng, noise, gain))[0]
            writer.add(recorder.finish(task="reach the target"))
    return root
