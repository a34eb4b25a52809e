"""Test fixture: tiny LeRobot v3 demonstration datasets of the toy env ``kinder/BenchReach-v0``.

The demos come from a scripted controller (a step of ``gain * (target - robot)``, gain 0.15 by
default, clipped to the action box, plus small seeded noise) and use the agreed KinDER feature
keys: ``observation.state`` (the robot's features), ``observation.environment_state`` (the rest),
``observation.images.render`` (video of the env's 32×32 render), ``action`` and ``task`` (no
``next.*`` columns: the baselines do not read them).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from kinder_bench_toy import TOY_ID

from kinder_bench.envs import make_env

os.environ.setdefault("HF_HUB_OFFLINE", "1")


def scripted_action(
    obs: np.ndarray, rng: np.random.Generator, noise: float, gain: float
) -> np.ndarray:
    step = gain * (obs[3:5] - obs[0:2]) + rng.normal(0.0, noise, 2)
    return np.clip(step, -0.1, 0.1)


def write_toy_dataset(
    root: Path,
    episodes: int,
    images: bool = True,
    seed: int = 0,
    noise: float = 0.01,
    gain: float = 0.15,
) -> Path:
    """Write ``episodes`` scripted toy episodes to a new dataset at ``root``."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    env = make_env(TOY_ID)
    names = env.unwrapped.box_space.feature_names
    robot = [i for i, n in enumerate(names) if n.startswith("robot.")]
    rest = [i for i, n in enumerate(names) if not n.startswith("robot.")]
    features: dict[str, dict] = {
        "observation.state": {
            "dtype": "float32",
            "shape": (len(robot),),
            "names": [names[i] for i in robot],
        },
        "observation.environment_state": {
            "dtype": "float32",
            "shape": (len(rest),),
            "names": [names[i] for i in rest],
        },
        "action": {"dtype": "float32", "shape": (2,), "names": ["dx", "dy"]},
    }
    if images:
        features["observation.images.render"] = {
            "dtype": "video",
            "shape": (32, 32, 3),
            "names": ["height", "width", "channels"],
        }
    ds = LeRobotDataset.create(
        repo_id="kinder/test", fps=10, features=features, root=root, robot_type=TOY_ID,
        use_videos=images,
    )  # fmt: skip
    rng = np.random.default_rng(seed)
    for e in range(episodes):
        obs, _ = env.reset(seed=seed * 1000 + e)
        for _ in range(40):
            action = scripted_action(obs, rng, noise, gain)
            frame = {
                "observation.state": obs[robot].astype(np.float32),
                "observation.environment_state": obs[rest].astype(np.float32),
                "action": action.astype(np.float32),
                "task": "reach the target",
            }
            if images:
                frame["observation.images.render"] = env.render()
            ds.add_frame(frame)
            obs, _, terminated, _, _ = env.step(action)
            if terminated:
                break
        ds.save_episode()
    ds.finalize()
    return root
