"""Demonstrations: the episode record, recording, storage (LeRobotDataset v3) and replay."""

from kinder_gym.demos.record import SOURCES, EpisodeRecord, EpisodeRecorder, SkillLabel

__all__ = ["SOURCES", "EpisodeRecord", "EpisodeRecorder", "SkillLabel"]
