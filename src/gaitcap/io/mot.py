"""OpenSim .mot / .sto tables (read only).

Layout: free header lines (``name``, ``version=1``, ``nRows=..``, ``nColumns=..``,
``inDegrees=yes``) up to a line ``endheader``, then a tab-separated line of column names, then
numbers. The first column is ``time``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gaitcap.errors import InputError


@dataclass(frozen=True)
class MotTable:
    """A numeric table: ``data`` shape (N, C) with ``columns`` (length C); ``header`` key=value pairs."""

    columns: tuple[str, ...]
    data: np.ndarray
    header: dict[str, str] = field(default_factory=dict)
    source: str = ""

    def column(self, name: str) -> np.ndarray:
        """One column, shape (N,)."""
        try:
            return self.data[:, self.columns.index(name)]
        except ValueError:
            raise InputError(f"{self.source}: no column {name!r} (columns: {', '.join(self.columns)})") from None

    @property
    def in_degrees(self) -> bool:
        """Whether angle columns are in degrees (header ``inDegrees``; OpenSim's default is yes)."""
        return self.header.get("inDegrees", "yes").strip().lower() == "yes"

    @property
    def time(self) -> np.ndarray:
        """The time column, shape (N,)."""
        return self.column("time")


def read_mot(path: str | Path) -> MotTable:
    """Read an OpenSim .mot/.sto file; :class:`InputError` naming the file if malformed."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as e:
        raise InputError(f"{path}: cannot read ({e.strerror})") from e
    try:
        end = next(i for i, line in enumerate(lines) if line.strip().lower() == "endheader")
    except StopIteration:
        raise InputError(f"{path}: not an OpenSim .mot/.sto file (no 'endheader' line)") from None
    header = {}
    for line in lines[:end]:
        if "=" in line:
            key, _, value = line.partition("=")
            header[key.strip()] = value.strip()
    if end + 1 >= len(lines):
        raise InputError(f"{path}: no column names after 'endheader'")
    columns = tuple(c.strip() for c in lines[end + 1].split("\t") if c.strip())
    rows = [line for line in lines[end + 2 :] if line.strip()]
    try:
        data = np.array([[float(v) for v in r.split()] for r in rows], dtype=np.float64)
    except ValueError as e:
        raise InputError(f"{path}: not a number in the data ({e})") from e
    if data.ndim != 2 or data.shape[1] != len(columns):
        raise InputError(f"{path}: {len(columns)} column names but rows of {data.shape[-1]} values")
    return MotTable(columns, data, header, str(path))
