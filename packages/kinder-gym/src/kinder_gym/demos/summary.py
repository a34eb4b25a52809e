"""Summaries of demonstration datasets: counts, lengths, sizes and a content checksum.

The **content checksum** is a SHA-256 over what the episodes contain, read back through lerobot
(:func:`~kinder_gym.demos.lerobot_format.load_records`), in episode order: per episode the env id,
seed, source, task, termination flags, skill labels and metadata (canonical JSON), and the
observations, states, actions and rewards (float64, little-endian bytes). It leaves out the
wall-clock step timings and the package versions (they change from run to run or machine to
machine without changing the data) and the files' bytes (parquet and mp4 encoders may embed
versions or differ in layout). Images are a function of the states (they are rendered from them),
so they are covered through the states. Regenerating a dataset with the same command therefore
gives the same checksum whenever it gives the same episodes.
"""

from __future__ import annotations

import hashlib
import json
from collections import Counter
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from kinder_gym.demos.record import EpisodeRecord


def _canonical(obj: Any) -> bytes:
    return json.dumps(obj, sort_keys=True, separators=(",", ":")).encode()


def content_checksum(records: Iterable[EpisodeRecord]) -> str:
    """The SHA-256 content checksum of episodes (module docstring), as ``sha256:<hex>``."""
    h = hashlib.sha256()
    for r in records:
        h.update(
            _canonical(
                {
                    "env_id": r.env_id,
                    "seed": int(r.seed),
                    "source": r.source,
                    "task": r.task,
                    "terminated": bool(r.terminated),
                    "truncated": bool(r.truncated),
                    "skills": [s.to_dict() for s in r.skills],
                    "metadata": r.metadata,
                    "steps": r.num_steps,
                }
            )
        )
        arrays = [r.observations, r.actions, r.rewards]
        if r.states is not None:
            arrays.append(r.states)
        for a in arrays:
            h.update(np.ascontiguousarray(a, dtype="<f8").tobytes())
    return f"sha256:{h.hexdigest()}"


def disk_size(root: Path | str) -> int:
    """Bytes of every file under ``root``."""
    return sum(p.stat().st_size for p in Path(root).rglob("*") if p.is_file())


def summarize_records(records: list[EpisodeRecord]) -> dict[str, Any]:
    """Counts, lengths, success and skill usage of episodes."""
    lengths = np.asarray([r.num_steps for r in records], dtype=np.float64)
    skills: Counter[str] = Counter(s.operator for r in records for s in r.skills)
    return {
        "episodes": len(records),
        "frames": int(lengths.sum()) if len(lengths) else 0,
        "length_mean": float(lengths.mean()) if len(lengths) else 0.0,
        "length_min": int(lengths.min()) if len(lengths) else 0,
        "length_max": int(lengths.max()) if len(lengths) else 0,
        "successes": sum(r.success for r in records),
        "sources": dict(Counter(r.source for r in records)),
        "skills": dict(sorted(skills.items())),
        "skill_labelled": sum(bool(r.skills) for r in records),
        "seeds": [int(r.seed) for r in records],
    }


def dataset_summary(root: Path | str) -> dict[str, Any]:
    """Everything a dataset card states about a LeRobot dataset (reads it through lerobot)."""
    from kinder_gym.demos.lerobot_format import load_records, read_kinder_meta

    root = Path(root)
    meta = read_kinder_meta(root)
    records = load_records(root)
    versions = records[0].versions if records else {}
    return {
        "env_id": meta["env_id"],
        "fps": meta["fps"],
        "cameras": meta["cameras"],
        "image_size": meta["image_size"],
        "robot_objects": meta["split"]["robot_objects"],
        "state_dim": len(meta["split"]["feature_names"]),
        "action_dim": meta["action_dim"],
        "task": meta["task"],
        "versions": versions,
        **summarize_records(records),
        "size_bytes": disk_size(root),
        "checksum": content_checksum(records),
    }


__all__ = ["content_checksum", "dataset_summary", "disk_size", "summarize_records"]
