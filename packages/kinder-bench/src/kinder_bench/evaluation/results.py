"""The results file of a run directory: one JSON object per finished episode.

Lines are appended with a single ``write`` on a file opened with ``O_APPEND`` and then synced, so
a line is either fully there or (after a crash in the middle of the write) a partial last line;
:func:`load_records` drops such a partial line (its episode is not finished and runs again).
"""

from __future__ import annotations

import json
import os
import platform
import shlex
import sys
import warnings
from pathlib import Path
from typing import Any

# Re-exported: the runner records these versions with every episode.
from kinder_bench.training.checkpoints import package_versions as package_versions

RESULTS_FILE = "results.jsonl"
CONFIG_FILE = "config.json"
SCHEMA_VERSION = 1


def load_records(path: Path | str) -> list[dict[str, Any]]:
    """The records of a results file (a run directory or the ``.jsonl`` file itself).

    A partial last line (an interrupted write) is removed from the file; a missing file has no
    records.
    """
    path = Path(path)
    if path.is_dir():
        path = path / RESULTS_FILE
    if not path.exists():
        return []
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        keep = data.rfind(b"\n") + 1
        with open(path, "r+b") as f:
            f.truncate(keep)
        data = data[:keep]
    records = []
    for n, line in enumerate(data.splitlines(), start=1):
        if not line.strip():
            continue
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError:
            warnings.warn(f"{path}:{n}: skipping a line that is not JSON", stacklevel=2)
    return records


def append_record(path: Path | str, record: dict[str, Any]) -> None:
    """Append one record as one line, atomically (a single ``O_APPEND`` write) and durably."""
    line = (json.dumps(record, sort_keys=True, allow_nan=False) + "\n").encode()
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        written = os.write(fd, line)
        if written != len(line):  # regular files write fully; fail loudly rather than corrupt
            raise OSError(f"short write to {path}: {written} of {len(line)} bytes")
        os.fsync(fd)
    finally:
        os.close(fd)


def write_text(path: Path | str, text: str) -> Path:
    """Write text (UTF-8) through a temporary file and a rename: readers never see half a file."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)
    return path


def write_json(path: Path | str, obj: Any) -> None:
    """Write JSON through a temporary file and a rename, so readers never see half a file."""
    write_text(path, json.dumps(obj, indent=2, sort_keys=True) + "\n")


def invocation() -> str:
    """This process's command line as a user would type it (``kinder bench run ...``,
    ``python -m kinder_bench ...`` or ``python SCRIPT ...``), for the record of what ran."""
    argv = list(sys.argv) or ["python"]
    head = Path(argv[0])
    if head.name == "kinder":
        prog = ["kinder"]
    elif head.name == "__main__.py":
        prog = ["python", "-m", head.parent.name]
    else:
        prog = ["python", argv[0]]
    return shlex.join(prog + argv[1:])


def load_config(run_dir: Path | str) -> dict[str, Any]:
    """A run directory's ``config.json`` (empty when it has none)."""
    path = Path(run_dir) / CONFIG_FILE
    if not path.exists():
        return {}
    config: dict[str, Any] = json.loads(path.read_text())
    return config


def environment_info() -> dict[str, Any]:
    """Where a run ran: versions, interpreter and platform."""
    return {
        "versions": package_versions(),
        "executable": sys.executable,
        "platform": platform.platform(),
    }
