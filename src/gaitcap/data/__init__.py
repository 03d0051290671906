"""Data shipped with gaitcap (see README.md beside this file for provenance and licences)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from gaitcap.errors import InputError

EMBEDDED_WALK = "walk_pig.c3d"


def embedded_walk() -> Path:
    """Path of the embedded Plug-in-Gait walking trial (``walk_pig.c3d``, Apache-2.0).

    Example:
        >>> from gaitcap.markers.motion import read_motion
        >>> read_motion(embedded_walk()).n_frames
        221
    """
    path = Path(str(resources.files("gaitcap.data").joinpath(EMBEDDED_WALK)))
    if not path.is_file():
        raise InputError(f"{path}: embedded walking trial missing (broken installation?)")
    return path
