"""Saving teleoperated episodes: an atomic file per episode at once, a LeRobot dataset at the end.

:class:`TeleopSaver` is the teleop loop's ``save`` callback used by ``kinder teleop``. Each saved
episode is written immediately as its own ``.npz`` file under ``<out>/episodes/`` with
:func:`kinder_gym.demos.store.save_record` (atomic: a crash or Ctrl+C loses nothing that was
saved), named ``episode-<n>-seed<seed>.npz`` in save order. :meth:`TeleopSaver.build` then
appends the episodes that are not yet in the LeRobotDataset v3 at ``<out>/lerobot`` with
:class:`kinder_gym.demos.lerobot_format.DemoWriter` (camera images are rendered from the recorded
states there, so teleoperation itself never pays for them). ``kinder teleop`` builds when it
exits; ``kinder teleop ID --out DIR --build-only`` finishes a build a killed session left undone.
Each dataset episode carries its file name in ``metadata["episode_file"]``, which is how a build
knows what is already in.
"""

from __future__ import annotations

import re
from pathlib import Path

from kinder_gym.demos.record import EpisodeRecord
from kinder_gym.demos.store import load_record, save_record

EPISODES_DIR = "episodes"
DATASET_DIR = "lerobot"
_NAME = re.compile(r"episode-(\d+)-seed(-?\d+)\.npz$")


class TeleopSaver:
    """Saves teleop episodes of one env under ``out`` (module docstring)."""

    def __init__(self, out: Path | str, env_id: str) -> None:
        self.out = Path(out)
        self.env_id = env_id
        self.episodes_dir = self.out / EPISODES_DIR
        self.dataset_dir = self.out / DATASET_DIR

    def files(self) -> list[Path]:
        """The saved episode files, in save order."""
        if not self.episodes_dir.is_dir():
            return []
        found = [p for p in self.episodes_dir.iterdir() if _NAME.search(p.name)]
        return sorted(found, key=lambda p: int(_NAME.search(p.name).group(1)))  # type: ignore[union-attr]

    def __call__(self, record: EpisodeRecord) -> Path:
        """Write one episode file (atomically); returns its path."""
        if record.env_id != self.env_id:
            raise ValueError(
                f"TeleopSaver for {self.env_id} got a record of {record.env_id}; expected one env "
                f"per output directory"
            )
        files = self.files()
        index = 0 if not files else int(_NAME.search(files[-1].name).group(1)) + 1  # type: ignore[union-attr]
        path = self.episodes_dir / f"episode-{index:06d}-seed{record.seed}.npz"
        record.metadata["episode_file"] = path.name
        return save_record(path, record)

    def pending(self) -> list[Path]:
        """Episode files not yet in the dataset."""
        files = self.files()
        if not (self.dataset_dir / "meta" / "info.json").exists():
            return files
        from kinder_gym.demos.lerobot_format import episode_summaries

        have = {
            str(e["metadata"].get("episode_file", "")) for e in episode_summaries(self.dataset_dir)
        }
        return [f for f in files if f.name not in have]

    def build(self, images: bool = True) -> int:
        """Append the pending episodes to the dataset; returns how many were added."""
        pending = self.pending()
        if not pending:
            return 0
        from kinder_gym.demos.lerobot_format import DemoWriter

        with DemoWriter(self.dataset_dir, self.env_id, images=images) as writer:
            for path in pending:
                writer.add(load_record(path))
        return len(pending)
