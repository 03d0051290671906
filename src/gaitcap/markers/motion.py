"""Public entry points: read a motion file's markers, or its gaitcap joint centres.

- :func:`read_markers`: raw markers (C3D or TRC), metres, gaitcap frame (z up).
- :func:`read_motion`: joint centres named with :data:`gaitcap.trajectory.POINT_NAMES`, the
  mapping chosen from the markers present, events from the C3D file or from force plates. A
  file whose points already carry gaitcap names (``joints.trc`` written by the tracker through
  :func:`gaitcap.io.trc.write_trc`) is returned as it is, in :data:`POINT_NAMES` order.

Up axis, in order of precedence: the ``up_axis`` argument; the file's own statement (C3D
POINT:Y_SCREEN); the mapping's ``up_axis``; for TRC files without one, the axis along which the
markers of a frame spread the most (the body is taller than it is wide or deep: head to feet, or
pelvis to feet for a lower-body set), ``"y"`` (the OpenSim convention) if that is not clear. See
:mod:`gaitcap.markers.axes` for the rotation.

Labels: a subject prefix (``A22:RKNE``) is removed; a file with several subjects gives the one
named by ``subject``, else the one with the most markers (logged). Samples at exactly (0, 0, 0)
(how several systems write a gap) become NaN; channels with no sample at all are left out.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path

import numpy as np

from gaitcap.errors import InputError
from gaitcap.io.c3d import read_c3d_markers, read_c3d_plates
from gaitcap.io.trc import read_trc
from gaitcap.markers.axes import UP_AXES, to_z_up
from gaitcap.markers.events import events_from_grf, events_from_plates
from gaitcap.markers.jointcentres import apply_mapping
from gaitcap.markers.mapping import Mapping, Resolution, load_mapping, shipped_mapping_names
from gaitcap.trajectory import POINT_NAMES, Trajectory

log = logging.getLogger("gaitcap.markers.motion")

READERS = {".c3d": read_c3d_markers, ".trc": read_trc}
TRC_DEFAULT_UP = "y"
#: the up axis is guessed only when the largest within-frame spread exceeds the next by this factor
UP_GUESS_RATIO = 1.3
MARKERS_HINT = "see `gaitcap markers FILE`, or write a mapping for your set and pass it with --mapping my_lab.yaml"


def read_raw_markers(path: str | Path, subject: str | None = None) -> Trajectory:
    """Markers in the file's own axes (metres), by file extension: one subject's labels without
    prefix, zero samples as gaps, empty channels left out (see the module docstring)."""
    path = Path(path)
    reader = READERS.get(path.suffix.lower())
    if reader is None:
        raise InputError(f"{path}: unknown motion file type (expected {', '.join(READERS)})")
    if not path.is_file():
        raise InputError(f"{path}: file not found")
    return _without_gaps(select_subject(reader(path), subject))


def split_subject(label: str) -> tuple[str, str]:
    """``"A22:RKNE"`` -> ``("A22", "RKNE")``; ``"RKNE"`` -> ``("", "RKNE")``."""
    prefix, _, name = label.rpartition(":")
    return prefix.strip(), name.strip()


def subjects(names: tuple[str, ...] | list[str]) -> dict[str, list[int]]:
    """Subject prefix -> indices of its labels (``""`` for labels without a prefix)."""
    out: dict[str, list[int]] = {}
    for i, label in enumerate(names):
        out.setdefault(split_subject(label)[0], []).append(i)
    return out


def select_subject(raw: Trajectory, subject: str | None = None) -> Trajectory:
    """One subject's markers with the prefix removed (labels without a prefix kept beside them).

    ``subject`` names the prefix; None takes the subject with the most markers. ``meta["subject"]``
    records the choice. :class:`InputError` when ``subject`` is not in the file.
    """
    groups = subjects(raw.names)
    named = {k: v for k, v in groups.items() if k}
    source = raw.meta.get("source", "motion file")
    if subject is not None and subject not in named:
        listed = ", ".join(named) or "none, labels have no prefix"
        raise InputError(f"{source}: no subject {subject!r} (subjects: {listed})")
    if not named:
        return raw
    chosen = subject if subject is not None else max(named, key=lambda k: len(named[k]))
    if len(named) > 1:
        counts = ", ".join(f"{k} ({len(v)} markers)" for k, v in named.items())
        log.info("%s: several subjects: %s; using %s", source, counts, chosen)
    keep = named[chosen] + groups.get("", [])
    names = [split_subject(raw.names[i])[1] for i in keep]
    if len(set(names)) < len(names):  # an unprefixed label repeats a subject's: the subject's wins
        keep = named[chosen] + [i for i in groups.get("", []) if raw.names[i] not in names[: len(named[chosen])]]
        names = [split_subject(raw.names[i])[1] for i in keep]
    meta = {**raw.meta, "subject": chosen}
    return replace(raw, names=tuple(names), points=raw.points[:, keep], meta=meta)


def _without_gaps(raw: Trajectory) -> Trajectory:
    """Zero samples as NaN; channels with no finite sample left out (named in ``meta["empty"]``)."""
    points = raw.points.copy()
    points[(points == 0.0).all(axis=-1)] = np.nan
    alive = np.isfinite(points).all(axis=-1).any(axis=0)
    dead = [n for n, ok in zip(raw.names, alive, strict=True) if not ok]
    if dead:
        log.debug("%s: channels without data left out: %s", raw.meta.get("source"), ", ".join(dead))
    names = tuple(n for n, ok in zip(raw.names, alive, strict=True) if ok)
    return replace(raw, names=names, points=points[:, alive], meta={**raw.meta, "empty": dead})


def guess_up_axis(points: np.ndarray) -> str | None:
    """The axis along which the markers of a frame spread the most (median over frames), or None.

    Args:
        points: shape (T, M, 3), any unit.
    Returns:
        ``"x"``, ``"y"`` or ``"z"`` when the largest spread exceeds the second by
        :data:`UP_GUESS_RATIO`, else None.
    """
    if points.shape[1] < 3:
        return None
    with warnings.catch_warnings():  # all-NaN frames are expected (gaps)
        warnings.simplefilter("ignore", RuntimeWarning)
        spread = np.nanmedian(np.nanmax(points, axis=1) - np.nanmin(points, axis=1), axis=0)
    if not np.isfinite(spread).all():
        return None
    order = np.argsort(spread)[::-1]
    if spread[order[0]] < UP_GUESS_RATIO * spread[order[1]]:
        return None
    return "xyz"[int(order[0])]


def _resolve_up_axis(raw: Trajectory, mapping: Mapping | None, up_axis: str | None) -> str:
    if up_axis is not None:
        if up_axis not in UP_AXES:
            raise InputError(f"unknown up axis {up_axis!r} (use one of {', '.join(UP_AXES)})")
        return up_axis
    if raw.meta.get("up_axis"):
        return str(raw.meta["up_axis"])
    if mapping is not None and mapping.up_axis is not None:
        return mapping.up_axis
    if raw.meta.get("format") != "trc":
        return "z"
    guess = guess_up_axis(raw.points)
    if guess is None:
        log.info("%s: up axis neither stated nor clear from the markers: %s assumed",
                 raw.meta.get("source"), TRC_DEFAULT_UP)  # fmt: skip
        return TRC_DEFAULT_UP
    if guess != TRC_DEFAULT_UP:
        log.info("%s: %s up (the body's long axis; TRC files are usually y up)", raw.meta.get("source"), guess)
    return guess


def _rotated(raw: Trajectory, up: str) -> Trajectory:
    meta = {**raw.meta, "file_up_axis": up, "up_axis": "z"}
    return replace(raw, points=to_z_up(raw.points, up), meta=meta)


def resolve_shipped(marker_names: tuple[str, ...] | list[str]) -> list[Resolution]:
    """Every shipped mapping checked against the marker names: fitting ones first (the one giving
    the most output points first), then by the number of markers missing."""
    found = [load_mapping(name).resolve(marker_names) for name in shipped_mapping_names()]
    return sorted(found, key=lambda r: (not r.fits, -len(r.output_points()), len(r.missing_required())))


def choose_mapping(marker_names: tuple[str, ...] | list[str], source: str = "motion file") -> Mapping:
    """The shipped mapping that fits the marker set (see :func:`resolve_shipped`).

    Raises:
        InputError: naming the closest mapping, its missing markers and the ``gaitcap markers``
        command.
    """
    best = resolve_shipped(marker_names)[0]
    if best.fits:
        return best.mapping
    raise InputError(f"{source}: no shipped marker mapping fits this marker set; closest: {best.mapping.name} "
                     f"(missing {', '.join(best.missing_required())}); {MARKERS_HINT}")  # fmt: skip


def _mapping_of(mapping: Mapping | str | Path | None, raw: Trajectory) -> Mapping:
    if isinstance(mapping, Mapping):
        return mapping
    if mapping is not None:
        return load_mapping(mapping)
    return choose_mapping(raw.names, str(raw.meta.get("source", "motion file")))


def read_markers(
    path: str | Path,
    up_axis: str | None = None,
    mapping: Mapping | str | Path | None = None,
    subject: str | None = None,
) -> Trajectory:
    """Raw marker trajectories of a .c3d or .trc file: metres, gaitcap frame (z up).

    Returns a :class:`Trajectory` named by marker labels, shape (T, M, 3), with the file's
    events (C3D) and ``meta`` (``source``, ``format``, ``units``, ``file_up_axis``,
    ``height_m`` for C3D, ``subject`` when the labels had a prefix). ``up_axis`` overrides the
    file's up axis; ``mapping`` (else the shipped one that fits, if any) may state it (see the
    module docstring); ``subject`` picks one subject of a file holding several.
    """
    raw = read_raw_markers(path, subject)
    chosen = None
    if up_axis is None and not raw.meta.get("up_axis"):
        try:
            chosen = _mapping_of(mapping, raw)
        except InputError:
            chosen = None
    return _rotated(raw, _resolve_up_axis(raw, chosen, up_axis))


def find_static_trial(motion_path: Path, pattern: str) -> Path:
    """The single file matching ``pattern`` (e.g. ``*_static.trc``) beside the motion file."""
    found = sorted(p for p in motion_path.parent.glob(pattern) if p != motion_path)
    if not found:
        if motion_path.match(pattern):  # a standing trial has no walk to read
            raise InputError(f"{motion_path}: this is a static trial ({pattern}), which the mapping reads beside a "
                             "walking trial: give the walking trial's file (and this one with --static FILE)")  # fmt: skip
        raise InputError(f"{motion_path}: the mapping needs a static trial ({pattern} beside it): none there; "
                         "give it with --static FILE")
    if len(found) > 1:
        names = ", ".join(p.name for p in found)
        raise InputError(f"{motion_path}: several static trials match {pattern} ({names}): give one with --static FILE")
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


def _plate_events(path: Path, joints: Trajectory, up: str) -> list:
    """Foot contacts from the C3D file's force plates (a second source when it has no EVENT group)."""
    if path.suffix.lower() != ".c3d":
        return []
    events = events_from_plates(read_c3d_plates(path), joints, up)
    if events:
        log.info("%s: no EVENT group; %d events from the force plates", path, len(events))
    return events


def read_motion(
    path: str | Path,
    mapping: Mapping | str | Path | None = None,
    static: str | Path | None = None,
    up_axis: str | None = None,
    subject: str | None = None,
    require: Iterable[str] = (),
) -> Trajectory:
    """Joint centres of a marker-based motion file (.c3d or .trc).

    Args:
        path: the motion trial.
        mapping: a :class:`Mapping`, a shipped mapping name or a YAML path; None chooses the
            shipped mapping whose markers are all present.
        static: the static trial for cluster rules; None looks for the mapping's
            ``static_trial`` pattern beside ``path``.
        up_axis: overrides the file's up axis (applied to the static trial too).
        subject: the subject prefix to read in a file holding several (default: most markers).
        require: output points the caller needs (``LOWER_LIMB`` for a report or a synthetic
            session): a mapping that does not define one of them is refused, naming it.
    Returns:
        :class:`Trajectory` of the points the mapping defines (:data:`POINT_NAMES` order),
        shape (T, P, 3), metres, z up; events from the C3D EVENT group, else from the force-plate
        table beside the file (mapping ``grf``), else from the C3D file's own force plates;
        ``meta``: ``source``, ``mapping``,
        ``height_m`` (C3D), ``static`` (path, when used).
    Raises:
        InputError: unreadable file, no fitting mapping (missing markers listed), no static trial,
            a ``require``-d point the mapping does not define.
    """
    path = Path(path)
    raw = read_raw_markers(path, subject)
    if mapping is None and raw.names and set(raw.names) <= set(POINT_NAMES):
        markers = _rotated(raw, _resolve_up_axis(raw, None, up_axis))
        return markers.subset(n for n in POINT_NAMES if markers.has(n))
    chosen = _mapping_of(mapping, raw)
    require = tuple(require)
    undefined = [n for n in require if n not in chosen.points]
    if undefined:
        raise InputError(f"{path}: {chosen.label} defines no {', '.join(undefined)} under points: each of "
                         f"{', '.join(require)} is needed here")  # fmt: skip
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
        joints = joints.with_events(_grf_events(path, chosen, up) or _plate_events(path, joints, up))
    log.info("%s: %d frames at %g Hz, mapping %s, %d points, %d events", path, joints.n_frames,
             joints.rate_hz, chosen.name, len(joints.names), len(joints.events))  # fmt: skip
    return joints
