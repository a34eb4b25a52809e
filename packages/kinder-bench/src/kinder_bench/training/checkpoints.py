"""The one checkpoint format of every trainer (PPO, SAC, DP, DPES, MBRL, GSC).

A run directory (the trainer's ``--out``) keeps its checkpoints under ``checkpoints/``::

    RUN_DIR/
        config.json                 the trainer's own record of the run (resume checks)
        progress.csv                one row per logging interval
        checkpoints/
            step_000051200/         one checkpoint, named by its step (9 digits)
                checkpoint.json     the metadata, written last (see below)
                ...                 the trainer's files (model.zip, model.safetensors, ...)
            latest                  the name of the newest checkpoint (for people; not read)

``checkpoint.json`` holds::

    format_version   FORMAT_VERSION; a reader refuses any other
    method           ppo, sac, dp, dpes, mbrl or gsc
    step             the trainer's unit: env steps (ppo, sac), optimiser steps (dp, dpes, gsc)
                     or epochs (mbrl)
    args             the trainer's argument dataclass as a dict (the command line that made it)
    versions         the versions of Python and the packages that decide a result (``VERSIONED``)
    kept             true: rotation never deletes it (PPO/SAC ``keep_steps``)
    info             whatever the trainer stores for its agent (env id, spaces, feature names)

Writes are atomic: :func:`save_checkpoint` fills ``checkpoints/.tmp-step_<N>/``, writes
``checkpoint.json`` last and renames the directory into place, so a kill at any moment leaves
either no ``step_<N>`` directory or a complete one; :func:`latest_checkpoint` only sees complete
ones (a ``step_*`` directory without ``checkpoint.json`` and the temporary directories are
ignored). After each write the newest ``keep`` checkpoints not marked ``kept`` stay and older
ones are deleted.

Agents and ``--resume`` accept a run directory (its newest checkpoint) or one checkpoint
directory; :func:`load_checkpoint` reads the metadata and raises :class:`CheckpointError` for a
missing or unreadable ``checkpoint.json``, another ``format_version`` or another method.
Checkpoints of the layouts before this format (``meta.json`` of PPO/SAC, ``kinder.json`` of
DP/DPES/MBRL, GSC's ``model.pt`` at the top of its run directory) are recognised and named as
legacy in that error; train them again.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import platform
import re
import shutil
from collections.abc import Callable, Collection, Mapping
from pathlib import Path
from typing import Any

from kinder_gym.demos import record as demo_record

#: The version of the format this module writes and reads.
FORMAT_VERSION = 1
#: The directory of a run directory that holds its checkpoints.
CHECKPOINTS_DIR = "checkpoints"
#: The metadata file of a checkpoint, written last (what makes a directory a checkpoint).
METADATA_FILE = "checkpoint.json"
#: The file under ``checkpoints/`` naming the newest checkpoint.
LATEST_FILE = "latest"
#: Every trainer's method name.
METHODS = ("ppo", "sac", "dp", "dpes", "mbrl", "gsc")
#: The packages whose versions decide a result, recorded with every checkpoint and every
#: evaluated episode: a demonstration record's (ours and the simulators beneath the envs), this
#: package and the learning libraries. Those not installed are left out.
VERSIONED = (
    "kinder-bench",
    *demo_record.VERSIONED_PACKAGES,
    "torch",
    "stable-baselines3",
    "lerobot",
)

_STEP_DIR = re.compile(r"^step_(\d+)$")
#: Files of the layouts before this format: file name -> what wrote it.
_LEGACY_FILES = {
    "meta.json": "`kinder train ppo|sac`",
    "kinder.json": "`kinder train dp|dpes|mbrl`",
    "model.pt": "`kinder train gsc`",
}


class CheckpointError(ValueError):
    """A checkpoint that cannot be used: unreadable, of another format version or method."""


@dataclasses.dataclass(frozen=True)
class Checkpoint:
    """A checkpoint directory and its metadata (``checkpoint.json``)."""

    path: Path
    method: str
    step: int
    args: dict[str, Any]
    """The trainer's argument dataclass as a dict."""
    versions: dict[str, str]
    kept: bool
    info: dict[str, Any]
    """What the trainer stored for its agent."""


def checkpoint_name(step: int) -> str:
    """The directory name of the checkpoint at ``step``."""
    return f"step_{step:09d}"


@functools.cache
def _versions() -> tuple[tuple[str, str], ...]:
    return (("python", platform.python_version()), *demo_record.package_versions(VERSIONED).items())


def package_versions() -> dict[str, str]:
    """Versions of Python and of the installed ``VERSIONED`` packages."""
    return dict(_versions())


def args_dict(args: Any) -> dict[str, Any]:
    """A trainer's argument dataclass (or mapping) as JSON-ready values (paths as strings)."""
    is_instance = dataclasses.is_dataclass(args) and not isinstance(args, type)
    raw = dataclasses.asdict(args) if is_instance else dict(args)
    return {k: _jsonable(v) for k, v in raw.items()}


def _jsonable(value: Any) -> Any:
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, tuple | list):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    return value


def _write_json(path: Path, obj: Any) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(obj, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def list_checkpoints(run_dir: Path | str) -> list[tuple[int, Path]]:
    """The complete checkpoints of a run directory as ``(step, path)``, oldest first."""
    root = Path(run_dir) / CHECKPOINTS_DIR
    if not root.is_dir():
        return []
    found = []
    for p in root.iterdir():
        m = _STEP_DIR.match(p.name)
        if m and (p / METADATA_FILE).is_file():
            found.append((int(m.group(1)), p))
    return sorted(found)


def _legacy_layout(path: Path) -> str | None:
    """What wrote ``path`` (a checkpoint or run directory) in a layout before this format."""
    places = [path, *(p for p in (path / CHECKPOINTS_DIR).glob("step_*") if p.is_dir())]
    for place in places:
        for name, writer in _LEGACY_FILES.items():
            if (place / name).is_file() and not (place / METADATA_FILE).is_file():
                return f"{place / name} (written by {writer} before checkpoint format 1)"
    return None


def _legacy_error(path: Path, legacy: str) -> CheckpointError:
    return CheckpointError(
        f"{path} holds a checkpoint in the legacy layout: {legacy}. This code reads checkpoint "
        f"format {FORMAT_VERSION} ({CHECKPOINTS_DIR}/step_*/{METADATA_FILE}); train it again "
        "into a new directory"
    )


def latest_checkpoint(path: Path | str) -> Path | None:
    """``path`` itself when it is a checkpoint, else its run directory's newest checkpoint, or
    None when it holds none.

    Raises:
        CheckpointError: ``path`` holds only checkpoints of a legacy layout (resuming from it
            would silently start over).
    """
    path = Path(path)
    if (path / METADATA_FILE).is_file():
        return path
    found = list_checkpoints(path)
    if found:
        return found[-1][1]
    legacy = _legacy_layout(path)
    if legacy is not None:
        raise _legacy_error(path, legacy)
    return None


def find_checkpoint(path: Path | str) -> Path:
    """Like :func:`latest_checkpoint`, but a clear error when there is none.

    Raises:
        FileNotFoundError: no path given, ``path`` does not exist, or it holds no checkpoint.
        CheckpointError: it holds only checkpoints of a legacy layout.
    """
    if not str(path):
        raise FileNotFoundError(
            "No checkpoint given: pass --arg checkpoint=DIR (a `kinder train` output directory "
            f"or one of its {CHECKPOINTS_DIR}/step_* directories)"
        )
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"Checkpoint {p} does not exist")
    found = latest_checkpoint(p)
    if found is None:
        raise FileNotFoundError(
            f"{p} holds no checkpoint: expected {METADATA_FILE} there, or complete "
            f"{CHECKPOINTS_DIR}/step_*/ directories (a `kinder train` output directory)"
        )
    return found


def read_checkpoint(path: Path | str, methods: Collection[str] | None = None) -> Checkpoint:
    """The metadata of one checkpoint directory, checked.

    Args:
        path: A checkpoint directory (not a run directory; see :func:`load_checkpoint`).
        methods: The methods the caller can use; None: any.

    Raises:
        CheckpointError: ``checkpoint.json`` is missing, unreadable or incomplete, of another
            ``format_version``, or of a method not in ``methods``.
    """
    path = Path(path)
    file = path / METADATA_FILE
    if not file.is_file():
        legacy = _legacy_layout(path)
        if legacy is not None:
            raise _legacy_error(path, legacy)
        raise CheckpointError(f"{path} is not a checkpoint: {METADATA_FILE} is missing")
    try:
        meta = json.loads(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise CheckpointError(f"{file} is unreadable ({e}); train this checkpoint again") from e
    if not isinstance(meta, dict):
        raise CheckpointError(f"{file} is not a JSON object; train this checkpoint again")
    version = meta.get("format_version")
    if version != FORMAT_VERSION:
        raise CheckpointError(
            f"{path} is a checkpoint of format_version {version!r}; this code reads format "
            f"{FORMAT_VERSION}: train it again with this version, or evaluate it with the version "
            f"that wrote it ({meta.get('versions', {}).get('kinder-bench', 'unknown')})"
        )
    missing = [k for k in ("method", "step", "args", "versions", "info") if k not in meta]
    if missing:
        raise CheckpointError(f"{file} lacks {missing}; train this checkpoint again")
    method = str(meta["method"])
    if methods is not None and method not in methods:
        wanted = " or ".join(sorted(methods))
        raise CheckpointError(
            f"{path} holds a {method} policy (a `kinder train {method}` checkpoint), not {wanted}: "
            f"evaluate it with --agent {method}"
        )
    return Checkpoint(
        path=path,
        method=method,
        step=int(meta["step"]),
        args=dict(meta["args"]),
        versions=dict(meta["versions"]),
        kept=bool(meta.get("kept", False)),
        info=dict(meta["info"]),
    )


def load_checkpoint(path: Path | str, methods: Collection[str] | None = None) -> Checkpoint:
    """The checkpoint at ``path`` (a run directory: its newest one), with checked metadata.

    Raises:
        FileNotFoundError: as :func:`find_checkpoint`.
        CheckpointError: as :func:`read_checkpoint`.
    """
    return read_checkpoint(find_checkpoint(path), methods)


def save_checkpoint(
    run_dir: Path | str,
    step: int,
    method: str,
    args: Any,
    write: Callable[[Path], None],
    *,
    info: Mapping[str, Any] | None = None,
    keep: int = 2,
    kept: bool = False,
) -> Path:
    """Write the checkpoint at ``step`` atomically, then delete all but the newest ``keep``
    checkpoints (those marked ``kept`` stay).

    A step's checkpoint is written once: when a complete one exists at ``step`` (a trainer that
    checkpoints twice at one step), its files stay and only ``kept=True`` is recorded.

    Args:
        run_dir: The run directory.
        step: The training step the checkpoint holds.
        method: The trainer's method (one of :data:`METHODS`).
        args: The trainer's argument dataclass (or a mapping), recorded as ``args``.
        write: Fills a (temporary) directory with the trainer's files.
        info: What the trainer stores for its agent, recorded as ``info``.
        keep: How many checkpoints not marked ``kept`` to keep; at least 1.
        kept: Never delete this checkpoint in rotation.

    Returns:
        The checkpoint directory.
    """
    if method not in METHODS:
        raise ValueError(f"Unknown trainer method {method!r}; expected one of {METHODS}")
    if step < 0:
        raise ValueError(f"A checkpoint's step must be >= 0, got {step}")
    root = Path(run_dir) / CHECKPOINTS_DIR
    root.mkdir(parents=True, exist_ok=True)
    final = root / checkpoint_name(step)
    if (final / METADATA_FILE).is_file():
        if kept:
            meta = json.loads((final / METADATA_FILE).read_text(encoding="utf-8"))
            if not meta.get("kept", False):
                _write_json(final / METADATA_FILE, {**meta, "kept": True})
        return final
    tmp = root / f".tmp-{final.name}"
    shutil.rmtree(tmp, ignore_errors=True)  # a leftover of a killed write
    tmp.mkdir()
    write(tmp)
    if (tmp / METADATA_FILE).exists():
        raise RuntimeError(f"A checkpoint writer must not write {METADATA_FILE} itself")
    record = {
        "format_version": FORMAT_VERSION,
        "method": method,
        "step": int(step),
        "args": args_dict(args),
        "versions": package_versions(),
        "kept": bool(kept),
        "info": _jsonable(dict(info or {})),
    }
    _write_json(tmp / METADATA_FILE, record)
    shutil.rmtree(final, ignore_errors=True)  # an incomplete leftover (no checkpoint.json)
    os.replace(tmp, final)
    (root / f".{LATEST_FILE}.tmp").write_text(final.name + "\n")
    os.replace(root / f".{LATEST_FILE}.tmp", root / LATEST_FILE)
    rotating = [p for _, p in list_checkpoints(run_dir) if not read_checkpoint(p).kept]
    for old in rotating[: -max(keep, 1)]:
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
