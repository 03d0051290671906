"""Gait events from foot kinematics: the coordinate-based method of Zeni et al. (2008).

Zeni JA, Richards JG, Higginson JS. Two simple methods for determining gait events during treadmill
and overground walking using kinematic data. Gait & Posture 27(4):710-714, 2008.

With ``d`` the horizontal walking direction (estimated, never assumed) and ``x_P = P . d``:

    foot strike  at the local maxima of  x_heel(t) - x_pelvis(t)
    foot off     at the local minima of  x_toe(t)  - x_pelvis(t)

Why this method: it needs only heel, toe and pelvis positions (which the tracker gives as joint
centres, no force plate and no marker-specific threshold), it has no velocity threshold to tune per
subject or per frame rate, it is the same for overground and walk-in-place / treadmill trials (the
pelvis-relative coordinate removes the progression), and Zeni et al. report it within about one
frame at 120 Hz of force-plate events. Its known bias: the heel's forward excursion peaks a little
before the force-plate contact, so foot strikes tend to come a few milliseconds early.

Refinement (``GaitOptions.refine``, on by default). The Zeni extrema are robust anchors (one per
step, never confused between steps), but on the Plug-in-Gait walk they come 35-40 ms before the
force-plate contact (the heel decelerates before it lands). Each anchor is therefore refined
locally, with a criterion that looks at the ground contact itself:

    foot strike  the heel's lowest point: the first upward zero crossing of the heel's vertical
                 velocity within ``strike_window_s`` after the anchor (never before the anchor);
    foot off     the peak forward acceleration of the toe (Hreljac & Marshall, J Biomech 33:783-786,
                 2000) within ``off_window_s`` around the anchor (-1/2 .. +1 window);

an anchor without such a point in its window is kept unchanged (``source`` tells which).

The windows are lengths of time for a normal cadence; the lag from an anchor to the contact it
refines is a phase of the cycle, which a slow walker stretches in time. On a walk whose median
stride (between one foot's anchors) is longer than ``window_stride_s`` (1.25 s), both windows widen
in proportion: the Plug-in-Gait walk slowed three times (strides of 3.3 s, 100 Hz) had the heel's
lowest point 110-130 ms after its anchor, past the 0.12 s window, so every foot strike kept its
anchor, 112-130 ms early, and stance read 66.3 % instead of the 61.4 % of the walk at its own pace;
with the windows widened the strikes came 28-66 ms late and stance 61.5 %. Walks of normal cadence
(the three real walks, strides of 0.95-1.22 s) are refined as before.

The refinement needs the landing resolved in time: below ``refine_min_rate_hz`` (50 Hz) only the
anchors are used. On the 25 fps synthetic sessions of both real walks (the truth joint centres,
the model's heel landmark), refined foot strikes came 47-69 ms late against the recorded events,
the anchors 16-41 ms early; on 7 tracked runs of those sessions, 49 of the 52 recorded events
detectable at all were within one frame (40 ms) with the anchors, 45 with the refinement.
A tracking run's trajectories keep their anchors at every rate (``refine_tracked`` off): the tracked
heel, a model's landmark low-passed at 4.5 Hz, has no sharp landing. On five tracked runs at 50 and
100 fps (the embedded walk and the C3D.ORG walk, synthetic sessions of seed 3, tracker seeds 0-2), of
23 recorded foot strikes the refined ones were within 40 ms of them in 65 % (90th percentile 78 ms,
worst 91 ms), the anchors in 91 % (40 and 49 ms); the 20 foot offs 90 against 95 % (38 and 29 ms).

Robustness:
- the signals are low-pass filtered (zero lag) and short NaN gaps bridged; long gaps split them;
- an extremum at the first or last sample of a run (a partial step at the start or end of the
  trial, or the edge of a gap) is never an event: only interior extrema are taken;
- next to a run's start or end only the interior side's prominence can be measured. An extremum
  whose edge side falls for two samples or more is taken. One at the second or next-to-last sample
  (its turn seen on one sample, as when a foot strikes 1.5 frames before the end of a 25 fps
  trial) is taken only if the stance or swing phase it opens or closes lasts within
  ``edge_rhythm_tolerance`` (25 %) of the median of that phase elsewhere on that side (the other
  side's if none): stance and swing vary by a few % from stride to stride, and a sample timed to
  +/- half a frame moves a 0.4 s swing by 10 % at 25 fps, whereas a mistracked last frame makes
  a turn anywhere in the cycle. On 14 tracked runs of the two synthetic walks and on their truth,
  cut at every frame near their ends, such true edge events kept the phase within -10..+12 %, the
  spurious ones (the tracker losing a foot in the last frames of the Vicon walk) broke it by
  43-58 %. Over 65 tracked runs (several tracker settings) the OpenSim walk's last foot strike,
  1.5 frames before the end, is now found (events within one frame: 232 -> 265 of 272), and the
  Vicon walk's events are unchanged;
- a toe marker lost at push-off while the toe stands on the floor is held there by the marker
  mapping until the ankle is out of the foot's reach (``Trajectory.meta[TOE_RELEASES]``,
  :func:`gaitcap.markers.jointcentres.hold_on_floor`); its signal then ends in its fall, and the
  release is taken as the foot off (an ``"end"`` edge event, under the rhythm check below);
- an extremum must stand out by a fraction of the signal's robust range (prominence), and events
  of one kind on one side are at least ``min_event_interval_s`` apart;
- per side, strikes and offs must alternate; of two consecutive events of the same kind the less
  prominent one is dropped;
- across the feet, two strikes closer than the shortest plausible step are not both kept (see
  :func:`_exclusive_strikes`), and a cycle needs one strike of the other foot inside it (see
  :func:`gaitcap.gait.cycles.find_cycles`).
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.signal import find_peaks, peak_prominences

from gaitcap.errors import InputError
from gaitcap.gait.options import GaitOptions
from gaitcap.gait.signals import fill_short_gaps, lowpass, parabolic_peak, velocity
from gaitcap.timeseries import finite_runs
from gaitcap.trajectory import SIDES, TOE_RELEASES, TRACKED_FORMAT, GaitEvent, Side, Trajectory, side_suffix

log = logging.getLogger("gaitcap.gait.events")

SOURCE = "zeni2008"
SOURCE_REFINED = "zeni2008+refined"


@dataclass(frozen=True)
class WalkingDirection:
    """The horizontal walking direction of a trial.

    Attributes:
        forward: unit vector (3,), horizontal (z = 0), the direction of progression.
        left: unit vector (3,), horizontal, ``up x forward`` (points to the subject's left).
        method: ``"pelvis displacement"`` or ``"swing foot velocity"``.
        pelvis_speed_m_s: net horizontal speed of the pelvis along ``forward``.
        in_place: True when the pelvis barely progresses (treadmill or progression removed).
    """

    forward: np.ndarray
    left: np.ndarray
    method: str
    pelvis_speed_m_s: float
    in_place: bool


def _point_or(traj: Trajectory, *names: str) -> np.ndarray:
    """The first of ``names`` present in the trajectory, shape (T, 3)."""
    for n in names:
        if traj.has(n):
            return traj.point(n)
    raise InputError(f"trajectory has none of the points {', '.join(names)} needed for gait analysis")


def pelvis_track(traj: Trajectory) -> np.ndarray:
    """Pelvis position, shape (T, 3): the ``pelvis`` point, else the mid-point of the hip centres."""
    if traj.has("pelvis") and np.isfinite(traj.point("pelvis")).any():
        return traj.point("pelvis")
    return 0.5 * (_point_or(traj, "hip_l") + _point_or(traj, "hip_r"))


def heel_track(traj: Trajectory, side: Side) -> np.ndarray:
    """Heel position (T, 3) of one side; the ankle centre if the trajectory has no heel."""
    s = side_suffix(side)
    return _point_or(traj, f"heel{s}", f"ankle{s}")


def toe_track(traj: Trajectory, side: Side) -> np.ndarray:
    """Toe position (T, 3) of one side; the heel (then ankle) if the trajectory has no toe."""
    s = side_suffix(side)
    return _point_or(traj, f"toe{s}", f"heel{s}", f"ankle{s}")


def _unit_horizontal(v: np.ndarray) -> np.ndarray:
    v = np.array([v[0], v[1], 0.0])
    n = np.linalg.norm(v)
    if not np.isfinite(n) or n < 1e-12:
        raise InputError("cannot estimate the walking direction: no horizontal motion")
    return v / n


def _principal_axis(xy: np.ndarray) -> np.ndarray:
    """Unit principal axis (2,) of a cloud of 2D points or vectors (N, 2) about its mean."""
    c = xy - xy.mean(axis=0)
    _, _, vt = np.linalg.svd(c, full_matrices=False)
    return vt[0]


def estimate_walking_direction(traj: Trajectory, options: GaitOptions | None = None) -> WalkingDirection:
    """Estimate the horizontal walking direction.

    Primary: the principal axis of the pelvis horizontal positions, oriented by the net
    displacement. Fallback, when the pelvis barely progresses (net speed below
    ``treadmill_speed_ratio`` x the swing-foot speed, as on a treadmill or in a walk-in-place
    recording): the principal axis of the fast (swing) horizontal foot velocities, oriented so that
    the fastest foot motion is forward (the swing foot always moves forward relative to the lab).

    Raises:
        InputError: no usable pelvis/foot samples.
    """
    opt = options or GaitOptions()
    rate = traj.rate_hz
    pel = pelvis_track(traj)[:, :2]
    ok = np.all(np.isfinite(pel), axis=1)
    if ok.sum() < 2:  # before the feet's signals, which cannot be filtered without a sample (a trajectory of no frame)
        raise InputError("cannot estimate the walking direction: too few valid pelvis and heel samples")
    feet = [fill_short_gaps(heel_track(traj, s)[:, :2], int(opt.max_gap_s * rate)) for s in SIDES]
    vel = np.concatenate([velocity(lowpass(f, rate, opt.lowpass_hz), rate) for f in feet])
    vel = vel[np.all(np.isfinite(vel), axis=1)]
    if ok.sum() < 2 or len(vel) < 4:
        raise InputError("cannot estimate the walking direction: too few valid pelvis and heel samples")
    speed = np.linalg.norm(vel, axis=1)
    fast = vel[speed >= np.quantile(speed, 0.8)]
    swing_speed = float(np.median(np.linalg.norm(fast, axis=1)))

    idx = np.flatnonzero(ok)
    duration = (idx[-1] - idx[0]) / rate
    net = pel[idx[-1]] - pel[idx[0]]
    axis = _principal_axis(pel[ok]) if ok.sum() >= 3 else net
    if np.dot(axis, net) < 0:
        axis = -axis
    pelvis_speed = float(abs(np.dot(axis, net)) / duration) if duration > 0 else 0.0
    in_place = pelvis_speed < opt.treadmill_speed_ratio * swing_speed
    if not in_place:
        fwd, method = _unit_horizontal(axis), "pelvis displacement"
    else:
        # uncentred second moment: the fast velocities are all roughly +/- along the walking axis
        _, _, vt = np.linalg.svd(fast, full_matrices=False)
        ax = vt[0]
        # the swing foot is the fastest and moves forward: orient by the sign of the fastest samples
        top = fast[np.argsort(np.linalg.norm(fast, axis=1))[-max(3, len(fast) // 4) :]]
        if np.sum(top @ ax) < 0:
            ax = -ax
        fwd, method = _unit_horizontal(ax), "swing foot velocity"
    left = np.cross([0.0, 0.0, 1.0], fwd)
    log.debug("walking direction %s (%s), pelvis speed %.3f m/s", fwd.round(3), method, pelvis_speed)
    return WalkingDirection(fwd, left, method, float(np.dot(fwd[:2], net) / duration) if duration else 0.0, in_place)


@dataclass(frozen=True)
class _Extremum:
    frame: float  # sub-frame index
    prominence: float
    side: Side
    event: str
    edge: str = ""  # "start" / "end": second / next-to-last sample of a run, its turn seen on one sample


def _phase(a: _Extremum, b: _Extremum) -> str:
    """The phase between two consecutive events of one side: ``"stance"`` or ``"swing"``."""
    return "stance" if a.event == "foot_strike" else "swing"


def _extrema(signal: np.ndarray, rate: float, opt: GaitOptions, maxima: bool) -> list[tuple[float, float, str]]:
    """Interior extrema of a (T,) signal with NaN gaps: list of (sub-frame index, prominence, edge).

    An extremum must drop by ``min_prominence`` x the robust range on both sides, except next to
    the start or end of a run (first/last partial step), where the interior side must and the
    edge side must fall for at least two samples, or for one (the extremum is then the second or
    next-to-last sample, ``edge`` ``"start"`` or ``"end"``: :func:`_in_rhythm` decides).
    """
    y = signal if maxima else -signal
    ok = np.isfinite(y)
    if ok.sum() < 3:
        return []
    min_prom = _min_prominence(y, opt)
    distance = max(1, int(round(opt.min_event_interval_s * rate)))
    found: list[tuple[float, float, str]] = []
    for start, stop in finite_runs(ok):
        seg = y[start:stop]
        if len(seg) < 3:
            continue
        peaks, _ = find_peaks(seg, distance=distance)
        if len(peaks) == 0:
            continue
        _, left_base, right_base = peak_prominences(seg, peaks)
        for p, lb, rb in zip(peaks, left_base, right_base, strict=True):
            drop_l, drop_r = seg[p] - seg[lb], seg[p] - seg[rb]
            edge = ""
            if min(drop_l, drop_r) >= min_prom:
                prom = min(drop_l, drop_r)
            elif lb == 0 and drop_r >= min_prom and (p == 1 or seg[p - 2] < seg[p - 1] < seg[p]):
                prom, edge = drop_r, "start" if p == 1 else ""
            elif rb == len(seg) - 1 and drop_l >= min_prom and (p == len(seg) - 2 or seg[p + 2] < seg[p + 1] < seg[p]):
                prom, edge = drop_l, "end" if p == len(seg) - 2 else ""
            else:
                continue
            found.append((start + parabolic_peak(seg, int(p)), float(prom), edge))
    return found


def _min_prominence(y: np.ndarray, opt: GaitOptions) -> float:
    """The prominence an extremum of the (T,) signal ``y`` needs: a fraction of its robust range."""
    lo, hi = np.nanquantile(y, [0.05, 0.95])
    return opt.min_prominence * max(float(hi - lo), 1e-9)


#: samples by which the toe signal may end before a release and still close on it
_RELEASE_REACH = 2


def _release_offs(toe: np.ndarray, releases: list[float], side: Side, opt: GaitOptions) -> list[_Extremum]:
    """Foot offs where a toe held on the floor through its marker's gap left the foot's reach
    (``Trajectory.meta[TOE_RELEASES]``, :func:`gaitcap.markers.jointcentres.hold_on_floor`).

    The held toe's signal ``toe`` (T,) falls until the release and has no sample after it, so the
    Zeni minimum is the run's last sample, which :func:`_extrema` never takes. A release is taken
    as a foot off at its sub-frame when a finite run of the signal ends within
    :data:`_RELEASE_REACH` samples before it (the toe point may end a little earlier than its
    marker's hold when another marker it is built from ends first), with the fall since the run's
    highest point as its prominence, marked ``edge="end"`` so that :func:`_in_rhythm` checks its
    stance against the others.
    """
    y = -toe
    ok = np.isfinite(y)
    if ok.sum() < 3:
        return []
    min_prom = _min_prominence(y, opt)
    out = []
    for frame in releases:
        last = min(int(np.floor(frame)), len(y) - 1)
        if last < 0 or (last + 1 < len(y) and ok[last + 1]):
            continue  # the signal goes on after the release: the Zeni extremum is interior
        i = last
        while i >= 0 and not ok[i] and last - i < _RELEASE_REACH:
            i -= 1
        if i < 0 or not ok[i]:
            continue
        start = next(a for a, b in finite_runs(ok) if a <= i < b)  # the run the release closes
        prom = float(y[i] - np.min(y[start : i + 1]))
        if prom >= min_prom:
            out.append(_Extremum(float(frame), prom, side, "foot_off", "end"))
    return out


def _alternate(extrema: list[_Extremum]) -> list[_Extremum]:
    """Keep one event per half-cycle: of consecutive same-kind events keep the most prominent, an
    ``edge`` one (a turn seen on one sample) only if both are."""
    out: list[_Extremum] = []
    for e in sorted(extrema, key=lambda e: e.frame):
        if out and out[-1].event == e.event:
            if (not e.edge, e.prominence) > (not out[-1].edge, out[-1].prominence):
                out[-1] = e
            continue
        out.append(e)
    return out


#: :func:`_exclusive_strikes` warns when it drops at least this share of the foot strikes
MANY_DROPPED = 0.2


def _exclusive_strikes(alternating: dict[Side, list[_Extremum]], min_frames: float) -> dict[Side, list[_Extremum]]:
    """Never two foot strikes of different feet closer than ``min_frames``; per side re-alternated.

    The minimum is the shortest plausible step, ``60 / the highest plausible cadence`` (0.24 s at
    250 steps/min, :attr:`gaitcap.gait.options.PlausibleRanges.min_step_s`): after one foot lands,
    the other must lift off, swing and land, which no walker does faster. Two strikes closer than
    that (e.g. both feet "landing" in the same frame when the tracker collapses the legs onto
    each other) are one landing seen twice; the one with the stronger evidence is kept: a turn
    seen on both sides before one seen on one sample only (``edge``), then the larger prominence
    of the Zeni extremum (the earlier on a tie). The foot that loses a strike then has two
    consecutive foot offs, of which :func:`_alternate` keeps the more prominent.
    """
    strikes = sorted((e for side in SIDES for e in alternating[side] if e.event == "foot_strike"), key=lambda e: e.frame)
    kept: list[_Extremum] = []
    dropped: list[_Extremum] = []
    for e in strikes:
        last = next((k for k in reversed(kept) if k.side != e.side), None)
        if last is not None and e.frame - last.frame < min_frames:
            if (not e.edge, e.prominence) > (not last.edge, last.prominence):
                kept.remove(last)
                dropped.append(last)
            else:
                dropped.append(e)
                continue
        kept.append(e)
    for e in dropped:
        log.info("dropped a %s foot strike at frame %.1f: within %.1f frames of the other foot's", e.side, e.frame, min_frames)
    if len(dropped) >= max(2, MANY_DROPPED * len(strikes)):  # not a landing seen twice now and then: a pattern
        log.warning("%d of %d foot strikes dropped as closer than %.1f frames to the other foot's (a step shorter "
                    "than the shortest plausible, plausible.min_step_s): a cadence above the plausible maximum "
                    "(a run?), or legs the tracker collapsed onto each other", len(dropped), len(strikes), min_frames)  # fmt: skip
    return {side: _alternate([e for e in alternating[side] if e not in dropped]) for side in SIDES}


def _phase_durations(events: list[_Extremum]) -> dict[str, list[float]]:
    """Stance and swing durations (frames) between consecutive events of one side, edge events
    left out (``events``: one side's alternating events in time order)."""
    out: dict[str, list[float]] = {"stance": [], "swing": []}
    for a, b in zip(events[:-1], events[1:], strict=True):
        if not (a.edge or b.edge):
            out[_phase(a, b)].append(b.frame - a.frame)
    return out


def _in_rhythm(events: list[_Extremum], other: list[_Extremum], tolerance: float) -> list[_Extremum]:
    """Drop the ``edge`` events (a turn seen on one sample only) that break the rhythm.

    ``events`` are one side's alternating events in time order, ``other`` the other side's. An
    edge event closes (at the end of a run) or opens (at its start) a stance or swing phase with
    its neighbour inside the run; it is kept only if that phase lasts within ``tolerance``
    (relative) of the median of the same phase between this side's other events (the other
    side's when this side has none). Without any such reference it is dropped.
    """
    own, contra = _phase_durations(events), _phase_durations(other)
    keep = []
    for i, e in enumerate(events):
        if e.edge:
            j = i - 1 if e.edge == "end" else i + 1  # the neighbour on the run's side
            if not 0 <= j < len(events):
                continue
            a, b = (events[j], e) if j < i else (e, events[j])
            typical = own[_phase(a, b)] or contra[_phase(a, b)]
            if not typical or abs((b.frame - a.frame) / float(np.median(typical)) - 1.0) > tolerance:
                log.debug("dropped a %s %s at frame %.1f: out of the rhythm", e.side, e.event, e.frame)
                continue
        keep.append(e)
    return keep


def zeni_signals(
    traj: Trajectory, direction: WalkingDirection, options: GaitOptions | None = None
) -> dict[str, np.ndarray]:
    """The pelvis-relative heel and toe coordinates along the walking direction (filtered).

    Returns:
        ``{"heel_l", "heel_r", "toe_l", "toe_r"}`` -> shape (T,) metres, NaN where missing.
    """
    opt = options or GaitOptions()
    rate = traj.rate_hz
    gap = int(round(opt.max_gap_s * rate))
    pel = pelvis_track(traj)
    out: dict[str, np.ndarray] = {}
    for side in SIDES:
        s = side_suffix(side)
        for name, track in (("heel", heel_track(traj, side)), ("toe", toe_track(traj, side))):
            rel = (track - pel) @ direction.forward
            out[f"{name}{s}"] = lowpass(fill_short_gaps(rel, gap), rate, opt.lowpass_hz)
    return out


def window_scale(alternating: dict[Side, list[_Extremum]], rate_hz: float, opt: GaitOptions) -> float:
    """The factor (>= 1) by which the refinement's windows widen: the median stride between
    consecutive foot strike anchors of one foot (both feet pooled), in seconds, over
    ``opt.window_stride_s``; 1 for a stride no longer than that, or without two strikes of a foot."""
    strides = [
        b.frame - a.frame
        for side in SIDES
        for a, b in itertools.pairwise([e for e in alternating[side] if e.event == "foot_strike"])
    ]
    if not strides:
        return 1.0
    return max(1.0, float(np.median(strides)) / rate_hz / opt.window_stride_s)


def _refiners(
    traj: Trajectory, side: Side, direction: WalkingDirection, opt: GaitOptions, scale: float = 1.0
) -> dict[str, Callable[[float], float | None]]:
    """Local refinement of the Zeni anchors (see the module docstring), by event kind.

    Each refiner maps an anchor (sub-frame index) to a refined sub-frame index, or None when the
    local criterion is not found in its window (the anchor is then kept). ``scale`` widens both
    windows (:func:`window_scale`: a slow walk's strides).
    """
    rate = traj.rate_hz
    strike_window_s, off_window_s = opt.strike_window_s * scale, opt.off_window_s * scale
    gap = int(round(opt.max_gap_s * rate))
    heel_vz = velocity(lowpass(fill_short_gaps(heel_track(traj, side), gap), rate, opt.lowpass_hz), rate)[:, 2]
    toe = lowpass(fill_short_gaps(toe_track(traj, side), gap), rate, opt.lowpass_hz)
    toe_acc = velocity(velocity(toe, rate), rate) @ direction.forward

    def strike(anchor: float) -> float | None:
        # the heel's lowest point: first upward zero crossing of its vertical velocity
        i0, i1 = int(np.floor(anchor)), min(len(heel_vz) - 1, int(np.ceil(anchor + strike_window_s * rate)))
        for k in range(max(i0, 0), i1):
            a, b = heel_vz[k], heel_vz[k + 1]
            if np.isfinite(a) and np.isfinite(b) and a < 0 <= b:
                return max(anchor, k + a / (a - b))
        return None

    def off(anchor: float) -> float | None:
        # the toe's peak forward acceleration (Hreljac & Marshall 2000) near the anchor
        i0 = max(1, int(np.floor(anchor - 0.5 * off_window_s * rate)))
        i1 = min(len(toe_acc) - 1, int(np.ceil(anchor + off_window_s * rate)))
        w = toe_acc[i0:i1]
        if len(w) < 3 or not np.isfinite(w).all():
            return None
        k = int(np.argmax(w))
        if k == 0 or k == len(w) - 1:
            return None  # no interior maximum in the window
        return parabolic_peak(toe_acc, i0 + k)

    return {"foot_strike": strike, "foot_off": off}


def refines(traj: Trajectory, opt: GaitOptions) -> bool:
    """Whether the events of ``traj`` are refined from their anchors (see the module docstring):
    ``refine`` on, sampled at ``refine_min_rate_hz`` or faster, and not a tracking run's trajectories
    unless ``refine_tracked``."""
    tracked = traj.meta.get("format") == TRACKED_FORMAT
    return opt.refine and traj.rate_hz >= opt.refine_min_rate_hz and (opt.refine_tracked or not tracked)


def detect_events(
    traj: Trajectory, options: GaitOptions | None = None, direction: WalkingDirection | None = None
) -> tuple[list[GaitEvent], WalkingDirection]:
    """Foot strikes and foot offs of both feet (Zeni et al. 2008, see the module docstring).

    Args:
        traj: joint-centre (or marker) trajectory with pelvis (or hips), heels (or ankles), toes.
        options: detection settings.
        direction: walking direction; estimated from ``traj`` if not given.

    Returns:
        The events sorted by time (times on the trajectory's axis, sub-frame), and the direction.
    """
    opt = options or GaitOptions()
    direction = direction or estimate_walking_direction(traj, opt)
    sig = zeni_signals(traj, direction, opt)
    alternating: dict[Side, list[_Extremum]] = {}
    for side in SIDES:
        s = side_suffix(side)
        ext = [_Extremum(f, p, side, "foot_strike", x) for f, p, x in _extrema(sig[f"heel{s}"], traj.rate_hz, opt, True)]
        ext += [_Extremum(f, p, side, "foot_off", x) for f, p, x in _extrema(sig[f"toe{s}"], traj.rate_hz, opt, False)]
        ext += _release_offs(sig[f"toe{s}"], traj.meta.get(TOE_RELEASES, {}).get(side, []), side, opt)
        alternating[side] = _alternate(ext)
    alternating = _exclusive_strikes(alternating, opt.plausible.min_step_s * traj.rate_hz)
    events: list[GaitEvent] = []
    scale = window_scale(alternating, traj.rate_hz, opt)
    if scale > 1.0:
        log.debug("refinement windows widened x%.2f for strides of %.2f s", scale, scale * opt.window_stride_s)
    for side, other in zip(SIDES, SIDES[::-1], strict=True):
        refined = _refiners(traj, side, direction, opt, scale) if refines(traj, opt) else None
        for e in _in_rhythm(alternating[side], alternating[other], opt.edge_rhythm_tolerance):
            frame, source = e.frame, SOURCE
            if refined is not None:
                better = refined[e.event](e.frame)
                if better is not None:
                    frame, source = better, SOURCE_REFINED
            events.append(GaitEvent(traj.t0_s + frame / traj.rate_hz, side, e.event, source))  # type: ignore[arg-type]
    events.sort()
    log.debug("detected %d gait events (%s)", len(events), direction.method)
    return events, direction
