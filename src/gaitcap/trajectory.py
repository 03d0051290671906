"""Named 3D point trajectories and gait events: the data that flows from motion files, synth and
tracking into gait analysis and export.

Units: metres, seconds; world frame z up, floor z = 0.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from gaitcap.errors import InputError

#: The output points, named the same everywhere. Hip = femoral head centre; knee =
#: mid-epicondyles; ankle = mid-malleoli; heel = back of the calcaneus at the sole;
#: toe = ball of the foot (2nd metatarsal head); pelvis = mid-point of the hip joint centres.
POINT_NAMES: tuple[str, ...] = (
    "pelvis", "hip_l", "hip_r", "knee_l", "knee_r", "ankle_l", "ankle_r",
    "heel_l", "heel_r", "toe_l", "toe_r",
    "thorax", "neck", "head",
    "shoulder_l", "shoulder_r", "elbow_l", "elbow_r", "wrist_l", "wrist_r",
)  # fmt: skip
LOWER_LIMB: tuple[str, ...] = ("hip_l", "hip_r", "knee_l", "knee_r", "ankle_l", "ankle_r")
FOOT: tuple[str, ...] = ("heel_l", "heel_r", "toe_l", "toe_r")

Side = Literal["left", "right"]
EventKind = Literal["foot_strike", "foot_off"]
SIDES: tuple[Side, Side] = ("left", "right")
EVENT_KINDS: tuple[EventKind, EventKind] = ("foot_strike", "foot_off")

#: ``Trajectory.meta`` key: side -> sub-frame indices where the toe, held on the floor through a
#: gap of its marker, was last within the foot's reach (its lift-off; gaitcap.markers.jointcentres)
TOE_RELEASES = "toe_releases"
#: ``Trajectory.meta["format"]`` of a tracking run's trajectories (``gaitcap.io.trajectories_h5``): its
#: gait events keep their anchors (``GaitOptions.refine_tracked``)
TRACKED_FORMAT = "trajectories.h5"


def exchanged_frames(a: np.ndarray, b: np.ndarray, pairs: Sequence[tuple[int, int]]) -> np.ndarray:
    """(T,) bool: the frames where the points of ``a`` (T, P, 3) lie nearer those of ``b`` (T, P, 3)
    with each (left, right) index pair of ``pairs`` exchanged than to ``b``'s own (mean distance over
    the pairs' points): left and right the other way round there. False where a distance is NaN."""
    left, right = [i for i, _ in pairs], [j for _, j in pairs]
    points, crossed = left + right, right + left  # a's right points against b's left ones and back
    direct = np.linalg.norm(a[:, points] - b[:, points], axis=2).mean(axis=1)
    exchanged = np.linalg.norm(a[:, crossed] - b[:, points], axis=2).mean(axis=1)
    with np.errstate(invalid="ignore"):
        return exchanged < direct


def side_suffix(side: Side) -> str:
    """``"left"`` -> ``"_l"``, ``"right"`` -> ``"_r"``."""
    return "_l" if side == "left" else "_r"


@dataclass(frozen=True, order=True)
class GaitEvent:
    """One gait event. ``time_s`` is on the trajectory's own time axis (see :class:`Trajectory`)."""

    time_s: float
    side: Side
    event: EventKind
    source: str = ""

    def __post_init__(self) -> None:
        if self.side not in SIDES:
            raise ValueError(f"gait event side must be left or right, got {self.side!r}")
        if self.event not in EVENT_KINDS:
            raise ValueError(f"gait event must be foot_strike or foot_off, got {self.event!r}")


@dataclass(frozen=True)
class Trajectory:
    """Named points over time.

    Attributes:
        names: point names, length P.
        points: positions, shape (T, P, 3), metres; NaN where a point is missing. A float64 array is
            held, not copied (a clip's passes are views of its frames).
        rate_hz: sampling rate.
        t0_s: time of frame 0 in seconds (C3D files start at ``(first_frame - 1) / rate``).
        events: gait events, times on the same axis as :meth:`times`.
        meta: free-form provenance (source file, subject height, ...).
    """

    names: tuple[str, ...]
    points: np.ndarray
    rate_hz: float
    t0_s: float = 0.0
    events: tuple[GaitEvent, ...] = ()
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        pts = np.asarray(self.points, dtype=np.float64)  # no copy: a pass of a clip is a view of its frames
        names = tuple(self.names)
        if pts.ndim != 3 or pts.shape[2] != 3 or pts.shape[1] != len(names):
            raise InputError(f"trajectory: points must have shape (T, {len(names)}, 3), got {pts.shape}")
        if len(set(names)) != len(names):
            raise InputError("trajectory: duplicate point names")
        if not (np.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise InputError(f"trajectory: sampling rate must be positive, got {self.rate_hz}")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "events", tuple(sorted(self.events)))

    @property
    def n_frames(self) -> int:
        return self.points.shape[0]

    def times(self) -> np.ndarray:
        """Time of each frame, shape (T,)."""
        return self.t0_s + np.arange(self.n_frames) / self.rate_hz

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise InputError(f"trajectory has no point {name!r} (points: {', '.join(self.names)})") from None

    def point(self, name: str) -> np.ndarray:
        """One point's positions, shape (T, 3)."""
        return self.points[:, self.index(name)]

    def has(self, name: str) -> bool:
        return name in self.names

    def subset(self, names: Iterable[str]) -> Trajectory:
        names = tuple(names)
        idx = [self.index(n) for n in names]
        return replace(self, names=names, points=self.points[:, idx])

    def with_events(self, events: Sequence[GaitEvent]) -> Trajectory:
        return replace(self, events=tuple(events))

    def frame_of(self, time_s: float) -> int:
        """Nearest frame index of a time on this trajectory's axis."""
        return int(round((time_s - self.t0_s) * self.rate_hz))

    def resample(self, rate_hz: float) -> Trajectory:
        """Linear resampling in time onto ``rate_hz`` over the same time span (NaN-aware).

        Raises:
            InputError: ``rate_hz`` not a positive number, or a trajectory of no frame.
        """
        try:
            rate = float(rate_hz)
        except (TypeError, ValueError):
            rate = math.nan
        if not (math.isfinite(rate) and rate > 0):
            raise InputError(f"trajectory: cannot resample at {rate_hz!r} Hz: the rate must be a positive number")
        if not self.n_frames:
            raise InputError("trajectory: cannot resample a trajectory of no frame")
        t = self.times()
        n_new = int(np.floor((t[-1] - t[0]) * rate_hz + 1e-9)) + 1
        t_new = t[0] + np.arange(n_new) / rate_hz
        flat = self.points.reshape(self.n_frames, -1)
        out = np.full((n_new, flat.shape[1]), np.nan)
        for j in range(flat.shape[1]):
            ok = np.isfinite(flat[:, j])
            if ok.sum() >= 2:
                v = np.interp(t_new, t[ok], flat[ok, j])
                # do not bridge gaps: a new sample is valid only if both neighbours are
                i = np.clip(np.searchsorted(t, t_new, side="right") - 1, 0, len(t) - 1)
                i2 = np.clip(i + 1, 0, len(t) - 1)
                near = np.isclose(t[i], t_new)
                valid = near & ok[i] | ok[i] & ok[i2]
                out[valid, j] = v[valid]
        return replace(self, points=out.reshape(n_new, len(self.names), 3), rate_hz=rate_hz, t0_s=float(t[0]))
