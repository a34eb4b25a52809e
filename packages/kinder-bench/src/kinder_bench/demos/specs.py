"""The project's demonstration datasets: what ``make datasets`` collects, builds and describes.

Ten datasets of at least 100 successful demonstrations each, one per env: the paper's eight
benchmark envs and two more:

* ``Obstruction2D-o1``: the Kinematic2D pick-and-place task with one obstruction on the target
  surface. Its plans chain several skills (clear the obstruction, then pick and place the target),
  which is what skill-conditioned learners such as generative skill chaining need, and its
  skills are planned with the same bilevel planner as the benchmark envs.
* ``ClutteredStorage2D-b1``: storing a block in a shelf, the env the upstream design notes
  (prpl-mono #61) proposed as the first demonstration env; another multi-skill Kinematic2D task
  with a different skill set (pick from the table, place into the shelf).

Both are cheap to plan (well under a second per episode), so they add variety without cost.

Every dataset comes from the bilevel planner (skill-labelled). Its planning timeout is raised for
collection so that the counted budgets (abstract plans, samples per step), not the machine's
speed, decide an attempt's outcome, which keeps the datasets reproducible. SweepIntoDrawer3D is
the exception: its plans take ~20 s and ~60 % of attempts fail, many by running out of time, so a
300 s budget would multiply the cost of every failure; it gets 60 s (the benchmark used 25 s), and
its attempts that end near that limit may differ between machines (and between a loaded and an
idle machine), which can change which episodes are kept.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from kinder_bench.demos.collection import COLLECTION_SEED, CollectConfig

#: Where the datasets live (relative to the repository root): ``datasets/<name>/``.
DATASETS_DIR = Path("datasets")
#: Planning timeout (s) used for collection (see the module docstring).
COLLECT_PLANNING_TIMEOUT = 300.0


@dataclasses.dataclass(frozen=True)
class DatasetSpec:
    """One dataset."""

    name: str
    """The directory name under ``datasets/`` (the env's short id)."""
    env_id: str
    agent: str = "bilevel_planning"
    agent_args: Mapping[str, Any] = dataclasses.field(
        default_factory=lambda: {"planning_timeout": COLLECT_PLANNING_TIMEOUT}
    )
    episodes: int = 100
    seed: int = COLLECTION_SEED
    """Collection seed, outside the evaluation seeds (see ``COLLECTION_SEED``)."""
    images: bool = True
    why: str = ""
    """Why the dataset is in the set (for the card)."""

    def collect_config(self, episodes: int | None = None) -> CollectConfig:
        return CollectConfig(
            env_id=self.env_id,
            agent=self.agent,
            agent_args=dict(self.agent_args),
            episodes=self.episodes if episodes is None else episodes,
            seed=self.seed,
        )

    def root(self, base: Path = DATASETS_DIR) -> Path:
        return base / self.name

    def collection_dir(self, base: Path = DATASETS_DIR) -> Path:
        """The collection directory (attempts and episode files; gitignored)."""
        return self.root(base) / "data" / "collection"

    def dataset_dir(self, base: Path = DATASETS_DIR) -> Path:
        """The LeRobotDataset v3 directory (gitignored)."""
        return self.root(base) / "data" / "lerobot"


_PAPER = "One of the paper's eight benchmark environments."

DATASETS: dict[str, DatasetSpec] = {
    s.name: s
    for s in (
        DatasetSpec("Motion2D-p0", "kinder/Motion2D-p0-v0", why=_PAPER),
        DatasetSpec("StickButton2D-b1", "kinder/StickButton2D-b1-v0", why=_PAPER),
        DatasetSpec("DynObstruction2D-o1", "kinder/DynObstruction2D-o1-v0", why=_PAPER),
        DatasetSpec("DynPushPullHook2D-o5", "kinder/DynPushPullHook2D-o5-v0", why=_PAPER),
        DatasetSpec("BaseMotion3D", "kinder/BaseMotion3D-v0", why=_PAPER),
        DatasetSpec("Transport3D-o2", "kinder/Transport3D-o2-v0", why=_PAPER),
        DatasetSpec("Shelf3D-o1", "kinder/Shelf3D-o1-v0", why=_PAPER),
        DatasetSpec(
            "SweepIntoDrawer3D-o5",
            "kinder/SweepIntoDrawer3D-o5-v0",
            agent_args={"planning_timeout": 60.0},
            why=_PAPER,
        ),
        DatasetSpec(
            "Obstruction2D-o1",
            "kinder/Obstruction2D-o1-v0",
            why="Extra: multi-skill pick-and-place (clear the obstruction, then place the "
            "target), the skill chains skill-conditioned learners need; cheap to plan.",
        ),
        DatasetSpec(
            "ClutteredStorage2D-b1",
            "kinder/ClutteredStorage2D-b1-v0",
            why="Extra: the env the upstream design notes proposed for the first demonstrations; "
            "a multi-skill storage task with a different skill set; cheap to plan.",
        ),
    )
}


def dataset_spec(name: str) -> DatasetSpec:
    """A dataset by name (its env's short id)."""
    if name not in DATASETS:
        raise ValueError(f"Unknown dataset {name!r}; known: {', '.join(DATASETS)}")
    return DATASETS[name]


__all__ = ["DATASETS", "DATASETS_DIR", "DatasetSpec", "dataset_spec"]
