"""One episode per file: the crash-safe staging format of collectors (``.npz``).

A LeRobot dataset is valid only after its writer closed, so long collections first keep every
finished episode as its own file, written atomically (a temporary file, then ``os.replace``):
a killed collection loses at most the episodes in flight, and a rerun skips the files already
there. The dataset is then built from the files in a fixed order (by seed), which makes it
independent of the order parallel workers finished in.

A file holds the record's arrays (float64, exact) and a JSON document with everything else.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from kinder_gym.demos.record import EpisodeRecord, SkillLabel

#: Version of the file layout.
STORE_VERSION = 1
_ARRAYS = ("observations", "actions", "rewards", "states", "step_seconds")


class EpisodeFileError(ValueError):
    """An episode file is missing, truncated or not an episode file (the message names it)."""


def save_record(path: Path | str, record: EpisodeRecord) -> Path:
    """Write ``record`` to ``path`` (``.npz``) atomically; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {
        "store_version": STORE_VERSION,
        "env_id": record.env_id,
        "seed": int(record.seed),
        "source": record.source,
        "terminated": bool(record.terminated),
        "truncated": bool(record.truncated),
        "skills": [s.to_dict() for s in record.skills],
        "task": record.task,
        "versions": dict(record.versions),
        "metadata": record.metadata,
    }
    arrays: dict[str, Any] = {"meta": np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)}
    for name in _ARRAYS:
        value = getattr(record, name)
        if value is not None:
            arrays[name] = np.asarray(value, dtype=np.float64)
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as f:
        f.write(buf.getvalue())
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    return path


def load_record(path: Path | str) -> EpisodeRecord:
    """Read an episode file written by :func:`save_record`."""
    path = Path(path)
    if not path.exists():
        raise EpisodeFileError(f"{path}: no such episode file")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: np.array(data[k]) for k in data.files}
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as e:
        raise EpisodeFileError(
            f"{path}: not a readable episode file ({type(e).__name__}: {e}); it is truncated or "
            f"corrupt"
        ) from None
    if "meta" not in arrays or "observations" not in arrays:
        raise EpisodeFileError(f"{path}: not an episode file (no 'meta' / 'observations')")
    try:
        meta = json.loads(arrays["meta"].tobytes().decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise EpisodeFileError(f"{path}: corrupt metadata ({e})") from None
    if meta.get("store_version") != STORE_VERSION:
        raise EpisodeFileError(
            f"{path}: store_version {meta.get('store_version')!r}, expected {STORE_VERSION}"
        )
    try:
        return EpisodeRecord(
            env_id=meta["env_id"],
            seed=int(meta["seed"]),
            source=meta["source"],
            observations=arrays["observations"],
            actions=arrays["actions"],
            rewards=arrays["rewards"],
            terminated=bool(meta["terminated"]),
            truncated=bool(meta["truncated"]),
            states=arrays.get("states"),
            step_seconds=arrays.get("step_seconds"),
            skills=[SkillLabel.from_dict(s) for s in meta["skills"]],
            task=meta["task"],
            versions=dict(meta["versions"]),
            metadata=dict(meta["metadata"]),
        )
    except (KeyError, ValueError) as e:
        raise EpisodeFileError(f"{path}: inconsistent episode file ({e})") from None


__all__ = ["STORE_VERSION", "EpisodeFileError", "load_record", "save_record"]
