"""``trajectories.h5``: the tracker's output trajectory (read and write only).

Layout (all lengths in metres, times in seconds):

- ``/points`` float64 (T, P, 3); attributes ``names`` (P strings), ``rate_hz``, ``t0_s``;
  frames the tracker flagged are NaN;
- ``/times`` float64 (T,);
- ``/uncertainty`` float64 (T, P), optional;
- ``/quality`` uint8 (T,), optional, 0 = ok;
- ``/events``, optional: a group of three datasets ``time_s`` float64 (E,), ``side`` and
  ``event`` (E,) strings (``left``/``right``, ``foot_strike``/``foot_off``); a compound dataset
  with the same three fields is read too;
- root attribute ``gaitcap_version``.

Each dataset of lengths or times carries a ``units`` attribute (``m``, ``s``: :func:`label_units`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np

from gaitcap import __version__
from gaitcap.errors import InputError
from gaitcap.io.atomic import atomic_path
from gaitcap.trajectory import TRACKED_FORMAT, GaitEvent, Trajectory

_STR = h5py.string_dtype("utf-8")

#: the units of the datasets that hold lengths or times (here, in the tracker's file, gaitcap.io.track_h5, and
#: in synth's truth.h5)
UNITS = {"points": "m", "points_unfiltered": "m", "uncertainty": "m", "spread": "m", "times": "s",
         "events/time_s": "s", "raw_points": "m", "fit_residual_m": "m"}  # fmt: skip


def label_units(f: h5py.File) -> None:
    """Set the ``units`` attribute of the datasets of :data:`UNITS` that ``f`` holds."""
    for name, units in UNITS.items():
        if name in f:
            f[name].attrs["units"] = units


def write_trajectory(
    path: str | Path,
    traj: Trajectory,
    uncertainty: np.ndarray | None = None,
    quality: np.ndarray | None = None,
) -> None:
    """Write ``traj`` (and optional per-point uncertainty (T, P) and per-frame quality (T,))."""
    T, P = traj.n_frames, len(traj.names)
    if uncertainty is not None and np.shape(uncertainty) != (T, P):
        raise ValueError(f"uncertainty must have shape {(T, P)}, got {np.shape(uncertainty)}")
    if quality is not None and np.shape(quality) != (T,):
        raise ValueError(f"quality must have shape {(T,)}, got {np.shape(quality)}")
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["gaitcap_version"] = __version__
        d = f.create_dataset("points", data=traj.points.astype(np.float64), compression="gzip")
        d.attrs["names"] = np.array(traj.names, dtype=object).astype(_STR)
        d.attrs["rate_hz"] = float(traj.rate_hz)
        d.attrs["t0_s"] = float(traj.t0_s)
        f.create_dataset("times", data=traj.times())
        if uncertainty is not None:
            f.create_dataset("uncertainty", data=np.asarray(uncertainty, dtype=np.float64))
        if quality is not None:
            f.create_dataset("quality", data=np.asarray(quality, dtype=np.uint8))
        g = f.create_group("events")
        g.create_dataset("time_s", data=np.array([e.time_s for e in traj.events], dtype=np.float64))
        g.create_dataset("side", data=np.array([e.side for e in traj.events], dtype=object), dtype=_STR)
        g.create_dataset("event", data=np.array([e.event for e in traj.events], dtype=object), dtype=_STR)
        label_units(f)


def _text(values: Any) -> list[str]:
    return [v.decode() if isinstance(v, bytes) else str(v) for v in np.asarray(values).tolist()]


def _read_events(node: Any, path: Path) -> list[GaitEvent]:
    fields = ("time_s", "side", "event")
    if isinstance(node, h5py.Group):
        missing = [k for k in fields if not isinstance(node.get(k), h5py.Dataset)]
        if missing:
            raise InputError(f"{path}: /events has no {', '.join(missing)} dataset (it needs {', '.join(fields)})")
        times, sides, kinds = node["time_s"][()], _text(node["side"][()]), _text(node["event"][()])
    else:  # compound dataset
        data = node[()]
        names = data.dtype.names or ()
        missing = [k for k in fields if k not in names]
        if missing:
            raise InputError(f"{path}: /events has no field {', '.join(missing)} (a group or a compound dataset of "
                             f"{', '.join(fields)})")  # fmt: skip
        times, sides, kinds = data["time_s"], _text(data["side"]), _text(data["event"])
    try:
        return [GaitEvent(float(t), s, k, "trajectories.h5") for t, s, k in zip(times, sides, kinds, strict=True)]  # type: ignore[arg-type]
    except ValueError as e:
        raise InputError(f"{path}: /events: {e}") from e


def read_trajectory(path: str | Path) -> Trajectory:
    """Read a ``trajectories.h5`` file into a :class:`Trajectory`.

    ``meta`` holds ``source``, ``format`` ("trajectories.h5"), ``gaitcap_version`` and, when
    present, ``uncertainty`` (T, P) and ``quality`` (T,) arrays.

    Raises:
        InputError: missing file, not HDF5, or a missing/ill-shaped dataset (named).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: file not found")
    try:
        with h5py.File(path, "r") as f:
            if "points" not in f:
                raise InputError(f"{path}: no /points dataset (not a gaitcap trajectories.h5?)")
            d = f["points"]
            for key in ("names", "rate_hz"):
                if key not in d.attrs:
                    raise InputError(f"{path}: /points has no attribute {key!r}")
            points = d[()]
            names = tuple(_text(d.attrs["names"]))
            rate = float(d.attrs["rate_hz"])
            t0 = float(d.attrs.get("t0_s", f["times"][0] if "times" in f and len(f["times"]) else 0.0))
            meta: dict[str, Any] = {"source": str(path), "format": TRACKED_FORMAT,
                                    "gaitcap_version": str(f.attrs.get("gaitcap_version", ""))}  # fmt: skip
            for key in ("uncertainty", "quality"):
                if key in f:
                    meta[key] = f[key][()]
            events = _read_events(f["events"], path) if "events" in f else []
    except OSError as e:
        raise InputError(f"{path}: not a readable HDF5 file ({e})") from e
    return Trajectory(names, points, rate, t0, tuple(events), meta)
