"""Axis conventions: rotate a file's frame into the gaitcap world frame (z up) and back.

gaitcap's world frame is right-handed, metres, z up. Motion files come either z up (Vicon,
Qualisys C3D) or y up (OpenSim TRC/MOT). The conversion is a proper rotation (no mirroring)
that takes the file's up axis to +z:

- ``"z"``: identity.
- ``"y"``: +90 deg about x: (x, y, z) -> (x, -z, y). x stays x, +y goes to +z, +z goes to -y.
  An OpenSim lab frame (x forward, y up, z right) becomes x forward, y left, z up.
- ``"x"``: -90 deg about y: (x, y, z) -> (-z, y, x). +x goes to +z, +z goes to -x.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from gaitcap.errors import InputError

UpAxis = Literal["x", "y", "z"]
UP_AXES: tuple[str, ...] = ("x", "y", "z")

#: R such that p_gaitcap = R @ p_file, for each file up axis.
_TO_Z_UP: dict[str, np.ndarray] = {
    "z": np.eye(3),
    "y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
    "x": np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),
}


def rotation_to_z_up(up_axis: str) -> np.ndarray:
    """The 3x3 rotation taking a frame whose up axis is ``up_axis`` to the z-up frame."""
    try:
        return _TO_Z_UP[up_axis]
    except KeyError:
        raise InputError(f"unknown up axis {up_axis!r} (use one of {', '.join(UP_AXES)})") from None


def to_z_up(points: np.ndarray, up_axis: str) -> np.ndarray:
    """Rotate points, shape (..., 3), from a frame with ``up_axis`` up to the z-up frame."""
    return np.asarray(points, dtype=np.float64) @ rotation_to_z_up(up_axis).T


def from_z_up(points: np.ndarray, up_axis: str) -> np.ndarray:
    """Inverse of :func:`to_z_up`: z-up points, shape (..., 3), into a frame with ``up_axis`` up."""
    return np.asarray(points, dtype=np.float64) @ rotation_to_z_up(up_axis)


#: metres per unit for the length units found in motion files.
LENGTH_UNITS: dict[str, float] = {"mm": 1e-3, "cm": 1e-2, "dm": 1e-1, "m": 1.0}


def metres_per_unit(unit: str, source: str) -> float:
    """Scale factor from a file's length unit to metres; :class:`InputError` naming ``source``."""
    key = unit.strip().lower()
    if key not in LENGTH_UNITS:
        raise InputError(f"{source}: unknown length unit {unit!r} (known: {', '.join(LENGTH_UNITS)})")
    return LENGTH_UNITS[key]
