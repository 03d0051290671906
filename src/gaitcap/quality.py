"""A run's verdict and its calibrated per-point uncertainty, computed after tracking from what the
tracker recorded (``trajectories.h5``: raw points, fit, quality flags; the calibration).

Signals of the whole run (:func:`run_signals`), each a physical check that a correct fit of a
walking person passes:

- the fraction of frames flagged (fit below ``quality.min_fit``, subject out of view...);
- the fraction of tracked frames whose ankles *cross*: the left ankle on the right of the right
  ankle along the hips' axis. A walking person's feet keep their sides (the truth of every suite
  walk keeps them 5 cm apart or more); crossed ankles are the mark of legs swapped below the hips;
- the tracked frames whose ankles are *out of the stride's rhythm* fore and aft: a walk swings
  the feet past each other twice a stride, so the left ankle's lead over the right one along the
  walking line, d(t), follows a sinusoid at the stride frequency f. A stretch of frames with the
  legs exchanged fore and aft (the left leg tracked on the right leg's pixels and back, each foot
  still on its own side) flips d's sign there: its ankles do not cross, and the events detected
  from them alternate as usual with the sides exchanged. f is found from |d|, which an exchange
  leaves unchanged (its fundamental is 2 f: the feet pass each other twice a stride), then

      d(t) ~ a cos 2 pi f t + b sin 2 pi f t      (least squares over the tracked frames)

  and a frame is out of rhythm where that sinusoid puts the legs well apart (beyond half its
  amplitude: 60 degrees of phase either side of a peak) and d has the other sign by more than
  ``exchanged_margin_m``. The run is judged in pieces of :data:`RHYTHM_STRIDES` strides, each with
  its own walking line and frequency (the cadence drifts, a walk turns), and apart before and after
  each point where the walk turns back (:func:`turns`: a subject walking up and down the room; the
  stride's phase starts afresh there); the frames where the pelvis pauses at such a turn (a pivot
  on the spot, :func:`turning_on_the_spot`) are not judged, nor fitted; nor are those where the
  subject stands still in the middle of a walk (:func:`standing_still`), after which the phase
  starts afresh too;
- the lowest foot point's height above the floor, median over the frames: one foot stands on the
  floor in every frame of a walk (z = 0 in the calibration's world frame); a model floating above
  it, or sunk into it, has collapsed onto something else;
- thigh and shank lengths against the usual proportions for the subject's height (the body
  model's own, body.yaml: 0.245 H and 0.246 H);
- the subject's height in each camera's image (pixels): a small figure leaves the limbs a few
  pixels wide;
- the frames whose lower-limb points' mean calibrated uncertainty (below) is above
  ``uncertain_mm``: a run that jitters or fits poorly through much of its length (the baseline
  trackers, a body scaled to a wrong height) is off by centimetres where no other check sees it;
- (a note, not a reason: it leaves the verdict as it is) whether some camera views the walk
  obliquely. Seen from beside the walkway a camera sees how far apart the feet are fore and aft
  but not which is on the left; seen along it, the reverse; two such views fit both pairings of
  the feet equally (up to perspective), so which leg is ahead cannot be told. A camera whose line of sight lies ``min_oblique_deg`` or more from both the
  walking line and its perpendicular sees a mix of both separations and tells them apart. The
  walking line is the principal horizontal axis of the tracked pelvis, or the way the hips face
  for a walk on the spot (a treadmill);
- (a note too) whether the tracked body faces against its motion: the way the hips face (their
  axis turned a quarter-turn about the vertical, the left hip on the left) against the pelvis's
  horizontal velocity, over the frames where it moves at
  :data:`~gaitcap.gait.passes.MIN_SPEED_M_S` or more. A subject
  walking backwards does (a rehabilitation exercise); a subject walking forwards does only if the
  model faces the wrong way, which the legs' rhythm does not reveal (a body facing backwards bends
  its knees to mimic the stride).

:func:`judge` turns them into ``ok`` / ``doubtful`` / ``failed`` with the reasons (and the
camera layout's note), by the thresholds of ``tracking.yaml``'s ``verdict`` section.

:func:`calibrated_uncertainty`: per frame and point, a standard-deviation-like radius (metres) that
grows with what varies with the error (docs/validation.md, scripts/bench_uncertainty.py):

    u = s_p exp(c0 + c_res * log(r) + c_fit * (1 - fit) + c_cross * crossed_run + c_floor * |floor|
            + c_crossed * crossed_frame)

times the point's ``point_scale`` (errors grow down the kinematic chain: hips < knees < ankles),
where r is the point's residual from its own zero-lag low-pass trajectory (the tracker's jitter,
metres), fit the frame's fit, crossed_run the run's crossed-ankle fraction, |floor| the run's foot
height off the floor (metres) and crossed_frame 1 when this frame's ankles cross. The coefficients
are fitted on the validation suite by regressing log |error| on these terms, then c0 is moved so
that 95 % of the lower-limb errors fall within 2 u, and each point's scale so that 95 % of its own
errors do.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Literal

import numpy as np

from gaitcap.body.measures import model_lengths, segment_lengths
from gaitcap.body.model import load_body_model
from gaitcap.gait import passes
from gaitcap.gait.passes import MIN_SPEED_M_S, travel_axis
from gaitcap.io.track_h5 import QUALITY_OK, tracked_frames
from gaitcap.tracking.smoothing import lowpass
from gaitcap.trajectory import LOWER_LIMB

if TYPE_CHECKING:
    from gaitcap.camera import CameraRig
    from gaitcap.tracking.config import UncertaintyConfig, VerdictConfig

log = logging.getLogger(__name__)

Verdict = Literal["ok", "doubtful", "failed"]  # gaitcap.track_summary.VERDICTS
FEET = ("heel_l", "heel_r", "toe_l", "toe_r")
#: the lengths (gaitcap.body.measures) checked against the body model's, each side on its own
SEGMENTS = ("thigh", "shank")


@dataclass(frozen=True)
class RunSignals:
    """What :func:`run_signals` measured on one run.

    Attributes:
        n_frames: frames of the run.
        n_tracked: frames with a pose (fit good or poor; not out of view or not initialised).
        n_ok: frames not flagged.
        n_crossed: tracked frames whose ankles cross.
        floor_m: median over the tracked frames of the lowest foot point's height (metres; NaN
            without frames or feet).
        segment_ratios: ``thigh_l`` ... ``shank_r`` -> median length / usual length for the height.
        image_height_px: camera -> median height of the tracked body in its image (pixels).
        crossed: (T,) bool, the frames whose ankles cross.
        body_problems: the shape calibration's lengths outside ``shape.ranges`` (its body was
            rejected and the shipped proportions tracked; gaitcap.body.measures.outside_ranges).
        view_angles_deg: camera -> angle (0-90 degrees) between its horizontal line of sight to
            the subject and the walking line (empty without cameras).
        exchanged: (T,) bool, the tracked frames whose ankles' fore-aft order goes against the
            stride's rhythm (:func:`out_of_rhythm`): legs possibly exchanged fore and aft.
        moving_backwards: (frames moving against the way the hips face, frames moving, first
            and last frame) of the tracked frames' stretch between turns that does so most
            (:func:`moving_backwards`).
        leg_support: segment (:data:`LEG_SEGMENTS`, :data:`FOOT_SEGMENTS`) -> (T,) its lowest share
            over the cameras of drawn pixels on the silhouettes
            (:func:`gaitcap.tracking.support.segment_support`; NaN: not judged), empty when not measured.
        n_uncertain: tracked frames whose lower-limb points' mean calibrated uncertainty is above the
            verdict's ``uncertain_mm`` (:func:`assess`; 0 when not measured).
        out_of_step: the cameras whose videos look out of step, in words
            (:func:`gaitcap.sync_check.out_of_step_listing`; empty: none found or not checked).
    """

    n_frames: int
    n_tracked: int
    n_ok: int
    n_crossed: int
    floor_m: float
    segment_ratios: dict[str, float] = field(default_factory=dict)
    image_height_px: dict[str, float] = field(default_factory=dict)
    crossed: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    body_problems: tuple[str, ...] = ()
    view_angles_deg: dict[str, float] = field(default_factory=dict)
    exchanged: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    moving_backwards: tuple[int, int, int, int] = (0, 0, 0, 0)
    leg_support: dict[str, np.ndarray] = field(default_factory=dict)
    n_uncertain: int = 0
    out_of_step: str = ""

    @property
    def n_exchanged(self) -> int:
        return int(np.sum(self.exchanged))

    @property
    def crossed_fraction(self) -> float:
        return self.n_crossed / self.n_tracked if self.n_tracked else 0.0

    @property
    def flagged_fraction(self) -> float:
        return 1.0 - self.n_ok / self.n_frames if self.n_frames else 1.0


@dataclass(frozen=True)
class RunVerdict:
    """``verdict``, ``verdict_reasons`` and ``verdict_notes`` of ``track.json``: the notes name what
    makes an error more likely without being one (they leave the verdict as it is)."""

    verdict: Verdict
    reasons: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, object]:
        return {"verdict": self.verdict, "verdict_reasons": list(self.reasons), "verdict_notes": list(self.notes)}


def _check_shapes(points: np.ndarray, names: tuple[str, ...], quality: np.ndarray) -> None:
    if points.ndim != 3 or points.shape[1:] != (len(names), 3):
        raise ValueError(f"points must have shape (T, {len(names)}, 3), got {points.shape}")
    if quality.shape != (points.shape[0],):
        raise ValueError(f"quality must have shape ({points.shape[0]},), got {quality.shape}")


def crossed_ankles(points: np.ndarray, names: tuple[str, ...], margin_m: float = 0.0) -> np.ndarray:
    """(T,) bool: frames whose left ankle lies more than ``margin_m`` on the right of the right
    ankle along the hips' axis (horizontal plane), from points (T, P, 3). False where a point is
    missing."""
    idx = {n: names.index(n) for n in ("hip_l", "hip_r", "ankle_l", "ankle_r")}
    hips = points[:, idx["hip_l"], :2] - points[:, idx["hip_r"], :2]
    ankles = points[:, idx["ankle_l"], :2] - points[:, idx["ankle_r"], :2]
    with np.errstate(invalid="ignore", divide="ignore"):
        lateral = np.sum(hips * ankles, axis=1) / np.linalg.norm(hips, axis=1)
    return np.nan_to_num(lateral, nan=np.inf) < -margin_m


def _floor_height(points: np.ndarray, names: tuple[str, ...]) -> float:
    feet = [names.index(n) for n in FEET if n in names]
    if not feet or not len(points):
        return float("nan")
    lowest = np.min(points[:, feet, 2], axis=1)
    lowest = lowest[np.isfinite(lowest)]
    return float(np.median(lowest)) if len(lowest) else float("nan")


def _segment_ratios(points: np.ndarray, names: tuple[str, ...], height_m: float) -> dict[str, float]:
    """``thigh_l`` ... ``shank_r`` -> median length (gaitcap.body.measures, each side on its own)
    over the shipped body model's length at ``height_m`` (its proportions, per metre of height)."""
    usual = model_lengths(load_body_model(height_m=1.0))
    per_side = {}
    for side, other in (("_l", "_r"), ("_r", "_l")):
        one_side = [n if not n.endswith(other) else "" for n in names]  # the other side's points left out
        per_side[side] = segment_lengths(one_side, points) if len(points) else {}
    return {seg + side: per_side[side][seg] / (usual[seg] * height_m) for seg in SEGMENTS for side in ("_l", "_r")
            if seg in per_side[side]}  # fmt: skip


def walking_line(points: np.ndarray, names: tuple[str, ...]) -> np.ndarray | None:
    """Unit horizontal vector (2,) of the walking line of points (T, P, 3): the principal horizontal
    axis of the pelvis positions when they travel (:func:`gaitcap.gait.passes.travel_axis`), else
    the perpendicular of the hips' mean horizontal axis (walking on the spot); None when neither can
    be measured (NaN frames ignored)."""
    axis = _travel_axis(points, names)
    if axis is not None:
        return axis
    if "hip_l" not in names or "hip_r" not in names:
        return None
    hips = points[:, names.index("hip_l"), :2] - points[:, names.index("hip_r"), :2]
    hips = hips[np.all(np.isfinite(hips), axis=1)]
    mean = hips.mean(axis=0) if len(hips) else np.zeros(2)
    norm = float(np.linalg.norm(mean))
    return np.array([-mean[1], mean[0]]) / norm if norm > 1e-9 else None


def _travel_axis(points: np.ndarray, names: tuple[str, ...]) -> np.ndarray | None:
    """:func:`gaitcap.gait.passes.travel_axis` of the pelvis of points (T, P, 3); None without one."""
    return travel_axis(points[:, names.index("pelvis"), :2]) if "pelvis" in names else None


#: a stretch between turns is judged for moving backwards when it moves in this many seconds of frames
MIN_STRETCH_S = 1.0


def pelvis_velocity(points: np.ndarray, names: tuple[str, ...], rate_hz: float) -> np.ndarray:
    """(T, 2) m/s: :func:`gaitcap.gait.passes.pelvis_velocity` of the pelvis of points (T, P, 3)."""
    return passes.pelvis_velocity(points[:, names.index("pelvis"), :2], rate_hz)


def moving_backwards(points: np.ndarray, names: tuple[str, ...], rate_hz: float) -> tuple[int, int, int, int]:
    """Where the tracked body moves against the way its hips face, in points (T, P, 3) sampled at
    ``rate_hz``: (frames moving so, frames moving, first frame, last frame) of the stretch between
    turns (:func:`turns`) with the largest share of such frames, among those that move in
    :data:`MIN_STRETCH_S` of frames or more; (0, 0, 0, 0) without one. The velocity is the pelvis's
    (:func:`pelvis_velocity`), moving at :data:`~gaitcap.gait.passes.MIN_SPEED_M_S` or more; the hips
    face (y, -x) of the left-minus-right hip (x, y) (z up). NaN frames count as neither; a pelvis
    without a travel axis (:func:`gaitcap.gait.passes.travel_axis`) moves in no frame (a walk on the
    spot, whose sway and jitter a 0.4 s span can take for motion). A subject
    who turns round while the model keeps facing the first way moves backwards after the turn only:
    hence the stretches."""
    none = (0, 0, 0, 0)
    if not {"pelvis", "hip_l", "hip_r"} <= set(names) or _travel_axis(points, names) is None:
        return none
    velocity = pelvis_velocity(points, names, rate_hz)
    T = len(points)
    if not np.isfinite(velocity).any():
        return none
    hips = points[:, names.index("hip_l"), :2] - points[:, names.index("hip_r"), :2]
    facing = np.stack([hips[:, 1], -hips[:, 0]], axis=1)
    with np.errstate(invalid="ignore"):
        moving = np.linalg.norm(velocity, axis=1) >= MIN_SPEED_M_S
        against = moving & (np.sum(velocity * facing, axis=1) < 0)
    bounds = [0, *turns(points, names).tolist(), T]
    best, share = none, -1.0
    for a, b in zip(bounds[:-1], bounds[1:]):
        n, k = int(moving[a:b].sum()), int(against[a:b].sum())
        if n >= MIN_STRETCH_S * rate_hz and k / n > share:
            best, share = (k, n, a, b - 1), k / n
    return best


def view_angles(points: np.ndarray, names: tuple[str, ...], rig: CameraRig | None) -> dict[str, float]:
    """camera -> angle in degrees (0: along the walking line, 90: square to it) between each camera's
    horizontal line of sight to the subject's mean position and the walking line
    (:func:`walking_line`) of points (T, P, 3); empty without cameras or a walking line."""
    line = walking_line(points, names)
    where = points[:, names.index("pelvis") if "pelvis" in names else 0, :2]
    where = where[np.all(np.isfinite(where), axis=1)]
    if rig is None or line is None or not len(where):
        return {}
    out = {}
    for cam in rig:
        sight = cam.center[:2] - where.mean(axis=0)
        cos = abs(float(sight @ line)) / max(float(np.linalg.norm(sight)), 1e-9)
        out[cam.name] = float(np.degrees(np.arccos(min(cos, 1.0))))
    return out


#: stride frequencies (Hz) searched for a run's rhythm: a slow walk to a run
STRIDE_HZ = (0.3, 1.6)
#: step (Hz) of that search
STRIDE_HZ_STEP = 0.005
#: a run is judged for its rhythm in pieces of about this many strides (at least one piece)
RHYTHM_STRIDES = 3
#: a frame's fore-aft order is judged where the rhythm puts the legs beyond this fraction of their
#: largest separation (0.5: 60 degrees of phase either side of a peak)
APART = 0.5


def fore_aft(points: np.ndarray, names: tuple[str, ...], line: np.ndarray) -> np.ndarray:
    """(T,) metres: the left ankle's lead over the right one along the unit horizontal ``line`` (2,),
    or each frame's own (T, 2), from points (T, P, 3); NaN where a point is missing."""
    apart = points[:, names.index("ankle_l"), :2] - points[:, names.index("ankle_r"), :2]
    return apart @ line if line.ndim == 1 else np.einsum("tk,tk->t", apart, line)


def _sinusoids(t: np.ndarray, hz: float | np.ndarray) -> np.ndarray:
    """cos and sin of 2 pi hz t: (len(t), 2) for one frequency, (H, len(t), 2) for H of them."""
    w = 2 * np.pi * np.multiply.outer(hz, t)
    return np.stack([np.cos(w), np.sin(w)], axis=-1)


#: frequencies whose sinusoids :func:`stride_frequency` holds at once: its memory is a few
#: times this many by the run's length, whatever the number of frequencies searched
_HZ_CHUNK = 16


def stride_frequency(t: np.ndarray, d: np.ndarray) -> float:
    """The stride frequency (Hz) of a fore-aft separation d (T,) (finite values) at times t (T,)
    (seconds): the frequency in :data:`STRIDE_HZ` at twice which a sinusoid plus a constant best
    fits |d| (least squares). |d| does not change when the legs are exchanged, and falls to zero
    twice a stride, where the feet pass each other."""
    hz = np.arange(STRIDE_HZ[0], STRIDE_HZ[1] + 1e-9, STRIDE_HZ_STEP)
    y = np.abs(d) - np.mean(np.abs(d))
    explained = np.concatenate([_explained(t, y, 2 * hz[i:i + _HZ_CHUNK])
                                for i in range(0, len(hz), _HZ_CHUNK)])  # fmt: skip
    return float(hz[int(np.argmax(explained))])


def _explained(t: np.ndarray, y: np.ndarray, hz: np.ndarray) -> np.ndarray:
    """(H,): how much a sinusoid plus a constant at each frequency of hz (H,) lowers the sum of
    squares of y (T,) (zero mean) at times t (T,), by least squares."""
    A = _sinusoids(t, hz)  # (H, T, 2)
    A -= A.mean(axis=1, keepdims=True)  # the constant's share taken out
    G = np.einsum("htj,htk->hjk", A, A) + 1e-12 * np.eye(2)  # normal equations of each frequency
    b = np.einsum("htj,t->hj", A, y)
    return np.einsum("hj,hj->h", b, np.linalg.solve(G, b[..., None])[..., 0])  # the residual's drop


def _separation(points: np.ndarray, names: tuple[str, ...], rate_hz: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The frames (n,) of points (T, P, 3) with both ankles and their fore-aft separation (n,)
    along the walking line of those frames; None without a walking line or under one stride of
    the fastest rhythm."""
    frames = np.flatnonzero(np.all(np.isfinite(points[:, [names.index("ankle_l"), names.index("ankle_r")], :2]),
                                   axis=(1, 2)))  # fmt: skip
    line = walking_line(points[frames], names)
    if line is None or len(frames) < rate_hz / STRIDE_HZ[1]:
        return None
    return frames, fore_aft(points[frames], names, line)


def _piece_out_of_rhythm(points: np.ndarray, names: tuple[str, ...], rate_hz: float, margin_m: float) -> np.ndarray:
    """:func:`out_of_rhythm` of one piece of a run, points (T, P, 3) NaN where not tracked."""
    out = np.zeros(len(points), bool)
    measured = _separation(points, names, rate_hz)
    if measured is None:
        return out
    frames, d = measured
    t = frames / rate_hz
    A = _sinusoids(t, stride_frequency(t, d))
    coef = np.linalg.lstsq(A, d, rcond=None)[0]
    rhythm = A @ coef
    apart = np.abs(rhythm) > APART * float(np.hypot(*coef))
    out[frames] = apart & (d * np.sign(rhythm) < -margin_m)
    return out


def out_of_rhythm(points: np.ndarray, names: tuple[str, ...], tracked: np.ndarray, rate_hz: float,
                  margin_m: float) -> np.ndarray:  # fmt: skip
    """(T,) bool: the tracked frames (``tracked`` (T,) bool) of points (T, P, 3) sampled at
    ``rate_hz`` whose ankles' fore-aft order goes against the stride's rhythm by more than
    ``margin_m`` (metres): legs possibly exchanged fore and aft (see the module docstring). The run
    is cut into pieces of about :data:`RHYTHM_STRIDES` strides at the whole run's stride
    frequency, each judged on its own; a run without a walking line or shorter than one stride is
    never out of it."""
    if rate_hz <= 0:
        raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
    if tracked.shape != (len(points),):
        raise ValueError(f"tracked must have shape ({len(points)},), got {tracked.shape}")
    pts = np.where(tracked[:, None, None], points, np.nan)
    at = turns(pts, names)
    pts[turning_on_the_spot(pts, names, rate_hz, at)] = np.nan
    still = standing_still(pts, names, rate_hz)
    pts[still] = np.nan
    restarts = np.flatnonzero(np.diff(still.astype(np.int8)) == -1) + 1  # a walk resumed: a new phase
    measured = _separation(pts, names, rate_hz)
    if measured is None:
        return np.zeros(len(points), bool)
    stride = rate_hz / stride_frequency(measured[0] / rate_hz, measured[1])  # frames
    pieces = []
    for leg in np.split(np.arange(len(points)), np.union1d(at, restarts).astype(int)):
        n_pieces = max(1, int(len(leg) // (RHYTHM_STRIDES * stride)))
        pieces += np.array_split(leg, n_pieces)
    return np.concatenate([_piece_out_of_rhythm(pts[idx], names, rate_hz, margin_m) for idx in pieces])


def turning_on_the_spot(points: np.ndarray, names: tuple[str, ...], rate_hz: float, at: np.ndarray) -> np.ndarray:
    """(T,) bool: the frames of points (T, P, 3) sampled at ``rate_hz`` where the pelvis pauses at a
    turn (``at``: :func:`turns`; :func:`gaitcap.gait.passes.paused_at_turns`). A subject who stops
    and pivots steps round on the spot there: the feet's fore-aft order along the walking line then
    follows the pivot, not a stride's rhythm. None without a turn (nor without a pelvis: no turn)."""
    if not len(at):
        return np.zeros(len(points), bool)
    return passes.paused_at_turns(points[:, names.index("pelvis"), :2], rate_hz, at)


#: the points whose horizontal paths say a subject stands still (:func:`standing_still`)
STILL_POINTS = ("pelvis", "heel_l", "toe_l", "heel_r", "toe_r")


def standing_still(points: np.ndarray, names: tuple[str, ...], rate_hz: float) -> np.ndarray:
    """(T,) bool: the frames of points (T, P, 3) sampled at ``rate_hz`` where the subject stands still
    (:func:`gaitcap.gait.passes.stops` of the pelvis, heels and toes): a stop in the middle of a walk,
    whose feet keep the order of the last step rather than the stride's rhythm. All False without
    those points."""
    out = np.zeros(len(points), bool)
    if not all(n in names for n in STILL_POINTS):
        return out
    tracks = points[:, [names.index(n) for n in STILL_POINTS], :2]
    for a, b in passes.stops(tracks, rate_hz):
        out[a:b] = True
    return out


def turns(points: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """(K,) int, increasing: the frames of points (T, P, 3) just after each point where the walk
    turns back (:func:`gaitcap.gait.passes.turns` of the pelvis). A turn restarts the stride's phase:
    before and after it the fore-aft rhythm is judged apart. Empty without a pelvis."""
    return passes.turns(points[:, names.index("pelvis"), :2]) if "pelvis" in names else np.zeros(0, int)


def _image_heights(points: np.ndarray, rig: CameraRig | None) -> dict[str, float]:
    if rig is None or not len(points):
        return {}
    out = {}
    for cam in rig:
        v = cam.project(points)[..., 1]  # (T, P)
        v = v[np.isfinite(v).any(axis=1)]
        if len(v):
            out[cam.name] = float(np.median(np.nanmax(v, axis=1) - np.nanmin(v, axis=1)))
    return out


def run_signals(points: np.ndarray, names: tuple[str, ...], quality: np.ndarray, height_m: float,
                rig: CameraRig | None = None, crossed_margin_m: float = 0.0, *, rate_hz: float,
                exchanged_margin_m: float = 0.03) -> RunSignals:  # fmt: skip
    """The run-level signals (see the module docstring) of the tracker's raw points (T, P, 3)
    (``points_unfiltered``) sampled at ``rate_hz``, per-frame quality (T,) and the subject's height
    (metres); the image heights need the cameras ``rig``; ankles count as crossed beyond
    ``crossed_margin_m`` and out of the stride's rhythm beyond ``exchanged_margin_m`` (metres)."""
    points, quality = np.asarray(points, float), np.asarray(quality)
    _check_shapes(points, names, quality)
    tracked = tracked_frames(quality)
    pts = points[tracked]
    crossed = crossed_ankles(points, names, crossed_margin_m) & tracked
    return RunSignals(
        n_frames=len(quality), n_tracked=int(tracked.sum()), n_ok=int(np.sum(quality == QUALITY_OK)),
        n_crossed=int(crossed.sum()), floor_m=_floor_height(pts, names),
        segment_ratios=_segment_ratios(pts, names, height_m), image_height_px=_image_heights(pts, rig),
        crossed=crossed, view_angles_deg=view_angles(pts, names, rig),
        exchanged=out_of_rhythm(points, names, tracked, rate_hz, exchanged_margin_m),
        moving_backwards=moving_backwards(np.where(tracked[:, None, None], points, np.nan), names, rate_hz),
    )  # fmt: skip


def _leg_doubts(s: RunSignals, cfg: VerdictConfig) -> tuple[bool, bool]:
    """Whether the verdict doubts the legs: (ankles crossed too often, out of the stride's rhythm too often)."""
    return bool(s.n_tracked and s.crossed_fraction >= cfg.max_crossed_fraction), s.n_exchanged >= cfg.min_exchanged_frames


def legs_in_doubt(points: np.ndarray, names: tuple[str, ...], rate_hz: float, cfg: VerdictConfig) -> int:
    """How many frames of a run tracked throughout, points (T, P, 3) sampled at ``rate_hz``, make the
    verdict doubt its legs (:func:`judge`: the frames whose ankles cross, when they are too many,
    plus those out of the stride's rhythm, when they are too many), plus those of the note on a body
    moving against the way it faces (:func:`moving_backwards`: the frames moving so in its stretch,
    when they are most of it: a turn the model did not follow, its knees bent the wrong way in the
    stride's rhythm; or a subject walking backwards, whose fresh start then agrees); 0 when none."""
    points = np.asarray(points, float)
    crossed = crossed_ankles(points, names, cfg.crossed_margin_m)
    exchanged = out_of_rhythm(points, names, np.ones(len(points), bool), rate_hz, cfg.exchanged_margin_m)
    T = len(points)
    signals = RunSignals(n_frames=T, n_tracked=T, n_ok=T, n_crossed=int(crossed.sum()), floor_m=float("nan"),
                         crossed=crossed, exchanged=exchanged)  # fmt: skip
    doubt_crossed, doubt_exchanged = _leg_doubts(signals, cfg)
    backwards = facing_in_doubt(points, names, rate_hz)
    return doubt_crossed * signals.n_crossed + doubt_exchanged * signals.n_exchanged + backwards


def pivots(points: np.ndarray, names: tuple[str, ...], rate_hz: float) -> int:
    """How many frames of points (T, P, 3) sampled at ``rate_hz`` pause at a turn
    (:func:`turning_on_the_spot`): a pivot, where the tracker can lose the legs and the stride's
    rhythm cannot tell (:func:`out_of_rhythm` does not judge those frames)."""
    points = np.asarray(points, float)
    return int(turning_on_the_spot(points, names, rate_hz, turns(points, names)).sum())


def facing_in_doubt(points: np.ndarray, names: tuple[str, ...], rate_hz: float) -> int:
    """The frames of :func:`legs_in_doubt` that a body moving against the way it faces puts in doubt
    (points (T, P, 3) sampled at ``rate_hz``; :func:`moving_backwards`: the stretch between turns
    moving so most, when they are most of its moving frames); 0 when none."""
    return _backwards_frames(moving_backwards(np.asarray(points, float), names, rate_hz))


def judge(signals: RunSignals, cfg: VerdictConfig) -> RunVerdict:
    """The verdict of a run from its signals: ``failed`` when too few frames fit
    (``cfg.min_ok_fraction``), else ``doubtful`` when any check fails, else ``ok``; with the
    camera layout's note, which leaves the verdict as it is (:func:`_layout_notes`)."""
    s, n = signals, signals.n_frames
    if s.n_ok < cfg.min_ok_fraction * n or s.n_ok == 0:
        count = f"only {s.n_ok} of {n} frames fit" if s.n_ok else f"none of the {n} frames fits"
        return RunVerdict("failed", (f"{count} the silhouettes (fit below quality.min_fit, or subject not found)",))
    reasons = []
    crossed, exchanged = _leg_doubts(s, cfg)
    if s.flagged_fraction > cfg.max_flagged_fraction:
        reasons.append(f"a poor fit for {n - s.n_ok} of {n} frames")
    if crossed:
        reasons.append(f"the ankles cross in {s.n_crossed} of {s.n_tracked} frames: a suspected leg swap")
    if exchanged:
        reasons.append(f"legs possibly exchanged fore and aft in {s.n_exchanged} frames: there the ankles' fore-aft "
                       "order goes against the stride's rhythm")  # fmt: skip
    if np.isfinite(s.floor_m) and abs(s.floor_m) > cfg.max_floor_offset_m:
        where = "above" if s.floor_m > 0 else "below"
        reasons.append(f"the feet stay {100 * abs(s.floor_m):.0f} cm {where} the floor: the model is not standing "
                       "on it")  # fmt: skip
    low, high = cfg.segment_ratio
    odd = {k: v for k, v in s.segment_ratios.items() if not low <= v <= high}
    if odd:
        listed = ", ".join(f"{k} {v:.2f}" for k, v in odd.items())
        reasons.append(f"a body outside anthropometric ranges (segment length / usual length for the height: {listed})")
    if s.body_problems:
        reasons.append("the shape calibration gave a body outside anthropometric ranges (" + "; ".join(s.body_problems)
                       + "): tracked with body.yaml's proportions")  # fmt: skip
    if s.n_uncertain > cfg.max_uncertain_fraction * s.n_tracked:
        reasons.append(f"the lower-limb points' uncertainty is above {cfg.uncertain_mm:g} mm in {s.n_uncertain} of "
                       f"{s.n_tracked} tracked frames: positions may be off by several centimetres")  # fmt: skip
    if s.out_of_step:
        reasons.append(f"the cameras' videos look out of step ({s.out_of_step}): views a frame apart put the joints "
                       "centimetres off (see the note on trimming the videos)")  # fmt: skip
    small = {k: v for k, v in s.image_height_px.items() if v < cfg.min_image_height_px}
    if small:
        listed = ", ".join(f"{v:.0f} px in {k}" for k, v in small.items())
        reasons.append(f"the subject is too small in the image ({listed})")
    notes = _layout_notes(s, cfg) + _direction_notes(s) + _support_notes(s, cfg)
    return RunVerdict("doubtful" if reasons else "ok", tuple(reasons), notes)


def no_oblique_view(angles: dict[str, float], min_oblique_deg: float) -> bool:
    """Whether every camera lies within ``min_oblique_deg`` of the walking line or of its perpendicular,
    ``angles``: camera -> degrees (:func:`view_angles`; empty, the walking line unknown: False). Seen
    from beside and along the walkway only, the two leg assignments fit the silhouettes nearly alike
    (module docstring)."""
    return bool(angles) and not any(min_oblique_deg <= a <= 90.0 - min_oblique_deg for a in angles.values())


def _layout_notes(s: RunSignals, cfg: VerdictConfig) -> tuple[str, ...]:
    """A note (not a reason) when no camera is ``cfg.min_oblique_deg`` or more from both the walking
    line and its perpendicular: which leg is ahead is then ambiguous to the tracker, but the legs'
    fore-aft rhythm (a reason of its own) tells whether it got them wrong."""
    angles = s.view_angles_deg
    if not no_oblique_view(angles, cfg.min_oblique_deg):
        return ()
    listed = ", ".join(f"{k} {v:.0f}" for k, v in angles.items())
    note = (f"no camera views the walk obliquely (degrees between each line of sight and the walking line: {listed}): "
            "from beside and in line with the walkway only, which leg is ahead is ambiguous; check the legs where "
            "they pass each other")  # fmt: skip
    return (note,)


#: the segments whose support (:func:`gaitcap.tracking.support.segment_support`) the verdict reads:
#: the legs (a note, and ``lost_legs``'s second run) ...
LEG_SEGMENTS = ("thigh_l", "shank_l", "thigh_r", "shank_r")
#: ... and the feet (a note only: a shoe of the floor's colour and brightness cannot be seen at all)
FOOT_SEGMENTS = ("foot_l", "foot_r")


def unsupported_legs(leg_support: dict[str, np.ndarray], cfg: VerdictConfig,
                     segments: tuple[str, ...] = LEG_SEGMENTS) -> dict[str, tuple[int, int]]:  # fmt: skip
    """The ``segments`` (default: the legs') that some camera's silhouette holds less than
    ``cfg.min_leg_support`` of in more than ``cfg.max_unsupported_fraction`` of the frames where they
    were judged: segment -> (such frames, frames judged). ``leg_support``: segment -> (T,), as
    :class:`RunSignals` holds it (segments it does not hold are not judged)."""
    low = {}
    for name, share in ((k, leg_support[k]) for k in segments if k in leg_support):
        judged = np.isfinite(share)
        n = int(np.sum(share[judged] < cfg.min_leg_support))
        if judged.any() and n > cfg.max_unsupported_fraction * np.sum(judged):
            low[name] = (n, int(np.sum(judged)))
    return low


def unsupported_listing(low: dict[str, tuple[int, int]]) -> str:
    """:func:`unsupported_legs`' result in words: "thigh_l in 38 of 56 frames, ..."."""
    return ", ".join(f"{k} in {n} of {m} frames" for k, (n, m) in low.items())


#: the support notes (:func:`_support_notes`): the segments judged, what they are called, the unit
#: a share is of, and what the masks' loss means for them
_SUPPORT_NOTES = (
    (LEG_SEGMENTS, "legs", "segment",
     "either the masks lost them there and the other cameras and the priors placed them, or the tracker "
     "placed them off the masks"),
    (FOOT_SEGMENTS, "feet", "foot",
     "either the masks do not show the shoes there (a shoe of the floor's colour and brightness cannot be told "
     "from it), or the tracker placed the feet off them; the heel and toe points, and the gait events and ankle "
     "angles read from them, follow the legs above"),
)  # fmt: skip


#: how a support note (:func:`_support_notes`) begins, ``what`` "legs" or "feet"
SUPPORT_NOTE_START = "{what} placed where a camera's silhouette has little of them"


def feet_off_masks(notes: tuple[str, ...] | list[str]) -> bool:
    """Whether a run's verdict notes hold the feet's support note (:func:`_support_notes`): feet placed
    where the silhouettes show little of them, whose heel and toe follow the legs."""
    start = SUPPORT_NOTE_START.format(what="feet")
    return any(n.startswith(start) for n in notes)


def _support_notes(s: RunSignals, cfg: VerdictConfig) -> tuple[str, ...]:
    """A note (not a reason) for the legs, and one for the feet, naming those the silhouettes hold
    little of in many frames (:func:`unsupported_legs`): there the other cameras and the priors
    placed them, right or wrong, and a foot's heel and toe points and gait events follow its leg."""
    notes = []
    for segments, what, unit, meaning in _SUPPORT_NOTES:
        low = unsupported_legs(s.leg_support, cfg, segments)
        if low:
            notes.append(f"{SUPPORT_NOTE_START.format(what=what)} ({unsupported_listing(low)}: "
                         f"less than {100 * cfg.min_leg_support:.0f} % of the {unit} on the masks): {meaning}; look "
                         "at the masks (silhouettes.h5, gaitcap track --save-masks) and at the model drawn over the "
                         "frames (gaitcap report)")  # fmt: skip
    return tuple(notes)


def _backwards_frames(found: tuple[int, int, int, int]) -> int:
    """The frames moving backwards of a :func:`moving_backwards` result when they are most of its
    stretch's moving frames (the note's, and the backward pass's doubt), else 0."""
    against, moving = found[:2]
    return against if moving and against > moving / 2 else 0


def _direction_notes(s: RunSignals) -> tuple[str, ...]:
    """A note (not a reason) when the tracked body moves against the way it faces in most of the
    frames where it moves, between two turns or over the clip: a subject walking backwards, or a
    model facing the wrong way (a turn it did not follow)."""
    if not _backwards_frames(s.moving_backwards):
        return ()
    against, moving, first, last = s.moving_backwards
    return (f"the tracked body moves backwards (against the way it faces) in {against} of the {moving} frames where "
            f"it moves in frames {first}-{last}: right for a subject walking backwards; otherwise the model faces "
            "the wrong way there",)


def point_residuals(points: np.ndarray, rate_hz: float, cutoff_hz: float) -> np.ndarray:
    """(T, P) distance (metres) of each raw point (T, P, 3) from its zero-lag low-pass trajectory:
    the tracker's frame-to-frame jitter. NaN where a point is missing; a run of frames too short
    for the filter gives 0."""
    if cutoff_hz >= rate_hz / 2:
        cutoff_hz = 0.4 * rate_hz
    smooth = lowpass(points, rate_hz, cutoff_hz)
    return np.linalg.norm(points - smooth, axis=2)


def calibrated_uncertainty(points: np.ndarray, names: tuple[str, ...], fit: np.ndarray, signals: RunSignals,
                           rate_hz: float, cfg: UncertaintyConfig) -> np.ndarray:  # fmt: skip
    """Per-point uncertainty (T, P), metres, from the raw points (T, P, 3), the per-frame fit (T,)
    and the run's signals (see the module docstring); NaN where a point or the fit is missing.
    Bounded below by ``cfg.min_m``."""
    points, fit = np.asarray(points, float), np.asarray(fit, float)
    T, P = points.shape[:2]
    if fit.shape != (T,) or signals.crossed.shape != (T,):
        raise ValueError(f"fit and the signals' crossed frames must have shape ({T},)")
    c = cfg.coefficients
    res = np.maximum(point_residuals(points, rate_hz, cfg.cutoff_hz), cfg.min_residual_m)
    floor = abs(signals.floor_m) if np.isfinite(signals.floor_m) else 0.0
    frame = (c.intercept + c.fit * (1.0 - fit) + c.crossed_run * signals.crossed_fraction + c.floor * floor
             + c.crossed_frame * signals.crossed)  # (T,)  # fmt: skip
    with np.errstate(invalid="ignore"):
        u = np.exp(frame[:, None] + c.log_residual * np.log(res)) * cfg.scales(names)
    return np.maximum(u, cfg.min_m)


@dataclass(frozen=True)
class Assessment:
    """:func:`assess`'s result: the run's signals, its verdict and the per-point uncertainty (T, P), metres."""

    signals: RunSignals
    verdict: RunVerdict
    uncertainty: np.ndarray


def assess(points: np.ndarray, names: tuple[str, ...], fit: np.ndarray, quality: np.ndarray, height_m: float,
           rate_hz: float, verdict_cfg: VerdictConfig, uncertainty_cfg: UncertaintyConfig,
           rig: CameraRig | None = None, body_problems: tuple[str, ...] = (),
           leg_support: dict[str, np.ndarray] | None = None, out_of_step: str = "") -> Assessment:  # fmt: skip
    """Signals, verdict and calibrated uncertainty of one run from the tracker's raw points
    (T, P, 3), fit (T,) and quality (T,) (``points_unfiltered``, ``fit``, ``quality`` of
    trajectories.h5); ``body_problems``, ``leg_support``, ``out_of_step``: see :class:`RunSignals`."""
    signals = replace(run_signals(points, names, quality, height_m, rig, verdict_cfg.crossed_margin_m,
                                  rate_hz=rate_hz, exchanged_margin_m=verdict_cfg.exchanged_margin_m),
                      body_problems=body_problems, leg_support=dict(leg_support or {}),
                      out_of_step=out_of_step)  # fmt: skip
    u = calibrated_uncertainty(points, names, fit, signals, rate_hz, uncertainty_cfg)
    signals = replace(signals, n_uncertain=_uncertain_frames(u, names, quality, verdict_cfg.uncertain_mm))
    return Assessment(signals, judge(signals, verdict_cfg), u)


def _uncertain_frames(u: np.ndarray, names: tuple[str, ...], quality: np.ndarray, limit_mm: float) -> int:
    """The tracked frames whose lower-limb points' mean uncertainty ``u`` (T, P), metres, is above ``limit_mm``."""
    lower = np.asarray(u, float)[:, [names.index(p) for p in LOWER_LIMB if p in names]]
    finite = np.isfinite(lower)
    counted = finite.sum(axis=1)
    mean = np.where(finite, lower, 0.0).sum(axis=1) / np.maximum(counted, 1)
    return int(np.sum(tracked_frames(quality) & (counted > 0) & (mean * 1000.0 > limit_mm)))
