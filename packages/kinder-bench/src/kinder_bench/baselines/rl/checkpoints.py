"""Checkpoints of the RL baselines on disk (no torch import).

A training output directory holds::

    config.json                  the algorithm, its full arguments, the env's spaces, versions
    progress.csv                 one row per logging interval (CsvLog)
    checkpoints/step_000051200/  one checkpoint per directory, named by its env step count:
        model.zip                  the SB3 model (policy, optimizers, hyperparameters)
        vecnormalize.pkl           the observation/reward normalisation statistics
        replay_buffer.pkl          SAC only: the replay buffer, so that training resumes exactly
        meta.json                  algo, env id, spaces, steps; written last
    tb/                          TensorBoard events, when tensorboard is installed

A checkpoint directory is written under a temporary name and renamed into place, so a directory
named ``step_*`` is always complete.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

CHECKPOINTS_DIR = "checkpoints"
META_FILE = "meta.json"
MODEL_FILE = "model.zip"
VECNORM_FILE = "vecnormalize.pkl"
REPLAY_FILE = "replay_buffer.pkl"
CONFIG_FILE = "config.json"
PROGRESS_FILE = "progress.csv"
_STEP_DIR = re.compile(r"^step_(\d+)$")


def checkpoint_name(steps: int) -> str:
    """The directory name of the checkpoint taken after ``steps`` env steps."""
    return f"step_{steps:09d}"


def list_checkpoints(run_dir: Path | str) -> list[tuple[int, Path]]:
    """The complete checkpoints of a training directory as ``(steps, path)``, oldest first."""
    root = Path(run_dir) / CHECKPOINTS_DIR
    if not root.is_dir():
        return []
    found = []
    for p in root.iterdir():
        m = _STEP_DIR.match(p.name)
        if m and (p / META_FILE).is_file():
            found.append((int(m.group(1)), p))
    return sorted(found)


def latest_checkpoint(run_dir: Path | str) -> Path | None:
    """The newest complete checkpoint of a training directory, or None."""
    found = list_checkpoints(run_dir)
    return found[-1][1] if found else None


def resolve_checkpoint(path: Path | str) -> Path:
    """A checkpoint directory from ``path``: a checkpoint directory itself, or a training output
    directory (its newest checkpoint).

    Raises:
        FileNotFoundError: naming what is missing and what was expected.
    """
    p = Path(path)
    if not str(path):
        raise FileNotFoundError(
            "No checkpoint given: pass --arg checkpoint=DIR (a `kinder train` output directory "
            "or one of its checkpoints/step_* directories)"
        )
    if (p / META_FILE).is_file():
        return p
    if not p.exists():
        raise FileNotFoundError(f"Checkpoint {p} does not exist")
    latest = latest_checkpoint(p)
    if latest is None:
        raise FileNotFoundError(
            f"{p} holds no checkpoint: expected {META_FILE} there, or complete "
            f"{CHECKPOINTS_DIR}/step_*/ directories (a `kinder train` output directory)"
        )
    return latest


def read_meta(checkpoint: Path | str) -> dict[str, Any]:
    """The ``meta.json`` of a checkpoint directory."""
    meta: dict[str, Any] = json.loads((Path(checkpoint) / META_FILE).read_text())
    return meta
