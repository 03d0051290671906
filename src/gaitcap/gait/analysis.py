"""The gait analysis of one trajectory: events -> cycles -> parameters -> angles -> cycle curves.

A clip of a subject walking up and down a walkway is cut into its passes
(:func:`gaitcap.gait.passes.walk_passes`: the stretches between turns, the pauses at them and the
frames of a turn walked round left out),
and each pass is analysed on its own, with its own walking direction: along one direction for the
whole clip, the heel's lead over the pelvis runs the other way after a turn, and the coordinate-based
events (:mod:`gaitcap.gait.events`) would take every foot off on the way back for a foot strike. The
events, cycles, strides and steps of the passes are then put together; the frames of a pause or of a
turn walked round belong to no pass (no event, no angle there). A clip without a turn is one pass: the analysis as before.

A subject who stops in the middle of a pass and walks on (:func:`gaitcap.gait.passes.stops`: the
pelvis and both feet still for about 0.7 s or more) has the pass cut there after its events are
detected: the stride and the step across the stop are no gait cycle and no step (the Plug-in-Gait
walk held still for 1 s in double support read 41.6 % double support, a stride-time symmetry index of
-62 % and stance 80.6 % on the right with the stride across the stop counted, and no word said).
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from gaitcap.errors import InputError
from gaitcap.gait.angles import ANGLE_NAMES, joint_angles
from gaitcap.gait.cycles import GaitCycle, find_cycles, normalise_cycle
from gaitcap.gait.events import WalkingDirection, detect_events, heel_track, pelvis_track, toe_track
from gaitcap.gait.options import GaitOptions, PlausibleRanges
from gaitcap.gait.parameters import GaitParameters, compute_parameters
from gaitcap.gait.passes import stops, walk_passes
from gaitcap.trajectory import SIDES, TOE_RELEASES, GaitEvent, Trajectory, side_suffix

log = logging.getLogger("gaitcap.gait.analysis")

#: ``parameters.info["event_method"]`` when the input's recorded events were used (``recorded``)
RECORDED_EVENT_METHOD = "recorded in the input file (its C3D EVENT group or force plates), not detected"


@dataclass(frozen=True)
class WalkPass:
    """One pass along the walkway: frames ``start`` to ``stop - 1`` and their walking direction."""

    start: int
    stop: int
    direction: WalkingDirection


def within(traj: Trajectory, start: int, stop: int) -> Trajectory:
    """Frames start..stop-1 of ``traj`` as a trajectory of their own, on the same time axis (its
    ``t0_s`` moved to frame ``start``: events found on it are on ``traj``'s times), with the meta's
    per-frame arrays (first axis of length T) and toe releases (``meta[TOE_RELEASES]``, frame
    indices) cut and shifted alike; ``traj`` itself when that is every frame. A slice, not a copy
    of the whole clip: the passes of a long clip hold its frames once."""
    if (start, stop) == (0, traj.n_frames):
        return traj
    meta = {k: v[start:stop] if isinstance(v, np.ndarray) and v.ndim and len(v) == traj.n_frames else v
            for k, v in traj.meta.items()}  # fmt: skip
    if TOE_RELEASES in meta:
        meta[TOE_RELEASES] = {side: [f - start for f in frames if start <= f < stop]
                              for side, frames in meta[TOE_RELEASES].items()}  # fmt: skip
    return replace(traj, points=traj.points[start:stop], t0_s=traj.t0_s + start / traj.rate_hz, meta=meta)


def forward_by_frame(passes: Sequence[WalkPass], n_frames: int) -> np.ndarray:
    """(T, 3): each frame's walking direction (its pass's ``forward``), NaN in no pass."""
    out = np.full((n_frames, 3), np.nan)
    for p in passes:
        out[p.start : p.stop] = p.direction.forward
    return out


def angles_by_pass(traj: Trajectory, passes: Sequence[WalkPass]) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """:func:`~gaitcap.gait.angles.joint_angles` of each pass against its own walking direction,
    put together (T,) degrees per angle, NaN in no pass; the notes of the first pass."""
    out: dict[str, np.ndarray] = {}
    notes: dict[str, str] = {}
    for p in passes:
        angles, pass_notes = joint_angles(within(traj, p.start, p.stop), p.direction)
        notes = notes or pass_notes
        for name, values in angles.items():
            out.setdefault(name, np.full(traj.n_frames, np.nan))[p.start : p.stop] = values
    return out, notes


def parameters_by_pass(traj: Trajectory, events: Sequence[GaitEvent], passes: Sequence[WalkPass],
                       ranges: PlausibleRanges | None = None) -> GaitParameters:  # fmt: skip
    """:func:`~gaitcap.gait.parameters.compute_parameters` of ``events`` (e.g. a file's recorded
    events), each pass's own (by time) against its own direction, put together."""
    parts = []
    for p in passes:
        part = within(traj, p.start, p.stop)
        lo, hi = part.t0_s - 0.5 / traj.rate_hz, part.times()[-1] + 0.5 / traj.rate_hz
        parts.append((part, [e for e in events if lo <= e.time_s < hi], p.direction))
    return compute_parameters(traj, events, passes[0].direction, ranges, passes=parts)


@dataclass
class GaitAnalysis:
    """Everything the report shows.

    Attributes:
        trajectory: the analysed trajectory (its own ``events`` are the file's reference events).
        events: events detected from the foot kinematics, sorted by time (the input's recorded ones
            with ``recorded``: :attr:`events_recorded`).
        passes: the passes along the walkway (one for a clip without a turn), each with its walking
            direction (:attr:`direction`: the first pass's).
        parameters: spatio-temporal parameters (``parameters.status`` tells if there were enough steps).
        angles: per-frame joint angles, ``"<angle>_l|_r" -> (T,)`` degrees.
        angle_notes: how the frames were built (e.g. the pelvis frame method).
        cycles: the complete gait cycles of each side.
        curves: ``side -> angle name (without suffix) -> (n_cycles, 101)`` degrees over 0-100 %.
    """

    trajectory: Trajectory
    events: list[GaitEvent]
    passes: list[WalkPass]
    parameters: GaitParameters
    angles: dict[str, np.ndarray]
    angle_notes: dict[str, str]
    cycles: dict[str, list[GaitCycle]]
    curves: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    #: True when :attr:`events` are the input file's recorded events (``analyse(..., recorded=True)``,
    #: ``gaitcap report --recorded-events``), not detected ones
    events_recorded: bool = False

    @property
    def direction(self) -> WalkingDirection:
        """The estimated walking direction of the first pass (of the clip, without a turn)."""
        return self.passes[0].direction

    @property
    def reference_events(self) -> tuple[GaitEvent, ...]:
        """Events recorded in the input file (force plates, Vicon), if any."""
        return self.trajectory.events

    def curve_stats(self, side: str, angle: str) -> tuple[np.ndarray, np.ndarray, int]:
        """Mean and SD (101,) over the cycles of ``side`` (NaN-aware), and the count of cycles that have
        the angle (a cycle whose angle is missing throughout, e.g. its pelvis markers in a gap, is not
        counted)."""
        c = self.curves[side][angle]
        c = c[np.isfinite(c).any(axis=1)] if len(c) else c
        if len(c) == 0:
            nan = np.full(101, np.nan)
            return nan, nan, 0
        with warnings.catch_warnings():  # all-NaN columns (a gap) give NaN, not a warning
            warnings.simplefilter("ignore", RuntimeWarning)
            mean = np.nanmean(c, axis=0)
            sd = np.nanstd(c, axis=0, ddof=1) if len(c) > 1 else np.full(101, np.nan)
        return mean, sd, len(c)


def _between_stops(traj: Trajectory, start: int, stop: int) -> tuple[list[tuple[int, int]], list[list[float]]]:
    """The frames (start, stop) of a pass cut at its stops (:func:`gaitcap.gait.passes.stops` of the
    pelvis, heels and toes), each stop left out and logged ([(start, stop)] without one), and the
    stops' first and last times (s)."""
    part = within(traj, start, stop)
    tracks = np.stack([pelvis_track(part)] + [f(part, s) for s in SIDES for f in (heel_track, toe_track)], axis=1)
    still = stops(tracks[..., :2], traj.rate_hz)
    if not still:
        return [(start, stop)], []
    out, a = [], start
    for s0, s1 in still:
        log.warning("the subject stood still for %.2f s or more (frames %d-%d, %.2f-%.2f s): the strides and steps "
                    "across the stop are left out", (s1 - s0) / traj.rate_hz, start + s0, start + s1 - 1,
                    part.t0_s + s0 / traj.rate_hz, part.t0_s + (s1 - 1) / traj.rate_hz)  # fmt: skip
        if start + s0 > a:
            out.append((a, start + s0))
        a = start + s1
    if stop > a:
        out.append((a, stop))
    times = [[round(part.t0_s + s0 / traj.rate_hz, 4), round(part.t0_s + (s1 - 1) / traj.rate_hz, 4)] for s0, s1 in still]
    return out, times


def analyse(traj: Trajectory, options: GaitOptions | None = None, recorded: bool = False) -> GaitAnalysis:
    """Run the gait analysis of one trajectory (never raises for too few steps: see
    ``result.parameters.status``). ``recorded``: the events the trajectory holds (a marker file's EVENT
    group or force plates) instead of those detected; the passes and their directions are found as
    otherwise.

    Raises:
        InputError: the trajectory lacks the points needed (pelvis or hips, heels or ankles), or
            ``recorded`` and it holds no event.
    """
    opt = options or GaitOptions()
    if recorded and not traj.events:
        raise InputError("no events recorded in the input (its EVENT group, or force plates): they cannot be used")
    passes, parts, stopped = [], [], []
    spans = walk_passes(pelvis_track(traj)[:, :2], traj.rate_hz)
    for start, stop in spans:
        part = within(traj, start, stop)
        try:
            found, direction = detect_events(part, opt)
        except InputError as e:
            if len(spans) == 1:
                raise
            log.info("frames %d-%d (a pass along the walkway) not analysed: %s", start, stop - 1, e)
            continue
        if recorded:  # the file's events of this pass's frames
            first, last = part.t0_s - 0.5 / traj.rate_hz, part.t0_s + (part.n_frames - 0.5) / traj.rate_hz
            found = [e for e in traj.events if first <= e.time_s < last]
        pieces, stop_times = _between_stops(traj, start, stop)
        stopped += stop_times
        for a, b in pieces:
            piece = within(traj, a, b)
            lo, hi = piece.t0_s - 0.5 / traj.rate_hz, piece.t0_s + (piece.n_frames - 0.5) / traj.rate_hz
            passes.append(WalkPass(a, b, direction))
            parts.append((piece, [e for e in found if lo <= e.time_s < hi], direction))
    if not passes:
        raise InputError("no pass along the walkway could be analysed (too few valid pelvis and heel samples in each)")
    events = sorted((e for _, found, _ in parts for e in found), key=lambda e: e.time_s)
    if recorded:
        log.info("%d gait events recorded in the input used", len(events))
    else:
        log.info("detected %d gait events (%s)", len(events), passes[0].direction.method)
    if len(passes) > 1:
        log.info("%d passes along the walkway (frames %s), each analysed along its own direction", len(passes),
                 ", ".join(f"{p.start}-{p.stop - 1}" for p in passes))  # fmt: skip
    params = compute_parameters(traj, events, passes[0].direction, opt.plausible, passes=parts)
    if recorded:  # the parameters are the recorded events', not the detector's
        params.info["event_method"] = RECORDED_EVENT_METHOD
    if stopped:  # the strides and steps across each stop are no gait cycle: left out (see the module docstring)
        params.info["stops_s"] = stopped
        said = "; ".join(f"{a:.2f}-{b:.2f} s" for a, b in stopped)
        params.reason = "; ".join(r for r in (params.reason, f"the subject stood still ({said}): the strides and "
                                              "steps across a stop are left out") if r)  # fmt: skip
    angles, notes = angles_by_pass(traj, passes)
    cycles = {s: [c for _, found, _ in parts for c in find_cycles(found, s)] for s in SIDES}
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
    return GaitAnalysis(traj, events, passes, params, angles, notes, cycles, curves, events_recorded=recorded)
