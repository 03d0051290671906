"""Read a ground truth written in gaitcap's own output formats (a folder), for ``gaitcap eval --truth DIR``.

Layout of DIR (that of ``external_sessions/*/truth/``; a lab can export its marker-based joint
centres the same way to check gaitcap against its own system)::

    joints.csv       frame,time_s,<point>_x,<point>_y,<point>_z,...   metres, the calibration's world
                     frame, one row per frame at a uniform rate (as ``gaitcap track`` writes it);
                     NaN or an empty cell = missing. Point names as gaitcap's (hip_l, knee_r, ...):
                     the points gaitcap does not know are ignored by the comparison.
    events.csv       optional: side,event,frame,time_s  (left/right, foot_strike/foot_off; frame may
                     be fractional; time_s on joints.csv's time axis is what is used)
    parameters.json  optional: {"overall": {name: value}, "left": {...}, "right": {...}} with the
                     names of gaitcap's parameters.json (cadence_steps_per_min, stride_length_m...);
                     other keys and non-numeric values are ignored
    masks.h5         optional: one dataset per camera, (frames, H, W) uint8 0/1, as many frames as
                     joints.csv has rows

Reading and checking only, no maths.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gaitcap.errors import InputError
from gaitcap.io.silhouettes_h5 import read_cameras, read_mask_shape
from gaitcap.trajectory import EVENT_KINDS, SIDES, GaitEvent, Trajectory

JOINTS_FILE = "joints.csv"
EVENTS_FILE = "events.csv"
PARAMETERS_FILE = "parameters.json"
MASKS_FILE = "masks.h5"
#: the scopes of parameters.json that are read
PARAMETER_SCOPES = ("overall", *SIDES)
#: a frame interval of joints.csv may differ from the mean one by this fraction (time_s is rounded)
RATE_TOLERANCE = 0.05


@dataclass(frozen=True)
class TruthFolder:
    """A truth folder, read.

    Attributes:
        path: the folder.
        trajectory: joints.csv's points (T, P, 3) metres, with events.csv's events (if any).
        parameters: parameters.json's numeric values per scope (overall/left/right), or None.
        masks: masks.h5 (checked: T frames per camera), or None.
        cameras: the cameras of masks.h5 (empty without it).
    """

    path: Path
    trajectory: Trajectory
    parameters: dict[str, dict[str, float]] | None = None
    masks: Path | None = None
    cameras: tuple[str, ...] = field(default_factory=tuple)


def is_truth_folder(path: str | Path) -> bool:
    """Whether ``path`` is a folder holding any file of a truth folder (joints.csv, events.csv,
    parameters.json, masks.h5): :func:`read_truth_folder` then says what is missing."""
    return any((Path(path) / name).is_file() for name in (JOINTS_FILE, EVENTS_FILE, PARAMETERS_FILE, MASKS_FILE))


def read_truth_folder(path: str | Path) -> TruthFolder:
    """Read and check a truth folder (see the module docstring).

    Raises:
        InputError: joints.csv missing or malformed; events.csv, parameters.json or masks.h5
            malformed, or masks.h5 not having joints.csv's frame count. The message names the file.
    """
    path = Path(path)
    joints = path / JOINTS_FILE
    if not joints.is_file():
        raise InputError(f"{joints}: missing (a truth folder holds joints.csv: frame,time_s,<point>_x,_y,_z in metres)")
    traj = read_joints_csv(joints)
    events = path / EVENTS_FILE
    if events.is_file():
        traj = traj.with_events(read_events_csv(events))
    params = path / PARAMETERS_FILE
    parameters = read_parameters_json(params) if params.is_file() else None
    masks = path / MASKS_FILE
    cameras: tuple[str, ...] = ()
    if masks.is_file():
        cameras = tuple(read_cameras(masks))
        for cam in cameras:
            n = read_mask_shape(masks, cam)[0]
            if n != traj.n_frames:
                raise InputError(f"{masks}: camera {cam!r} has {n} frames but {joints.name} has {traj.n_frames} rows")
    return TruthFolder(path, traj, parameters, masks if masks.is_file() else None, cameras)


def _float(text: str) -> float:
    text = text.strip()
    return math.nan if text == "" or text.lower() == "nan" else float(text)


def _point_names(path: Path, header: list[str]) -> tuple[str, ...]:
    """The point names of a joints.csv header ``frame,time_s,<p>_x,<p>_y,<p>_z,...``."""
    if header[:2] != ["frame", "time_s"]:
        raise InputError(f"{path}: the first columns must be 'frame,time_s', got {','.join(header[:2])!r}")
    coords = header[2:]
    if not coords or len(coords) % 3:
        raise InputError(f"{path}: after frame,time_s the columns must come in threes <point>_x,<point>_y,<point>_z "
                         f"(got {len(coords)} columns)")  # fmt: skip
    names = []
    for i in range(0, len(coords), 3):
        name = coords[i][:-2]
        if coords[i : i + 3] != [f"{name}_x", f"{name}_y", f"{name}_z"]:
            raise InputError(f"{path}: columns {i + 3}-{i + 5} must be <point>_x,<point>_y,<point>_z, "
                             f"got {','.join(coords[i : i + 3])}")  # fmt: skip
        names.append(name)
    if len(set(names)) != len(names):
        raise InputError(f"{path}: a point appears twice in the header")
    return tuple(names)


def read_joints_csv(path: str | Path) -> Trajectory:
    """A ``joints.csv`` (``frame,time_s,<point>_x,_y,_z``, metres) as a :class:`Trajectory`.

    The rate is that of the ``time_s`` column (uniform within :data:`RATE_TOLERANCE`); frame 0's
    time is the trajectory's ``t0_s``.

    Raises:
        InputError: unreadable file, wrong header, a row of the wrong length or with a non-number,
            fewer than two rows, or a non-uniform time column.
    """
    path = Path(path)
    try:
        with path.open(newline="") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{path}: cannot read ({e})") from e
    if not rows:
        raise InputError(f"{path}: empty file")
    header = [c.strip() for c in rows[0]]
    names = _point_names(path, header)
    body = [r for r in rows[1:] if any(c.strip() for c in r)]
    if len(body) < 2:
        raise InputError(f"{path}: needs at least two rows of data, has {len(body)}")
    values = np.empty((len(body), len(header)))
    for i, row in enumerate(body):
        if len(row) != len(header):
            raise InputError(f"{path}: line {i + 2} has {len(row)} columns, the header {len(header)}")
        try:
            values[i] = [_float(c) for c in row]
        except ValueError as e:
            raise InputError(f"{path}: line {i + 2}: not a number ({e})") from e
    times = values[:, 1]
    return Trajectory(names, values[:, 2:].reshape(len(body), len(names), 3), _rate(path, times), float(times[0]),
                      meta={"source": str(path)})  # fmt: skip


def _rate(path: Path, times: np.ndarray) -> float:
    """The sampling rate of a uniform, increasing (T,) time column."""
    if not np.all(np.isfinite(times)):
        raise InputError(f"{path}: the time_s column has a missing value")
    dt = np.diff(times)
    mean = (times[-1] - times[0]) / (len(times) - 1)
    if mean <= 0 or np.any(np.abs(dt - mean) > RATE_TOLERANCE * mean):
        raise InputError(f"{path}: time_s must increase at a uniform rate (intervals {dt.min():.6g}-{dt.max():.6g} s)")
    return float(1.0 / mean)


def read_events_csv(path: str | Path) -> tuple[GaitEvent, ...]:
    """An ``events.csv`` (``side,event,frame,time_s``) as gait events (times from ``time_s``).

    Raises:
        InputError: unreadable, a missing column, an unknown side or event, a non-numeric time.
    """
    path = Path(path)
    try:
        with path.open(newline="") as fh:
            rows = list(csv.DictReader(fh))
            fields = [] if not rows else list(rows[0])
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{path}: cannot read ({e})") from e
    missing = [c for c in ("side", "event", "frame", "time_s") if rows and c not in fields]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)} (expected side,event,frame,time_s)")
    events = []
    for i, row in enumerate(rows):
        side, kind = row["side"].strip(), row["event"].strip()
        if side not in SIDES or kind not in EVENT_KINDS:
            raise InputError(f"{path}: line {i + 2}: side must be left/right and event foot_strike/foot_off, "
                             f"got {side!r}, {kind!r}")  # fmt: skip
        try:
            time_s = float(row["time_s"])
        except (TypeError, ValueError) as e:
            raise InputError(f"{path}: line {i + 2}: time_s is not a number ({row['time_s']!r})") from e
        events.append(GaitEvent(time_s, side, kind, source=path.name))  # type: ignore[arg-type]
    return tuple(events)


def read_parameters_json(path: str | Path) -> dict[str, dict[str, float]]:
    """The numeric values of ``parameters.json`` per scope (``overall``, ``left``, ``right``).

    Raises:
        InputError: unreadable, not JSON, or not an object holding at least one of those scopes.
    """
    path = Path(path)
    try:
        doc: Any = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise InputError(f"{path}: cannot read as JSON ({e})") from e
    if not isinstance(doc, dict) or not any(isinstance(doc.get(s), dict) for s in PARAMETER_SCOPES):
        raise InputError(f"{path}: expected an object with 'overall', 'left' or 'right' parameters")
    return {
        scope: {k: float(v) for k, v in doc[scope].items() if isinstance(v, int | float) and not isinstance(v, bool)}
        for scope in PARAMETER_SCOPES
        if isinstance(doc.get(scope), dict)
    }
