"""Periodic, atomic checkpoint directories for the trainers.

A run directory keeps its checkpoints as ``checkpoints/step_<NNNNNNNN>/``. Each is written into a
hidden temporary directory and renamed into place, so a kill never leaves a half-written
checkpoint under a real name; ``checkpoints/latest`` (written atomically) names the newest one.
Agents and ``--resume`` accept either the run directory (its latest checkpoint) or one checkpoint
directory.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

#: A file every checkpoint directory holds (what tells a checkpoint from a run directory).
MARKER = "kinder.json"
_STEP_DIR = re.compile(r"^step_(\d{8})$")


def checkpoint_dirs(run_dir: Path | str) -> list[Path]:
    """The complete checkpoints of a run directory, oldest first."""
    root = Path(run_dir) / "checkpoints"
    if not root.is_dir():
        return []
    found = [p for p in root.iterdir() if _STEP_DIR.match(p.name) and (p / MARKER).is_file()]
    return sorted(found, key=lambda p: p.name)


def latest_checkpoint(path: Path | str) -> Path | None:
    """``path`` itself when it is a checkpoint, else its run directory's newest checkpoint."""
    path = Path(path)
    if (path / MARKER).is_file():
        return path
    found = checkpoint_dirs(path)
    return found[-1] if found else None


def find_checkpoint(path: Path | str) -> Path:
    """Like :func:`latest_checkpoint`, but a clear error when there is none."""
    found = latest_checkpoint(path)
    if found is None:
        raise FileNotFoundError(
            f"No checkpoint at {path}: expected a run directory of `kinder train ...` (with "
            f"checkpoints/step_*/) or one checkpoint directory (with {MARKER})"
        )
    return found


def save_checkpoint(
    run_dir: Path | str, step: int, write: Callable[[Path], None], keep: int = 2
) -> Path:
    """Write checkpoint ``step`` atomically and keep only the newest ``keep`` ones.

    Args:
        run_dir: The run directory.
        step: The training step the checkpoint holds.
        write: Fills a (temporary) directory; it must write :data:`MARKER` last.
        keep: How many checkpoints to keep (older ones are deleted); at least 1.
    """
    root = Path(run_dir) / "checkpoints"
    root.mkdir(parents=True, exist_ok=True)
    final = root / f"step_{step:08d}"
    tmp = root / f".step_{step:08d}.{os.getpid()}.tmp"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    write(tmp)
    if not (tmp / MARKER).is_file():
        raise RuntimeError(f"checkpoint writer did not write {MARKER}")
    if final.exists():
        shutil.rmtree(final)
    os.replace(tmp, final)
    latest_tmp = root / f".latest.{os.getpid()}.tmp"
    latest_tmp.write_text(final.name + "\n")
    os.replace(latest_tmp, root / "latest")
    for old in checkpoint_dirs(run_dir)[: -max(keep, 1)]:
        shutil.rmtree(old, ignore_errors=True)
    return final


def check_resume_config(out: Path, record: Mapping[str, Any], keys: tuple[str, ...]) -> None:
    """Refuse to resume ``out`` when its checkpointed run had another trainer or other ``keys``.

    ``record`` is the new run's ``config.json`` content (``{"trainer": ..., "args": {...}}``);
    nothing is checked when ``out`` holds no checkpoint yet.
    """
    path = out / "config.json"
    if not path.is_file() or latest_checkpoint(out) is None:
        return
    old = json.loads(path.read_text())
    changed = [k for k in keys if old.get("args", {}).get(k) != record["args"].get(k)]
    if old.get("trainer") != record["trainer"] or changed:
        raise ValueError(
            f"{out} holds a run with different {changed or ['trainer']}; use another --out to "
            f"start a new run"
        )
