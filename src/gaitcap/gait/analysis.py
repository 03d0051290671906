"""The gait analysis of one trajectory: events -> cycles -> parameters -> angles -> cycle curves."""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field

import numpy as np

from gaitcap.gait.angles import ANGLE_NAMES, joint_angles
from gaitcap.gait.cycles import GaitCycle, find_cycles, normalise_cycle
from gaitcap.gait.events import WalkingDirection, detect_events
from gaitcap.gait.options import GaitOptions
from gaitcap.gait.parameters import GaitParameters, compute_parameters
from gaitcap.trajectory import SIDES, GaitEvent, Trajectory, side_suffix

log = logging.getLogger("gaitcap.gait.analysis")


@dataclass
class GaitAnalysis:
    """Everything the report shows.

    Attributes:
        trajectory: the analysed trajectory (its own ``events`` are the file's reference events).
        events: events detected from the foot kinematics, sorted by time.
        direction: the estimated walking direction.
        parameters: spatio-temporal parameters (``parameters.status`` tells if there were enough steps).
        angles: per-frame joint angles, ``"<angle>_l|_r" -> (T,)`` degrees.
        angle_notes: how the frames were built (e.g. the pelvis frame method).
        cycles: the complete gait cycles of each side.
        curves: ``side -> angle name (without suffix) -> (n_cycles, 101)`` degrees over 0-100 %.
    """

    trajectory: Trajectory
    events: list[GaitEvent]
    direction: WalkingDirection
    parameters: GaitParameters
    angles: dict[str, np.ndarray]
    angle_notes: dict[str, str]
    cycles: dict[str, list[GaitCycle]]
    curves: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)

    @property
    def reference_events(self) -> tuple[GaitEvent, ...]:
        """Events recorded in the input file (force plates, Vicon), if any."""
        return self.trajectory.events

    def curve_stats(self, side: str, angle: str) -> tuple[np.ndarray, np.ndarray, int]:
        """Mean and SD (101,) over the cycles of ``side`` (NaN-aware), and the cycle count."""
        c = self.curves[side][angle]
        if len(c) == 0:
            nan = np.full(101, np.nan)
            return nan, nan, 0
        with warnings.catch_warnings():  # all-NaN columns (a gap) give NaN, not a warning
            warnings.simplefilter("ignore", RuntimeWarning)
            mean = np.nanmean(c, axis=0)
            sd = np.nanstd(c, axis=0, ddof=1) if len(c) > 1 else np.full(101, np.nan)
        return mean, sd, len(c)


def analyse(traj: Trajectory, options: GaitOptions | None = None) -> GaitAnalysis:
    """Run the gait analysis of one trajectory (never raises for too few steps: see
    ``result.parameters.status``).

    Raises:
        InputError: the trajectory lacks the points needed (pelvis or hips, heels or ankles).
    """
    opt = options or GaitOptions()
    events, direction = detect_events(traj, opt)
    params = compute_parameters(traj, events, direction, opt.plausible)
    angles, notes = joint_angles(traj, direction)
    cycles = {s: find_cycles(events, s) for s in SIDES}
    times = traj.times()
    curves: dict[str, dict[str, np.ndarray]] = {}
    for side in SIDES:
        sfx = side_suffix(side)
        curves[side] = {
            name: np.array([normalise_cycle(angles[f"{name}{sfx}"], times, c) for c in cycles[side]]).reshape(-1, 101)
            for name in ANGLE_NAMES
        }
    if not params.ok:
        log.warning("%s", params.reason)
    return GaitAnalysis(traj, events, direction, params, angles, notes, cycles, curves)
