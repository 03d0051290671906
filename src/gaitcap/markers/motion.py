"""Public entry points: read a motion file's markers, or its gaitcap joint centres.

- :func:`read_markers`: raw markers (C3D or TRC), metres, gaitcap frame (z up).
- :func:`read_motion`: joint centres named with :data:`gaitcap.trajectory.POINT_NAMES`, the
  mapping chosen from the markers present, events from the C3D file or from force plates. A
  file whose points already carry gaitcap names (``joints.trc`` written by the tracker through
  :func:`gaitcap.io.trc.write_trc`) is returned as it is, in :data:`POINT_NAMES` order.

Up axis, in order of precedence: the ``up_axis`` argument; the file's own statement (C3D
POINT:Y_SCREEN); the mapping's ``up_axis``; for TRC files without one, ``"y"`` (the OpenSim
convention TRC files follow). See :mod:`gaitcap.markers.axes` for the rotation.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

from gaitcap.errors import InputError
from gaitcap.io.c3d import read_c3d_markers
from gaitcap.io.trc import read_trc
from gaitcap.markers.axes import UP_AXES, to_z_up
from gaitcap.markers.events import events_from_grf
from gaitcap.markers.jointcentres import apply_mapping
from gaitcap.markers.mapping import Mapping, load_mapping, shipped_mapping_names
from gaitcap.trajectory import POINT_NAMES, Trajectory

log = logging.getLogger("gaitcap.markers.motion")

READERS = {".c3d": read_c3d_markers, ".trc": read_trc}
TRC_DEFAULT_UP = "y"


def read_raw_markers(path: str | Path) -> Trajectory:
    """Markers in the file's own axes (metres), by file extension."""
    path = Path(path)
    reader = READERS.get(path.suffix.lower())
    if reader is None:
        raise InputError(f"{path}: unknown motion file type (expected {', '.join(READERS)})")
    if not path.is_file():
        raise InputError(f"{path}: file not found")
    return reader(path)


def _resolve_up_axis(raw: Trajectory, mapping: Mapping | None, up_axis: str | None) -> str:
    if up_axis is not None:
        if up_axis not in UP_AXES:
            raise InputError(f"unknown up axis {up_axis!r} (use one of {', '.join(UP_AXES)})")
        return up_axis
    if raw.meta.get("up_axis"):
        return str(raw.meta["up_axis"])
    if mapping is not None and mapping.up_axis is not None:
        return mapping.up_axis
    return TRC_DEFAULT_UP if raw.meta.get("format") == "trc" else "z"


def _rotated(raw: Trajectory, up: str) -> Trajectory:
    meta = {**raw.meta, "file_up_axis": up, "up_axis": "z"}
    return replace(raw, points=to_z_up(raw.points, up), meta=meta)


def choose_mapping(marker_names: tuple[str, ...] | list[str], source: str = "motion file") -> Mapping:
    """The shipped mapping whose markers are all present; :class:`InputError` listing what is missing."""
    report = []
    for name in shipped_mapping_names():
        mapping = load_mapping(name)
        missing = mapping.missing_markers(marker_names)
        if not missing:
            return mapping
        report.append(f"{name}: missing {', '.join(missing)}")
    raise InputError(f"{source}: no marker mapping fits this marker set ({'; '.join(report)})")


def _mapping_of(mapping: Mapping | str | Path | None, raw: Trajectory) -> Mapping:
    if isinstance(mapping, Mapping):
        return mapping
    if mapping is not None:
        return load_mapping(mapping)
    return choose_mapping(raw.names, str(raw.meta.get("source", "motion file")))


def read_markers(path: str | Path, up_axis: str | None = None) -> Trajectory:
    """Raw marker trajectories of a .c3d or .trc file: metres, gaitcap frame (z up).

    Returns a :class:`Trajectory` named by marker labels, shape (T, M, 3), with the file's
    events (C3D) and ``meta`` (``source``, ``format``, ``units``, ``file_up_axis``,
    ``height_m`` for C3D). ``up_axis`` overrides the file's up axis (see module docstring).
    """
    raw = read_raw_markers(path)
    mapping = None
    if up_axis is None and not raw.meta.get("up_axis"):
        try:
            mapping = choose_mapping(raw.names)
        except InputError:
            mapping = None
    return _rotated(raw, _resolve_up_axis(raw, mapping, up_axis))


def find_static_trial(motion_path: Path, pattern: str) -> Path:
    """The single file matching ``pattern`` (e.g. ``*_static.trc``) beside the motion file."""
    found = sorted(p for p in motion_path.parent.glob(pattern) if p != motion_path)
    if not found:
        raise InputError(f"{motion_path}: the mapping needs a static trial ({pattern} beside it); pass it explicitly")
    if len(found) > 1:
        names = ", ".join(p.name for p in found)
        raise InputError(f"{motion_path}: several static trials match {pattern} ({names}); pass one explicitly")
    return found[0]


def _grf_events(path: Path, mapping: Mapping, up: str) -> list:
    if mapping.grf is None:
        return []
    grf_path = path.with_name(path.stem + mapping.grf.file_suffix)
    if not grf_path.is_file():
        log.info("%s: no force-plate file %s, no events", path, grf_path.name)
        return []
    g = mapping.grf
    return events_from_grf(grf_path, g.threshold_n, g.right, g.left, up_axis=up)


def read_motion(
    path: str | Path,
    mapping: Mapping | str | Path | None = None,
    static: str | Path | None = None,
    up_axis: str | None = None,
) -> Trajectory:
    """Joint centres of a marker-based motion file (.c3d or .trc).

    Args:
        path: the motion trial.
        mapping: a :class:`Mapping`, a shipped mapping name or a YAML path; None chooses the
            shipped mapping whose markers are all present.
        static: the static trial for cluster rules; None looks for the mapping's
            ``static_trial`` pattern beside ``path``.
        up_axis: overrides the file's up axis (applied to the static trial too).
    Returns:
        :class:`Trajectory` of the points the mapping defines (:data:`POINT_NAMES` order),
        shape (T, P, 3), metres, z up; events from the C3D EVENT group, or from the force-plate
        table beside the file (mapping ``grf``); ``meta``: ``source``, ``mapping``,
        ``height_m`` (C3D), ``static`` (path, when used).
    Raises:
        InputError: unreadable file, no fitting mapping (missing markers listed), no static trial.
    """
    path = Path(path)
    raw = read_raw_markers(path)
    if mapping is None and raw.names and set(raw.names) <= set(POINT_NAMES):
        markers = _rotated(raw, _resolve_up_axis(raw, None, up_axis))
        return markers.subset(n for n in POINT_NAMES if markers.has(n))
    chosen = _mapping_of(mapping, raw)
    up = _resolve_up_axis(raw, chosen, up_axis)
    markers = _rotated(raw, up)
    static_traj = None
    if chosen.needs_static():
        static_path = Path(static) if static is not None else find_static_trial(path, chosen.static_trial or "*_static.*")
        static_raw = read_raw_markers(static_path)
        static_traj = _rotated(static_raw, _resolve_up_axis(static_raw, chosen, up_axis))
        markers = replace(markers, meta={**markers.meta, "static": str(static_path)})
    joints = apply_mapping(chosen, markers, static_traj)
    if not joints.events:
        joints = joints.with_events(_grf_events(path, chosen, up))
    log.info("%s: %d frames at %g Hz, mapping %s, %d points, %d events", path, joints.n_frames,
             joints.rate_hz, chosen.name, len(joints.names), len(joints.events))  # fmt: skip
    return joints
