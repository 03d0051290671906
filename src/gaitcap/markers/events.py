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
from gaitcap.io.mot import read_mot
from gaitcap.trajectory import GaitEvent

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
