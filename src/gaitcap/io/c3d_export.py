"""C3D export of point trajectories with gait events in the EVENT group (write only, ezc3d).

Points are written in millimetres (POINT:UNITS = "mm") in gaitcap's z-up world frame, stated as
Vicon states it (POINT:X_SCREEN = "+X", POINT:Y_SCREEN = "+Z"), NaN samples as invalid points
(residual -1). The header's first frame is ``round(t0_s * rate) + 1`` (1-based), so event times, which C3D
stores in seconds from the start of the capture (EVENT:TIMES row 2, row 1 = minutes = 0), stay on
the trajectory's own time axis. Events use the Vicon/Nexus vocabulary: contexts ``Left``/``Right``,
labels ``Foot Strike``/``Foot Off``.
"""

from __future__ import annotations

from pathlib import Path

import ezc3d
import numpy as np

from gaitcap.errors import OutputError
from gaitcap.io.atomic import atomic_path
from gaitcap.trajectory import Trajectory

_LABELS = {"foot_strike": "Foot Strike", "foot_off": "Foot Off"}
_ICONS = {"foot_strike": 1, "foot_off": 2}
_DESCRIPTIONS = {
    "foot_strike": "The instant the heel strikes the ground",
    "foot_off": "The instant the toe leaves the ground",
}


def write_c3d(path: str | Path, traj: Trajectory, subject: str = "") -> None:
    """Write ``traj`` (points and events) as a C3D file readable by ezc3d and the ``c3d`` package.

    Raises:
        OutputError: the file cannot be written.
    """
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(traj.rate_hz)]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(traj.names)
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    # the axes, as Vicon states them: gaitcap's world is z up (viewers orient the display from these)
    c.add_parameter("POINT", "X_SCREEN", ["+X"])
    c.add_parameter("POINT", "Y_SCREEN", ["+Z"])
    data = np.ones((4, len(traj.names), traj.n_frames))
    data[:3] = np.transpose(traj.points * 1000.0, (2, 1, 0))
    c["data"]["points"] = data
    c["header"]["points"]["first_frame"] = max(0, int(round(traj.t0_s * traj.rate_hz)))
    ev = traj.events
    if ev:
        c.add_parameter("EVENT", "USED", len(ev))  # a scalar: ezc3d stores a list of ints as floats
        c.add_parameter("EVENT", "CONTEXTS", [e.side.capitalize() for e in ev])
        c.add_parameter("EVENT", "LABELS", [_LABELS[e.event] for e in ev])
        c.add_parameter("EVENT", "DESCRIPTIONS", [_DESCRIPTIONS[e.event] for e in ev])
        c.add_parameter("EVENT", "SUBJECTS", [subject or "subject"] * len(ev))
        _add_integers(c, "EVENT", "ICON_IDS", [_ICONS[e.event] for e in ev])
        _add_integers(c, "EVENT", "GENERIC_FLAGS", [0] * len(ev))
        c.add_parameter("EVENT", "TIMES", np.array([[0.0] * len(ev), [float(e.time_s) for e in ev]]))
    # ezc3d appends .c3d to a name that does not end with it: keep the temporary name's suffix .c3d
    with atomic_path(path, suffix=".part.c3d") as tmp:
        try:
            c.write(str(tmp))
        except (RuntimeError, ValueError) as e:
            raise OutputError(f"{path}: C3D write failed ({e})") from e


def _add_integers(c: ezc3d.c3d, group: str, name: str, values: list[int]) -> None:
    """Add the parameter ``group:name`` as 16-bit integers (``add_parameter`` stores a list of ints as
    floats, which readers that ask for integers, as the ``c3d`` package's ``get_int16``, misread)."""
    c.add_parameter(group, name, values)
    parameter = c["parameters"][group][name]
    parameter["type"] = ezc3d.ezc3d.INT
    parameter["value"] = np.asarray(values, dtype=int)
