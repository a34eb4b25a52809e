"""Demonstrations: the episode record, recording, storage (LeRobotDataset v3) and replay.

* :mod:`.record`: :class:`EpisodeRecord` (one type for every source) and :class:`EpisodeRecorder`.
* :mod:`.layout`: :class:`StateSplit` (robot state vs environment state, by feature name) and
  the dataset cameras (:func:`camera_frames`).
* :mod:`.lerobot_format`: ``DemoWriter`` / ``load_records`` / ``load_dataset`` for LeRobotDataset
  v3 (imports lerobot, and so torch, only when used).
* :mod:`.replay`: replaying a record from its seed and checking it reproduces.
"""

from kinder_gym.demos.layout import StateSplit, camera_frames, camera_names
from kinder_gym.demos.record import SOURCES, EpisodeRecord, EpisodeRecorder, SkillLabel
from kinder_gym.demos.replay import ReplayResult, replay_record

__all__ = [
    "SOURCES",
    "EpisodeRecord",
    "EpisodeRecorder",
    "ReplayResult",
    "SkillLabel",
    "StateSplit",
    "camera_frames",
    "camera_names",
    "replay_record",
]
