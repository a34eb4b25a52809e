"""An append-only CSV log that survives restarts (the trainers' ``progress.csv``)."""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Mapping, Sequence
from pathlib import Path


class CsvLog:
    """Appends rows to ``path``, writing the header once.

    On resume the existing header is kept and must match ``columns``; each row is one ``O_APPEND``
    write followed by ``fsync``, so a kill never leaves half a row behind.

    Args:
        path: The CSV file (created with its parent directory when missing).
        columns: Column names, in order.
    """

    def __init__(self, path: Path | str, columns: Sequence[str]) -> None:
        self.path = Path(path)
        self.columns = tuple(columns)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.exists() and self.path.stat().st_size > 0:
            with self.path.open(newline="") as f:
                header = tuple(next(csv.reader(f), ()))
            if header != self.columns:
                raise ValueError(
                    f"{self.path}: existing header {list(header)} does not match the columns "
                    f"{list(self.columns)}; use another output directory"
                )
        else:
            self._append(self.columns)

    def _append(self, values: Sequence[object]) -> None:
        buf = io.StringIO()
        csv.writer(buf).writerow(values)
        data = buf.getvalue().encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)

    def write(self, row: Mapping[str, object]) -> None:
        """Append one row; keys not in :attr:`columns` raise, missing ones are left empty."""
        unknown = set(row) - set(self.columns)
        if unknown:
            raise ValueError(f"{self.path}: unknown columns {sorted(unknown)}")
        self._append([row.get(c, "") for c in self.columns])

    def rows(self) -> list[dict[str, str]]:
        """Every row written so far (as strings)."""
        with self.path.open(newline="") as f:
            return list(csv.DictReader(f))
