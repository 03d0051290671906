"""Automatic initialisation: find the subject, its walking direction and a first pose. No clicks.

1. In the first frames, the centroid of each camera's silhouette is triangulated (DLT on the
   pinhole views): the subject's position over time.
2. The walking direction is the direction of that motion (when it moves more than 15 cm);
   otherwise every heading is tried.
3. Global search on the first frame: headings x stride phases x positions around the
   triangulated centroid, scored with the full-body likelihood; the best candidates are refined
   with the tracker's own search on widened intervals; the best refined pose wins. Which way the
   subject faces is then decided over the first frames: that pose and the best one facing the
   other way are each tracked over them, the better mean fit wins (:func:`_facing`). The motion
   does not tell: a subject may walk backwards (a rehabilitation exercise), and on the spot (a
   treadmill) there is none.
4. Which leg is which: the first frames are tracked from that pose and from its leg-swapped
   mirror, and the start with the better mean fit is kept (:func:`settle_legs`). One frame
   cannot tell: seen from the side, the two assignments of legs that are apart fit within a few
   hundredths once the pelvis and the hips have compensated, while a swap shows over the frames
   that follow (on the Vicon walk, tracker seed 25, a start swapped on one frame's evidence fit
   0.76-0.85 for 16 frames, against 0.87-0.91 once undone where the legs crossed). The mirror's
   track stops after 3 frames where one start already leads by 0.03 or more.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gaitcap.body.model import BodyModel
from gaitcap.camera import dlt_point
from gaitcap.errors import TrackingError
from gaitcap.tracking.base import Track, Tracker
from gaitcap.tracking.likelihood import SilhouetteLikelihood
from gaitcap.tracking.observation import Observation, TrackingView

log = logging.getLogger("gaitcap.tracking.init")

MIN_MOTION_M = 0.15


@dataclass(frozen=True)
class InitResult:
    q: np.ndarray  # (D,) pose at the first observation
    heading_rad: float
    walking_direction_known: bool
    fit: float  # of q against observations[0] (1 - xor/|S|, mean over the cameras)
    #: whether the leg assignment of q was chosen over several frames (:func:`settle_legs`)
    legs_settled: bool = False


def silhouette_centroid(sil: np.ndarray) -> np.ndarray | None:
    """Centroid (u, v) of a soft silhouette (h, w); None when it holds less than 4 pixels."""
    total = float(sil.sum())
    if total < 4:
        return None
    ys, xs = np.mgrid[0 : sil.shape[0], 0 : sil.shape[1]]
    return np.array([(xs * sil).sum() / total, (ys * sil).sum() / total])


def triangulate(views: list[TrackingView], pixels: list[np.ndarray | None]) -> np.ndarray | None:
    """DLT triangulation of one point seen in several pinhole views (None: not seen)."""
    seen = [(view, px) for view, px in zip(views, pixels, strict=True) if px is not None]
    return dlt_point([view.K @ np.hstack([view.camera.R, view.camera.tvec[:, None]]) for view, _ in seen],
                     [px for _, px in seen])  # fmt: skip


def subject_positions(views: list[TrackingView], observations: list[Observation]) -> np.ndarray:
    """Triangulated silhouette centroids (T, 3), NaN where fewer than two cameras see the subject."""
    out = np.full((len(observations), 3), np.nan)
    for t, obs in enumerate(observations):
        X = triangulate(views, [silhouette_centroid(s) for s in obs.silhouettes])
        if X is not None:
            out[t] = X
    return out


def height_on_vertical(view: TrackingView, u: float, v: float, position: np.ndarray) -> float | None:
    """Height z (m) at which the ray through pixel (u, v) of ``view`` passes closest to the vertical
    line through ``position`` (3,); None when the ray is vertical."""
    ray = view.camera.R.T @ np.linalg.solve(view.K, [u, v, 1.0])
    C = view.camera.center
    # closest point between the ray C + s ray and the vertical line (x, y) = position[:2]
    d = np.array([0.0, 0.0, 1.0])
    w0 = C - np.array([position[0], position[1], 0.0])
    a, b, c = ray @ ray, ray @ d, d @ d
    dd, e = ray @ w0, d @ w0
    den = a * c - b * b
    if abs(den) < 1e-9:
        return None
    return float((a * e - b * dd) / den)


def silhouette_row_centre(sil: np.ndarray, row: int) -> float:
    """The silhouette-weighted column (u) of one row of a soft silhouette (h, w)."""
    return float(np.average(np.arange(sil.shape[1]), weights=sil[row] + 1e-9))


def estimate_height(views: list[TrackingView], obs: Observation, position: np.ndarray) -> float | None:
    """Height from the top of each silhouette: the ray through the topmost silhouette pixel meets the
    vertical line through the subject's position; the median over cameras, over 0.99 (the head top
    of a walking person is about 1 % below the standing height)."""
    tops = []
    for view, sil in zip(views, obs.silhouettes):
        rows = np.where(sil.max(axis=1) > 0.5)[0]
        if len(rows) == 0:
            continue
        top = height_on_vertical(view, silhouette_row_centre(sil, rows[0]), rows[0], position)
        if top is not None:
            tops.append(top)
    if not tops:
        return None
    return float(np.median(tops) / 0.99)


def _candidate_poses(model: BodyModel, position: np.ndarray, headings: list[float]) -> np.ndarray:
    """Standing poses at several headings, stride phases and positions around ``position``."""
    deg = np.pi / 180
    phases = [(0.0, 0.0, 5.0, 5.0), (20.0, -15.0, 5.0, 30.0), (-15.0, 20.0, 30.0, 5.0), (10.0, -5.0, 50.0, 5.0),
              (-5.0, 10.0, 5.0, 50.0)]  # fmt: skip
    offsets = [(dx, dy) for dx in (-0.1, 0.0, 0.1) for dy in (-0.1, 0.0, 0.1)]
    out = []
    for h in headings:
        for hl, hr, kl, kr in phases:
            for dx, dy in offsets:
                q = model.neutral_pose(heading_rad=h, x=position[0] + dx, y=position[1] + dy)
                q[model.dof_index("hip_flexion_l")] = hl * deg
                q[model.dof_index("hip_flexion_r")] = hr * deg
                q[model.dof_index("knee_flexion_l")] = kl * deg
                q[model.dof_index("knee_flexion_r")] = kr * deg
                q[model.dof_index("pelvis_tz")] -= 0.02
                out.append(q)
    return model.clip(np.asarray(out))


def initialise(
    tracker: Tracker, likelihood: SilhouetteLikelihood, views: list[TrackingView], observations: list[Observation],
    heading_step_deg: float, refine_passes: int, widen: float, keep: int = 3, leg_frames: int = 0,
    heading_rad: float | None = None,
) -> InitResult:  # fmt: skip
    """Find the first pose (see the module docstring). ``observations[0]`` is the frame to start at;
    with ``leg_frames`` > 1 and as many observations, which way the subject faces and its leg
    assignment are chosen over them. ``heading_rad``: the subject's heading when already known
    (radians; the frames need not run forwards in time), searched within 20 degrees instead of the
    walking direction; the facing check tests the other way as it does the motion's (the backward
    pass's fresh start takes the forward pass's last heading, wrong after a turn it lost)."""
    model = tracker.model
    positions = subject_positions(views, observations)
    seen = np.where(np.all(np.isfinite(positions), axis=1))[0]
    if len(seen) == 0 or not np.all(np.isfinite(positions[0])):
        raise TrackingError("cannot initialise: the subject is not seen by two cameras in the first frame")
    start = positions[0]
    motion = positions[seen[-1]] - start
    known = bool(np.hypot(motion[0], motion[1]) > MIN_MOTION_M)
    if heading_rad is None and known:
        heading_rad = float(np.arctan2(motion[1], motion[0]))
        log.info("walking direction from the first %d frames: %.0f degrees", len(observations), np.degrees(heading_rad))
    if heading_rad is not None:
        known = True
        headings = _headings_around(heading_rad)
    else:
        headings = list(np.radians(np.arange(0, 360, heading_step_deg)))
        log.info("the subject barely moves in the first frames: searching every heading")
    obs = observations[0]
    fit, q = _refined(tracker, likelihood, obs, _candidate_poses(model, start, headings), keep, refine_passes, widen)
    settled = leg_frames > 1 and len(observations) > 1
    own = None  # q's track over the first frames, when already tracked
    if settled:
        fit, q, own = _facing(tracker, likelihood, observations[:leg_frames], start, (fit, q), keep, refine_passes,
                              widen, decisive=DECISIVE_FIT if known else None)  # fmt: skip
        kept = settle_legs(tracker, observations[:leg_frames], q, own=own)
        if not np.array_equal(kept, q):  # the mirror: its own fit, not the refined pose's
            fit = tracker.full_fit(obs, kept)[1]
        q = kept
    heading = float(q[model.dof_index("pelvis_rotation")])
    return InitResult(q=q, heading_rad=heading, walking_direction_known=known, fit=fit, legs_settled=settled)


def _headings_around(heading_rad: float) -> list[float]:
    """The headings (radians) searched around a known one: within 20 degrees of it, 10 apart."""
    return [heading_rad + np.radians(d) for d in (-20, -10, 0, 10, 20)]


def _refined(tracker: Tracker, likelihood: SilhouetteLikelihood, obs: Observation, Q: np.ndarray, keep: int,
             refine_passes: int, widen: float) -> tuple[float, np.ndarray]:  # fmt: skip
    """The best of the candidate poses Q (N, D) on ``obs``, refined: the ``keep`` best-scoring
    candidates of distinct headings (25 degrees apart or more), each refined by ``refine_passes``
    of the tracker on intervals ``widen`` times wider; returns (fit, pose (D,)) of the best refined."""
    yaw = tracker.model.dof_index("pelvis_rotation")
    order = np.argsort(-likelihood.score(obs, tracker.projector.capsules(Q)))
    chosen: list[int] = []
    for i in order:
        if all(abs(np.angle(np.exp(1j * (Q[i, yaw] - Q[j, yaw])))) > np.radians(25) for j in chosen):
            chosen.append(int(i))
        if len(chosen) == keep:
            break
    best: tuple[float, np.ndarray] | None = None
    for i in chosen:
        tracker.start(Q[i])
        est = None
        for _ in range(max(1, refine_passes)):
            est = tracker.step(obs, widen=widen)  # type: ignore[call-arg]
        assert est is not None
        if best is None or est.fit > best[0]:
            best = (est.fit, est.q.copy())
    assert best is not None
    return best


def _tracked(tracker: Tracker, observations: list[Observation], q: np.ndarray,
             stop: Callable[[int, float], bool] | None = None) -> Track:  # fmt: skip
    """``observations`` tracked from pose q (D,), started as settled (as :func:`settle_legs` tracks its
    starts), until ``stop(n, sum of the n fits)`` is true after n frames."""
    tracker.start(np.array(q, float, copy=True), fresh=False)
    start = tracker.q.copy()
    estimates, states = [], []
    total = 0.0
    for o in observations:
        estimates.append(tracker.step(o))
        states.append(tracker.snapshot())
        total += estimates[-1].fit
        if stop is not None and stop(len(estimates), total):
            break
    return Track(start, tuple(observations[: len(estimates)]), tuple(estimates), tuple(states))


def _fits(track: Track) -> np.ndarray:
    """The fit of each frame of a track (T,)."""
    return np.array([e.fit for e in track.estimates])


def _facing(tracker: Tracker, likelihood: SilhouetteLikelihood, observations: list[Observation],
            position: np.ndarray, found: tuple[float, np.ndarray], keep: int, refine_passes: int, widen: float,
            decisive: float | None = None) -> tuple[float, np.ndarray, Track | None]:  # fmt: skip
    """Which way the subject faces: the pose ``found`` (fit on the first frame, pose (D,)) and the
    best refined pose facing the other way (headings within 20 degrees of the opposite one) are
    each tracked over ``observations``, and the one with the better mean fit is returned: (fit on
    the first frame, pose, and for ``found`` its track, :func:`settle_legs`'s first track, else
    None). One frame cannot tell: a silhouette seen from the front or the back is
    nearly the same either way, and from the side a body facing backwards bends its knees to mimic
    the stride (on a walk on the spot, with the legs half lost over a floor of their colour, a start
    facing backwards was tracked so through the whole clip: 300 mm off, its fit 0.60 against 0.67
    facing forwards); over frames the legs' motion shows it. Nor does the walking direction: a
    subject walking backwards, started facing the motion, was tracked so through the clip (236 mm
    off, every frame's legs exchanged, the verdict "ok"; fit 0.68 against 0.76 facing the truth's
    way over the first 8 frames). With ``decisive`` (a walking direction known from the motion), the
    other way's track stops once one leads by that much per frame (:func:`_race`), and the other way
    is taken only if it leads by that much: a subject facing the motion or its opposite fits
    0.06-0.12 better over the first frames than the other way, and a tie keeps the motion's way (the
    check tried at the backward pass's fresh start turned a forward walk's end round on 0.812
    against 0.810 over 8 frames: 35 -> 61 mm).

    ``found`` is tracked first, with the tracker's random stream as it was; the stream is then left
    where that track left it when ``found`` is kept, else where it was: either way the run goes on
    as it would have without the check."""
    model = tracker.model
    stream = tracker.rng.bit_generator.state
    own = _tracked(tracker, observations, found[1])
    after = tracker.rng.bit_generator.state
    back = _headings_around(float(found[1][model.dof_index("pelvis_rotation")]) + np.pi)
    other = _refined(tracker, likelihood, observations[0], _candidate_poses(model, position, back),
                     keep if decisive is None else 1, refine_passes, widen)  # fmt: skip
    fits, n, _ = _race(tracker, observations, other[1], np.cumsum(_fits(own)), decisive)
    if fits[1] > fits[0] + (decisive or 0.0):
        log.info("first pose: facing the other way fits the first %d frames better (%.3f against %.3f)",
                 n, fits[1], fits[0])  # fmt: skip
        tracker.rng.bit_generator.state = stream
        return other[0], other[1], None
    tracker.rng.bit_generator.state = after
    return found[0], found[1], own


#: the mirror's frames left are not tracked once, over its first :data:`LEAST_FRAMES` frames or more,
#: one start's mean fit leads the other's over the same frames by this much (or by the caller's
#: margin, if larger): a start with its legs exchanged and apart fits 0.05-0.2 worse from the first
#: frames on, while where the legs cross the two stay within a few hundredths and every frame is tracked
DECISIVE_FIT = 0.03
LEAST_FRAMES = 3


def _race(tracker: Tracker, observations: list[Observation], q: np.ndarray, totals: np.ndarray,
          decisive: float | None) -> tuple[tuple[float, float], int, Track]:  # fmt: skip
    """A track from pose q (D,) over ``observations`` (started as settled) against one already made,
    whose cumulative fits are ``totals`` (T,); it stops once, over its first :data:`LEAST_FRAMES`
    frames or more, one leads the other by ``decisive`` per frame (None: never). Returns both mean
    fits over the frames tracked (the earlier track's, q's), their number and q's track."""

    def decided(n: int, mine: float) -> bool:
        return decisive is not None and n >= LEAST_FRAMES and abs(mine - totals[n - 1]) > n * decisive

    track = _tracked(tracker, observations, q, decided)
    n = len(track.estimates)
    mine = float(np.cumsum(_fits(track))[-1]) if n else 0.0  # summed in order, as totals
    return ((float(totals[n - 1]) / n, mine / n) if n else (0.0, 0.0)), n, track


def settle_legs(tracker: Tracker, observations: list[Observation], q: np.ndarray, margin: float = 0.0,
                own: Track | None = None) -> np.ndarray:  # fmt: skip
    """The leg assignment of a first pose q (D,) that the frames ``observations`` support: they are
    tracked from q and from its leg-swapped mirror, each started as settled (no mirror weighed
    on the first frame, which would make both tracks the same), and the mirror is returned when its
    mean fit over them is higher than q's by more than ``margin`` (0: whichever is higher; a
    margin when q's assignment is one already chosen, which a tie should not overturn), else q.
    The mirror's track stops early, both compared over the frames it covered, once one start leads
    by :data:`DECISIVE_FIT` (and ``margin``) after :data:`LEAST_FRAMES` frames or more. The tracker is
    left started there, settled, remembering the kept start's track (:meth:`Tracker.remember`: the
    caller's next steps over the same frames take it). ``own``: q's track over ``observations``
    when it was tracked already, the tracker's random stream left where that track left it
    (:func:`_facing`)."""
    starts = (np.array(q, float, copy=True), tracker.mirrored(q))
    mine = own if own is not None else _tracked(tracker, observations, starts[0])
    fits, n, mirror = _race(tracker, observations, starts[1], np.cumsum(_fits(mine)), max(DECISIVE_FIT, margin))
    kept = int(fits[1] > fits[0] + margin)
    if kept:
        log.info("first pose: the leg-swapped start fits the first %d frames better (%.3f against %.3f)", n, fits[1],
                 fits[0])  # fmt: skip
    tracker.start(starts[kept], fresh=False)
    tracker.remember((mine, mirror)[kept])
    return starts[kept]
