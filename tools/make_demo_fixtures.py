"""Regenerate the small demonstration datasets the tests read (committed, a few hundred KB).

* ``packages/kinder-gym/tests/data/demos/Motion2D-p0``: 3 bilevel-planner episodes of
  Motion2D-p0 with skill labels and rendered images (LeRobotDataset v3).
* ``packages/kinder-gym/tests/data/demos/Obstruction2D-o1``: 2 episodes of Obstruction2D-o1
  (several skills per episode), without images.

Run ``uv run python tools/make_demo_fixtures.py`` after a change that alters these envs'
dynamics or the planner (the replay tests then tell you the fixtures are stale).
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from kinder_bench.demos.collection import CollectConfig, build_dataset, collect

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "packages" / "kinder-gym" / "tests" / "data" / "demos"
FIXTURES = (("Motion2D-p0", 3, True), ("Obstruction2D-o1", 2, False))


def main() -> None:
    for name, episodes, images in FIXTURES:
        target = OUT / name
        with tempfile.TemporaryDirectory() as tmp:
            coll = Path(tmp) / "collection"
            config = CollectConfig(name, episodes=episodes, agent_args={"planning_timeout": 300})
            collect(config, coll, executor="inline", progress=False)
            shutil.rmtree(target, ignore_errors=True)
            build_dataset(coll, target, images=images, progress=False)
        print(f"wrote {target}")


if __name__ == "__main__":
    main()
