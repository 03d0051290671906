"""TRC marker files (OpenSim / Motion Analysis format): read and write.

Layout (tab separated)::

    PathFileType  4  (X/Y/Z)  <file name>
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
    60.00     60.00       151        41          mm     60.00         1                   151
    Frame#  Time  <name1>  <tab> <tab>  <name2> ...
                  X1  Y1  Z1  X2  Y2  Z2 ...
    <blank line>
    1  0.000000  x  y  z  ...  <tab>

Missing samples are empty cells (read as NaN); each data row ends with a tab, as OpenSim writes
them (its reader drops an empty last cell that no tab follows). The file frame is kept by the reader (metres,
axes as in the file); rotation to gaitcap's z-up frame is the caller's job
(:func:`gaitcap.markers.motion.read_markers`). The writer takes a z-up trajectory and writes
it in the requested up-axis convention (OpenSim expects y up).
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np

from gaitcap.errors import InputError, OutputError
from gaitcap.io.atomic import atomic_path
from gaitcap.markers.axes import from_z_up, metres_per_unit
from gaitcap.trajectory import Trajectory

log = logging.getLogger("gaitcap.io.trc")

_HEADER_KEYS = ("DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units",
                "OrigDataRate", "OrigDataStartFrame", "OrigNumFrames")  # fmt: skip


def _cell(text: str) -> float:
    text = text.strip()
    if not text:
        return math.nan
    return float(text)


def _header(keys_line: str, values_line: str) -> dict[str, str]:
    """The header's key -> value. Empty cells and extra tabs are dropped from both lines first:
    OpenSim's own example files write ``100.0<TAB><TAB>100.0<TAB><TAB>238...``."""
    keys = [k.strip() for k in keys_line.split("\t") if k.strip()]
    values = [v.strip() for v in values_line.split("\t") if v.strip()]
    return dict(zip(keys, values, strict=False))


def read_trc(path: str | Path) -> Trajectory:
    """Read a TRC file into a :class:`Trajectory` of markers, in metres and in the file's axes.

    ``points`` has shape (T, M, 3) for the M markers named in the file; ``t0_s`` is the first
    value of the Time column; ``meta`` holds ``source``, ``units`` (as in the file) and
    ``format="trc"``. Raises :class:`InputError` naming the file on any malformed content.
    """
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as e:
        raise InputError(f"{path}: cannot read TRC file ({e.strerror})") from e
    if len(lines) < 5 or not lines[0].startswith("PathFileType"):
        raise InputError(f"{path}: not a TRC file (first line must start with PathFileType)")
    header = _header(lines[1], lines[2])
    try:
        rate = float(header["DataRate"])
        units = header["Units"]
        n_markers = int(float(header["NumMarkers"]))
    except (KeyError, ValueError) as e:
        raise InputError(f"{path}: bad TRC header line 3 ({e})") from e
    scale = metres_per_unit(units, str(path))
    names = [n.strip() for n in lines[3].split("\t")[2:] if n.strip()]
    if len(names) != n_markers:
        log.warning("%s: header says %d markers, the name line has %d", path, n_markers, len(names))
    n_cols = 2 + 3 * len(names)
    times: list[float] = []
    rows: list[list[float]] = []
    for lineno, line in enumerate(lines[5:], start=6):
        if not line.strip():
            continue
        cells = line.split("\t")
        cells = (cells + [""] * n_cols)[:n_cols]
        try:
            times.append(_cell(cells[1]))
            rows.append([_cell(c) for c in cells[2:]])
        except ValueError as e:
            raise InputError(f"{path}: line {lineno}: not a number ({e})") from e
    if not rows:
        raise InputError(f"{path}: no data rows")
    points = np.asarray(rows, dtype=np.float64).reshape(len(rows), len(names), 3) * scale
    t0 = times[0] if math.isfinite(times[0]) else 0.0
    meta = {"source": str(path), "units": units, "format": "trc"}
    return Trajectory(names=tuple(names), points=points, rate_hz=rate, t0_s=t0, meta=meta)


def _format_row(frame: int, time_s: float, values: np.ndarray, fmt: str) -> str:
    """One data row, ended by a tab as OpenSim's own writer ends it: OpenSim's reader (TRCFileAdapter)
    keeps an empty cell only when a tab follows it, so without it a row whose last marker is missing
    (every cell of a frame the tracker flagged) is one column short and the whole file is refused."""
    cells = ["" if not math.isfinite(v) else format(v, fmt) for v in values]
    return "\t".join([str(frame), f"{time_s:.6f}", *cells]) + "\t"


def write_trc(path: str | Path, trajectory: Trajectory, units: str = "mm", up_axis: str = "y") -> Path:
    """Write a z-up :class:`Trajectory` to a TRC file (OpenSim conventions), atomically.

    Args:
        path: target file.
        trajectory: points (T, P, 3), metres, gaitcap z-up frame.
        units: ``"mm"`` or ``"m"`` (or ``"cm"``): the length unit written in the file.
        up_axis: the file's up axis; ``"y"`` (default) is what OpenSim expects. The rotation is
            the inverse of the reader's (see :mod:`gaitcap.markers.axes`), so
            ``read_markers(write_trc(p, traj), up_axis="y")`` gives ``traj`` back.

    NaN samples become empty cells. Events and meta are not stored (TRC has no place for them).
    """
    path = Path(path)
    scale = metres_per_unit(units, str(path))
    pts = from_z_up(trajectory.points, up_axis) / scale
    n_frames, n_points = pts.shape[:2]
    fmt = ".6f" if scale <= 1e-3 else ".9f"
    rate = f"{trajectory.rate_hz:.2f}"
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
        "\t".join(_HEADER_KEYS),
        "\t".join([rate, rate, str(n_frames), str(n_points), units, rate, "1", str(n_frames)]),
        "\t".join(["Frame#", "Time"] + [f"{n}\t\t" for n in trajectory.names]),
        "\t".join(["", ""] + [f"X{i}\tY{i}\tZ{i}" for i in range(1, n_points + 1)]),
        "",
    ]
    flat = pts.reshape(n_frames, -1)
    times = trajectory.times()
    lines += [_format_row(i + 1, times[i], flat[i], fmt) for i in range(n_frames)]
    try:
        with atomic_path(path) as tmp:
            tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
    except OSError as e:  # pragma: no cover - atomic_path already maps most errors
        raise OutputError(f"{path}: cannot write TRC ({e.strerror})") from e
    return path
