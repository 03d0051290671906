"""Gait events from force-plate data.

A foot is in contact while its vertical ground reaction force exceeds a threshold (20 N is
the usual choice, e.g. Zeni et al. 2008 use force plates with a 20 N threshold as the gold
standard). Foot strike = an upward crossing, foot off = a downward crossing; the crossing time
is interpolated linearly between the two samples.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gaitcap.errors import InputError
from gaitcap.io.c3d import ForcePlate
from gaitcap.io.mot import read_mot
from gaitcap.markers.axes import to_z_up
from gaitcap.trajectory import GaitEvent, Trajectory

#: Which column component is vertical, by the table's up axis.
_VERTICAL = {"x": "x", "y": "y", "z": "z"}


def threshold_crossings(time: np.ndarray, force: np.ndarray, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """Times where ``force`` (N,) crosses ``threshold`` upward (strikes) and downward (offs)."""
    above = force > threshold
    i_up = np.flatnonzero(~above[:-1] & above[1:])
    i_down = np.flatnonzero(above[:-1] & ~above[1:])

    def interp(i: np.ndarray) -> np.ndarray:
        f0, f1 = force[i], force[i + 1]
        with np.errstate(invalid="ignore", divide="ignore"):
            a = np.clip((threshold - f0) / (f1 - f0), 0.0, 1.0)
        return time[i] + a * (time[i + 1] - time[i])

    return interp(i_up), interp(i_down)


def events_from_grf(
    mot_path: str | Path,
    threshold_n: float = 20.0,
    right: str = "ground_force_v",
    left: str = "1_ground_force_v",
    up_axis: str = "y",
) -> list[GaitEvent]:
    """Foot strikes and foot offs from an OpenSim ground-reaction-force table.

    Args:
        mot_path: the .mot file (OpenSim example: ``subject01_walk1_grf.mot``).
        threshold_n: vertical force threshold in newtons.
        right, left: column prefixes of each foot's force vector (``<prefix>x|y|z``).
        up_axis: the table's vertical axis (OpenSim: ``"y"``).
    Returns:
        events sorted by time, ``source="grf"``, times on the table's time axis.
    """
    if up_axis not in _VERTICAL:
        raise InputError(f"unknown up axis {up_axis!r}")
    table = read_mot(mot_path)
    time = table.time
    events: list[GaitEvent] = []
    for side, prefix in (("right", right), ("left", left)):
        force = table.column(prefix + _VERTICAL[up_axis])
        strikes, offs = threshold_crossings(time, force, threshold_n)
        events += [GaitEvent(float(t), side, "foot_strike", "grf") for t in strikes]  # type: ignore[arg-type]
        events += [GaitEvent(float(t), side, "foot_off", "grf") for t in offs]  # type: ignore[arg-type]
    return sorted(events)


def _foot_on_plate(joints: Trajectory, time: np.ndarray, cop: np.ndarray, start: float, end: float) -> str | None:
    """The side whose foot (nearer of heel/toe, else ankle) stays nearest, on the floor plane, to
    the centre of pressure over the contact ``start``-``end`` (median over the marker frames; the
    swing foot passes close to the plate only briefly). ``time`` (N,), ``cop`` (N, 3)."""
    frames = np.arange(joints.n_frames)
    t = joints.t0_s + frames / joints.rate_hz
    inside = frames[(t >= start) & (t <= end)]
    if inside.size == 0:
        return None
    c = cop[np.clip(np.searchsorted(time, t[inside]), 0, len(time) - 1), :2]
    dist = {}
    for side, s in (("left", "_l"), ("right", "_r")):
        names = [n for n in (f"heel{s}", f"toe{s}", f"ankle{s}") if joints.has(n)][:2]
        if names:
            d = np.min([np.linalg.norm(joints.point(n)[inside, :2] - c, axis=1) for n in names], axis=0)
            if np.isfinite(d).any():
                dist[side] = float(np.nanmedian(d))
    return min(dist, key=dist.__getitem__) if dist else None


def events_from_plates(
    plates: list[ForcePlate], joints: Trajectory, up_axis: str = "z", threshold_n: float = 20.0
) -> list[GaitEvent]:
    """Foot strikes and foot offs from C3D force plates: a contact is a run of vertical force
    above ``threshold_n``; its foot is the one staying nearest to the centre of pressure.

    Args:
        plates: from :func:`gaitcap.io.c3d.read_c3d_plates` (file axes).
        joints: the trial's joint centres (z up, same time axis as the file).
        up_axis: the file's up axis (rotates forces and centres of pressure to z up).
    Returns:
        events sorted by time, ``source="forceplate"``; a contact already loaded at the start
        gives only its foot off, one still loaded at the end only its strike.
    """
    events: list[GaitEvent] = []
    for plate in plates:
        fz = np.abs(np.nan_to_num(to_z_up(np.nan_to_num(plate.force), up_axis)[:, 2]))
        cop = to_z_up(np.nan_to_num(plate.cop), up_axis)
        cop[~np.isfinite(plate.cop).all(axis=1)] = np.nan  # unloaded: ignored by the median
        time = plate.times()
        strikes, offs = threshold_crossings(time, fz, threshold_n)
        bounds = sorted([(t, "foot_strike") for t in strikes] + [(t, "foot_off") for t in offs])
        for k, (t, kind) in enumerate(bounds):
            if kind == "foot_strike":  # the contact runs to the next off, or to the end
                other = bounds[k + 1][0] if k + 1 < len(bounds) else float(time[-1])
            else:
                other = bounds[k - 1][0] if k > 0 else float(time[0])
            side = _foot_on_plate(joints, time, cop, min(t, other), max(t, other))
            if side is not None:
                events.append(GaitEvent(float(t), side, kind, "forceplate"))  # type: ignore[arg-type]
    return sorted(events)
