"""Compare a tracked trajectory with a reference (a synthetic truth or another run).

Steps, each a small function:

1. :func:`align`: the frames both trajectories cover (matched by time; the reference is resampled
   first if its rate differs), the points both have. A point OUT never tracked (NaN throughout) is
   dropped with a note (none is when OUT tracked no point at all: then every frame is flagged). A
   frame where OUT has any NaN among the kept points is *flagged* and excluded from every position
   and angle statistic (and counted).
2. positions: MPJPE over all points, the lower limb (hips, knees, ankles), heel/toe, and per point,
   and each group's MPJPE with every point's constant offset removed (what changes from frame to frame);
   each point's mean signed error in the walking frame (:func:`walking_frame`), the part of its error
   that is the same offset in every frame (a body model whose joints sit elsewhere than the
   reference's, a calibration off by a shift).
3. left/right swaps: frames where exchanging OUT's left and right leg points fits better.
4. joint angles (:func:`gaitcap.gait.angles.joint_angles`, both in the reference's walking
   direction, pass by pass for a walk that turns: :func:`gaitcap.gait.analysis.angles_by_pass`):
   RMSE per angle and side.
5. gait events detected on OUT (:func:`gaitcap.gait.analysis.analyse`) against the reference's
   recorded events (a truth from ``gaitcap synth`` carries the motion file's events) or, when it
   has none, the events detected on the reference; plus the *method baseline*: events detected on
   the reference itself against its recorded events (what the event detector alone costs).
6. gait parameters of OUT against the reference's (computed with the recorded events when there
   are some), or against the values the truth states (a truth folder's ``parameters.json``: the
   names both have, overall and per side).

The silhouette IoU (:mod:`gaitcap.evaluation.silhouettes`) is added by the caller when OUT holds
masks and the truth has some.
"""

from __future__ import annotations

import logging
import math
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from gaitcap import __version__
from gaitcap.body.measures import length_errors, segment_lengths
from gaitcap.errors import InputError
from gaitcap.evaluation.metrics import (
    angle_rmse_deg,
    event_error_summary,
    group_errors,
    match_events,
    point_bias_mm,
    point_distances_mm,
    runs,
    swap_mask,
)
from gaitcap.gait.analysis import GaitAnalysis, analyse, angles_by_pass, parameters_by_pass
from gaitcap.gait.angles import ANGLE_NAMES
from gaitcap.gait.options import GaitOptions
from gaitcap.gait.parameters import OVERALL_KEYS, SIDE_KEYS, GaitParameters
from gaitcap.quality import walking_line
from gaitcap.track_summary import VERDICTS
from gaitcap.trajectory import FOOT, LOWER_LIMB, SIDES, GaitEvent, Trajectory, side_suffix

log = logging.getLogger(__name__)

#: the angles the ``--max-angle-rmse-deg`` threshold applies to (both sides); the others (pelvis,
#: hip ab/adduction and rotation) are reported only: from joint centres they are poorly determined
CHECKED_ANGLES: tuple[str, ...] = ("hip_flexion", "knee_flexion", "ankle_dorsiflexion")
#: the hips' mean left-minus-right axis (metres, along the walking line's left) that tells which
#: way the subject faces (hip centres are 0.1 H apart: shorter means the subject turned round)
MIN_HIP_AXIS_M = 0.05
#: a detected event further than this from every reference event of its side and kind is "extra"
MAX_MATCH_S = 0.25


@dataclass(frozen=True)
class Thresholds:
    """Limits that make ``gaitcap eval`` fail (exit code 3; None: not checked). ``max_event_error_frames``
    (frames of OUT's rate) and ``max_event_error_ms`` (milliseconds: the same limit at every frame rate)
    also fail on a reference event not detected; ``min_compared_fraction``: of OUT's frames, those compared
    (not flagged, with a reference frame; against a reference run, its frames OUT lacks count too);
    ``require_verdict``: OUT's verdict at least this good."""

    max_mpjpe_mm: float | None = None
    max_angle_rmse_deg: float | None = None
    max_event_error_frames: float | None = None
    max_lower_limb_mpjpe_mm: float | None = None
    min_compared_fraction: float | None = None
    require_verdict: str | None = None
    max_event_error_ms: float | None = None


@dataclass(frozen=True)
class Aligned:
    """Two trajectories on common frames and points.

    Attributes:
        names: the P common points.
        est, ref: positions (F, P, 3), metres; ``est`` keeps its NaNs.
        times: (F,) seconds on OUT's time axis.
        rate_hz: the common rate.
        flagged: (F,) OUT has a NaN among the points.
        ref_missing: (F,) the reference has a NaN (excluded too, counted apart).
        dropped: points OUT never tracked.
        formats: ``"est"`` and ``"ref"`` -> their trajectories' ``meta["format"]`` (what they were read
            from: a tracking run's gait events keep their anchors, ``GaitOptions.refine_tracked``).
        ref_frames: the reference's frames (at OUT's rate).
        ref_outside: of them, those at a time OUT has no frame for (not compared).
    """

    names: tuple[str, ...]
    est: np.ndarray
    ref: np.ndarray
    times: np.ndarray
    rate_hz: float
    flagged: np.ndarray
    ref_missing: np.ndarray
    dropped: tuple[str, ...] = ()
    formats: dict[str, str] = field(default_factory=dict)
    ref_frames: int = 0
    ref_outside: int = 0

    @property
    def valid(self) -> np.ndarray:
        return ~self.flagged & ~self.ref_missing

    def trajectory(self, which: str, mask_invalid: bool = False) -> Trajectory:
        pts = (self.est if which == "est" else self.ref).copy()
        if mask_invalid:
            pts[~self.valid] = np.nan
        fmt = self.formats.get(which)
        return Trajectory(self.names, pts, self.rate_hz, float(self.times[0]), meta={"format": fmt} if fmt else {})


def align(out: Trajectory, ref: Trajectory) -> Aligned:
    """Common frames (by time) and points of ``out`` and ``ref`` (see the module docstring).

    Raises:
        InputError: no common point, or no common frame.
    """
    if not math.isclose(out.rate_hz, ref.rate_hz, rel_tol=1e-6):
        log.info("resampling the reference from %g Hz to %g Hz", ref.rate_hz, out.rate_hz)
        ref = ref.resample(out.rate_hz)
    names = [n for n in out.names if n in ref.names]
    if not names:
        raise InputError(f"no point in common (OUT: {', '.join(out.names)}; reference: {', '.join(ref.names)})")
    dropped = tuple(n for n in names if not np.isfinite(out.point(n)).any())
    if len(dropped) < len(names):
        names = [n for n in names if n not in dropped]
    else:  # a run lost throughout: every frame flagged, nothing compared (a threshold fails on it, as on any)
        dropped = ()
    j = np.rint((out.times() - ref.t0_s) * out.rate_hz).astype(int)
    keep = (j >= 0) & (j < ref.n_frames)
    if not keep.any():
        raise InputError(
            f"no frame in common: OUT covers {out.times()[0]:.3f}-{out.times()[-1]:.3f} s, "
            f"the reference {ref.times()[0]:.3f}-{ref.times()[-1]:.3f} s"
        )
    est = out.subset(names).points[keep]
    refp = ref.subset(names).points[j[keep]]
    return Aligned(
        names=tuple(names), est=est, ref=refp, times=out.times()[keep], rate_hz=out.rate_hz,
        flagged=~np.isfinite(est).all(axis=(1, 2)), ref_missing=~np.isfinite(refp).all(axis=(1, 2)),
        dropped=dropped, ref_frames=ref.n_frames, ref_outside=ref.n_frames - len(np.unique(j[keep])),
        formats={k: str(t.meta["format"]) for k, t in (("est", out), ("ref", ref)) if t.meta.get("format")},
    )  # fmt: skip


@dataclass
class Evaluation:
    """Everything ``gaitcap eval`` reports; :meth:`to_dict` is ``eval.json``."""

    out_source: str
    reference_source: str
    rate_hz: float
    n_frames: int
    n_flagged: int
    n_reference_missing: int
    points: list[str]
    positions: dict[str, dict[str, float] | None]
    per_point_mm: dict[str, float]
    swaps: dict[str, Any]
    angles_rmse_deg: dict[str, float]
    events: dict[str, Any]
    events_baseline: dict[str, Any] | None
    parameters: dict[str, Any]
    silhouettes: dict[str, dict[str, Any]] | None = None
    #: the tracked body's segment lengths against the reference's (:func:`compare_lengths`)
    segment_lengths: dict[str, dict[str, float]] | None = None
    #: point -> mean signed error in the walking frame (:func:`gaitcap.evaluation.metrics.point_bias_mm`)
    bias_mm: dict[str, dict[str, float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)
    #: the run's own verdict and its reasons (OUT's track.json), when it has one
    verdict: str | None = None
    verdict_reasons: list[str] = field(default_factory=list)
    #: OUT's own frames (``n_frames`` counts those with a reference frame)
    n_out_frames: int = 0
    #: the thresholds checked (:class:`Thresholds`, those given)
    thresholds: dict[str, Any] = field(default_factory=dict)
    #: a reference run's own verdict (its track.json; None for a truth or a run not judged)
    reference_verdict: str | None = None
    #: the reference's frames (at OUT's rate), and those at a time OUT has no frame for
    n_reference_frames: int = 0
    n_reference_outside: int = 0
    #: the reference is another tracking run (``--reference``), not a truth: its frames OUT lacks count as not
    #: compared for ``min_compared_fraction`` (a run that lost frames is a regression)
    reference_is_run: bool = False

    def compared_share(self) -> tuple[int, float]:
        """The frames the compared ones are counted against (OUT's own; for a reference run, also the reference's
        that OUT lacks) and the share compared (0 without any)."""
        total = self.n_out_frames + (self.n_reference_outside if self.reference_is_run else 0)
        return total, (self.n_compared / total if total else 0.0)

    @property
    def n_compared(self) -> int:
        return self.n_frames - self.n_flagged - self.n_reference_missing

    @property
    def mpjpe_mm(self) -> float:
        return (self.positions.get("all") or {}).get("mpjpe_mm", math.nan)

    def max_checked_angle_rmse(self) -> tuple[str, float]:
        """The worst of :data:`CHECKED_ANGLES` (name with side suffix, RMSE degrees)."""
        vals = {k: v for k, v in self.angles_rmse_deg.items() if k.rsplit("_", 1)[0] in CHECKED_ANGLES}
        finite = {k: v for k, v in vals.items() if math.isfinite(v)}
        if not finite:
            return "", math.nan
        k = max(finite, key=finite.__getitem__)
        return k, finite[k]

    def to_dict(self) -> dict[str, Any]:
        name, worst = self.max_checked_angle_rmse()
        doc = {
            "gaitcap_version": __version__,
            "out": self.out_source,
            "reference": self.reference_source,
            "reference_verdict": self.reference_verdict,
            "rate_hz": self.rate_hz,
            "verdict": self.verdict,
            "verdict_reasons": self.verdict_reasons,
            "frames": {"compared": self.n_compared, "total": self.n_frames, "out_total": self.n_out_frames,
                       "outside_reference": self.n_out_frames - self.n_frames, "flagged": self.n_flagged,
                       "reference_total": self.n_reference_frames, "reference_outside_out": self.n_reference_outside,
                       "reference_missing": self.n_reference_missing},
            "points": self.points,
            "positions_mm": self.positions,
            "per_point_mm": self.per_point_mm,
            "bias_mm": self.bias_mm,
            "left_right_swaps": self.swaps,
            "angles_rmse_deg": self.angles_rmse_deg,
            "checked_angles": {"names": list(CHECKED_ANGLES), "worst": name, "worst_rmse_deg": worst},
            "events": self.events,
            "events_method_baseline": self.events_baseline,
            "parameters": self.parameters,
            "silhouette_iou": self.silhouettes,
            "segment_lengths": self.segment_lengths,
            "notes": self.notes,
            "thresholds": self.thresholds,
            "thresholds_failed": self.failures,
            "passed": not self.failures,
        }  # fmt: skip
        return _clean(doc)


def compare_lengths(tracked_m: dict[str, float], reference: Trajectory) -> dict[str, dict[str, float]]:
    """The tracked body's segment lengths (metres, ``track.json``'s ``body.segment_lengths_m``)
    against those measured on the reference's joint centres (:mod:`gaitcap.body.measures`):
    name -> {tracked_m, reference_m, diff_pct}, for the lengths both have."""
    ref = segment_lengths(reference.names, reference.points)
    return {k: {"tracked_m": float(tracked_m[k]), "reference_m": ref[k], "diff_pct": 100.0 * e}
            for k, e in length_errors(tracked_m, ref).items()}  # fmt: skip


def _clean(obj: Any) -> Any:
    """NaN/inf -> None, numpy scalars -> Python (for JSON)."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


# ------------------------------------------------------------------------------ sections
def walking_frame(points: np.ndarray, names: tuple[str, ...]) -> np.ndarray | None:
    """The unit horizontal walking direction (2,) of points (F, P, 3): the walking line
    (:func:`gaitcap.quality.walking_line`) pointed so that the left hip is on its left (the hips'
    mean horizontal axis at least :data:`MIN_HIP_AXIS_M` long), else the way the pelvis travels;
    None when neither can be told."""
    line = walking_line(points, names)
    if line is None:
        return None
    if "hip_l" in names and "hip_r" in names:
        axis = points[:, names.index("hip_l"), :2] - points[:, names.index("hip_r"), :2]
        axis = axis[np.all(np.isfinite(axis), axis=1)]
        facing = float(axis.mean(axis=0) @ np.array([-line[1], line[0]])) if len(axis) else 0.0
        if abs(facing) >= MIN_HIP_AXIS_M:
            return line if facing > 0 else -line
    if "pelvis" in names:
        xy = points[:, names.index("pelvis"), :2]
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        travel = float((xy[-1] - xy[0]) @ line) if len(xy) >= 2 else 0.0
        if travel != 0.0:
            return line if travel > 0 else -line
    return None


def _units_note(a: Aligned) -> str:
    """A note when OUT's body is a hundred times the reference's size or more (or less): the points of
    one of them are likely in millimetres (a gait lab's export), where gaitcap reads metres; empty else.
    The size is the median distance of the points from each frame's centroid."""
    def size(points: np.ndarray) -> float:
        pts = points[a.valid]
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            d = np.linalg.norm(pts - np.nanmean(pts, axis=1, keepdims=True), axis=2)
            return float(np.nanmedian(d)) if np.isfinite(d).any() else math.nan

    est, ref = size(a.est), size(a.ref)
    if not (math.isfinite(est) and math.isfinite(ref)) or est <= 0 or ref <= 0 or 0.01 < est / ref < 100:
        return ""
    ratio = f"{est / ref:.0f} times as far apart as" if est > ref else f"{ref / est:.0f} times closer together than"
    return (f"OUT's points are {ratio} the reference's: one of them is likely in millimetres, and gaitcap reads "
            "metres (divide its points by 1000)")


def _positions(a: Aligned) -> tuple[dict[str, dict[str, float] | None], dict[str, float], dict[str, Any],
                                    dict[str, dict[str, float]]]:  # fmt: skip
    est, ref = a.est[a.valid], a.ref[a.valid]
    dist = point_distances_mm(est, ref)
    groups = {"all": a.names, "lower_limb": LOWER_LIMB, "heel_toe": FOOT}
    positions = {g: group_errors(dist, a.names, members) for g, members in groups.items()}
    error = est - ref  # each point's constant offset removed: the error that changes over time
    moving = point_distances_mm(error - error.mean(axis=0), np.zeros_like(error)) if len(error) else dist
    for g, members in groups.items():
        if positions[g] is not None:
            positions[g]["offset_free_mpjpe_mm"] = (group_errors(moving, a.names, members) or {}).get("mpjpe_mm", math.nan)
    bias = point_bias_mm(est, ref, a.names, walking_frame(ref, a.names)) if len(est) else {}
    per_point = {n: (float(dist[:, i].mean()) if len(dist) else math.nan) for i, n in enumerate(a.names)}
    swapped = swap_mask(a.est, a.ref, list(a.names)) & a.valid
    n_valid = int(a.valid.sum())
    swaps = {
        "n_frames": int(swapped.sum()),
        "fraction": float(swapped.sum() / n_valid) if n_valid else math.nan,
        "runs": [[int(s), int(e)] for s, e in runs(swapped)],  # OUT frame ranges [start, stop) of the compared span
    }
    return positions, per_point, swaps, bias


def _angles(a: Aligned, ref_analysis: GaitAnalysis | None, notes: list[str]) -> dict[str, float]:
    if ref_analysis is None:
        return {}
    try:
        est_angles, _ = angles_by_pass(a.trajectory("est", mask_invalid=True), ref_analysis.passes)
        ref_angles, _ = angles_by_pass(a.trajectory("ref"), ref_analysis.passes)
    except InputError as e:
        notes.append(f"joint angles not compared: {e}")
        return {}
    return {f"{n}{side_suffix(s)}": angle_rmse_deg(est_angles[f"{n}{side_suffix(s)}"], ref_angles[f"{n}{side_suffix(s)}"])[0]
            for n in ANGLE_NAMES for s in SIDES}  # fmt: skip


def _event_section(detected: list[GaitEvent], reference: list[GaitEvent], rate_hz: float, label: str) -> dict[str, Any]:
    matches, missed, extra = match_events(detected, reference, MAX_MATCH_S)
    return {
        "reference_events": label,
        "n_reference": len(reference),
        "n_detected": len(detected),
        "n_matched": len(matches),
        "n_missed": len(missed),
        "n_extra": len(extra),
        **event_error_summary(matches, rate_hz),
        "matches": [
            {"side": m.side, "event": m.event, "reference_s": round(m.reference_s, 6), "detected_s": round(m.detected_s, 6),
             "error_ms": 1000 * m.error_s, "error_frames": m.error_s * rate_hz}
            for m in matches
        ],  # fmt: skip
        "missed": [{"side": e.side, "event": e.event, "time_s": e.time_s} for e in missed],
        "extra": [{"side": e.side, "event": e.event, "time_s": e.time_s} for e in extra],
    }


def _differences(out: dict[str, float], ref: dict[str, float], keys) -> dict[str, dict[str, float]]:
    """reference, out, diff = out - reference and diff % of each of ``keys``."""
    doc = {}
    for key in keys:
        r, o = ref.get(key, math.nan), out.get(key, math.nan)
        diff = o - r
        doc[key] = {"reference": r, "out": o, "diff": diff,
                    "diff_pct": 100.0 * diff / abs(r) if math.isfinite(r) and r != 0 else math.nan}  # fmt: skip
    return doc


def _parameters(
    out_p: GaitParameters | None, ref_p: GaitParameters | None, stated: dict[str, dict[str, float]] | None = None
) -> dict[str, Any]:
    """OUT's gait parameters against the reference's, or against the ``stated`` values (scope ->
    name -> value) of a truth's parameters.json: the names both have, overall and per side."""
    doc: dict[str, Any] = {
        "out_status": out_p.status if out_p else "not computed",
        "reference_status": "stated in the truth's parameters.json" if stated is not None
                            else ref_p.status if ref_p else "not computed",
        "values": {},
    }  # fmt: skip
    if out_p is None or (ref_p is None and stated is None):
        return doc
    if stated is None:
        doc["values"] = _differences(out_p.overall, ref_p.overall, OVERALL_KEYS)  # type: ignore[union-attr]
        return doc
    doc["values"] = _differences(out_p.overall, stated.get("overall", {}),
                                 [k for k in OVERALL_KEYS if k in stated.get("overall", {})])  # fmt: skip
    doc["sides"] = {side: _differences(out_p.sides[side], stated.get(side, {}),
                                       [k for k in SIDE_KEYS if k in stated.get(side, {})])
                    for side in SIDES}  # fmt: skip
    return doc


class _Labelled(logging.Filter):
    """Prefixes the records of the loggers it is added to with ``label: ``."""

    def __init__(self, label: str) -> None:
        super().__init__()
        self.label = label

    def filter(self, record: logging.LogRecord) -> bool:
        record.msg = f"{self.label}: {record.msg}"
        return True


@contextmanager
def _logs_labelled(label: str, prefix: str = "gaitcap.gait") -> Iterator[None]:
    """The messages of the loggers under ``prefix`` (the gait analysis's) say which trajectory they are about."""
    loggers = [logging.getLogger(name) for name in list(logging.Logger.manager.loggerDict) if name.startswith(prefix)]
    labelled = _Labelled(label)
    for logger in loggers:
        logger.addFilter(labelled)
    try:
        yield
    finally:
        for logger in loggers:
            logger.removeFilter(labelled)


def _analyse(traj: Trajectory, what: str, options: GaitOptions | None, notes: list[str]) -> GaitAnalysis | None:
    try:
        with _logs_labelled(what):  # the same messages come for OUT and for the reference
            return analyse(traj, options)
    except InputError as e:
        notes.append(f"gait analysis of {what} failed: {e}")
        return None


def evaluate(
    out: Trajectory,
    reference: Trajectory,
    *,
    options: GaitOptions | None = None,
    out_source: str = "",
    reference_source: str = "",
    reference_parameters: dict[str, dict[str, float]] | None = None,
) -> Evaluation:
    """Compare ``out`` with ``reference`` (see the module docstring).

    Args:
        out: the tracked trajectory (NaN frames are flagged).
        reference: the truth or another run; its ``events`` are used as the recorded events.
        options: gait analysis options for event detection on both.
        reference_parameters: gait parameters the truth states (scope ``overall``/``left``/``right``
            -> name -> value); OUT's are compared with them instead of with the reference's computed ones.

    Raises:
        InputError: no common point or frame.
    """
    a = align(out, reference)
    notes = [f"point never tracked in OUT, not compared: {n}" for n in a.dropped]
    if a.flagged.all():
        notes.append("OUT has no tracked frame at all (every frame is NaN): nothing compared")
    if len(a.times) < out.n_frames:  # a shorter reference, or one that starts later: said, not hidden
        notes.append(f"{out.n_frames - len(a.times)} of OUT's {out.n_frames} frames have no reference frame: not "
                     "compared")  # fmt: skip
    if a.ref_outside:  # a longer reference, or OUT starting later: its other frames are not compared either
        notes.append(f"{a.ref_outside} of the reference's {a.ref_frames} frames have no frame in OUT: not compared")
    if note := _units_note(a):
        notes.append(note)
    positions, per_point, swaps, bias = _positions(a)

    t_lo, t_hi = float(a.times[0]), float(a.times[-1])
    recorded = [e for e in reference.events if t_lo - 1e-9 <= e.time_s <= t_hi + 1e-9]
    ref_traj = replace(a.trajectory("ref"), events=tuple(recorded))
    ref_analysis = _analyse(ref_traj, "the reference", options, notes)
    out_analysis = _analyse(a.trajectory("est"), "OUT", options, notes)
    angles = _angles(a, ref_analysis, notes)

    events: dict[str, Any] = {}
    baseline = None
    ref_params = None
    if ref_analysis is not None:
        if recorded:
            reference_events, label = recorded, "recorded in the reference"
            baseline = _event_section(ref_analysis.events, recorded, a.rate_hz, label)
            plausible = (options or GaitOptions()).plausible
            ref_params = parameters_by_pass(ref_traj, recorded, ref_analysis.passes, plausible)
        else:
            reference_events, label = ref_analysis.events, "detected on the reference"
            ref_params = ref_analysis.parameters
        if out_analysis is not None:
            events = _event_section(out_analysis.events, reference_events, a.rate_hz, label)
    parameters = _parameters(out_analysis.parameters if out_analysis else None, ref_params, reference_parameters)
    return Evaluation(
        out_source=out_source, reference_source=reference_source, rate_hz=a.rate_hz,
        n_frames=len(a.times), n_flagged=int(a.flagged.sum()), n_reference_missing=int((a.ref_missing & ~a.flagged).sum()),
        points=list(a.names), positions=positions, per_point_mm=per_point, swaps=swaps, angles_rmse_deg=angles,
        bias_mm=bias, events=events, events_baseline=baseline, parameters=parameters, notes=notes,
        n_out_frames=out.n_frames, n_reference_frames=a.ref_frames, n_reference_outside=a.ref_outside,
    )  # fmt: skip


def _worst_point(ev: Evaluation, members: tuple[str, ...] | None) -> str:
    """`` (worst point NAME X mm)`` of ``ev``'s points among ``members`` (None: all), what a CI log names as the
    drift; empty when none has a value."""
    values = {n: v for n, v in ev.per_point_mm.items() if (members is None or n in members) and math.isfinite(v)}
    if not values:
        return ""
    name = max(values, key=values.__getitem__)
    return f" (worst point {name} {values[name]:.1f} mm)"


def check_thresholds(ev: Evaluation, limits: Thresholds) -> list[str]:
    """The thresholds ``ev`` exceeds, one sentence each (empty: all passed); records those checked in
    ``ev.thresholds``.

    A checked value that is not available (every frame flagged, no event matched, no verdict) fails.
    """
    ev.thresholds = {k: v for k, v in asdict(limits).items() if v is not None}
    failures = []
    for limit, key, what in ((limits.max_mpjpe_mm, "all", "MPJPE (all points)"),
                             (limits.max_lower_limb_mpjpe_mm, "lower_limb", "lower-limb MPJPE")):  # fmt: skip
        if limit is None:
            continue
        v = (ev.positions.get(key) or {}).get("mpjpe_mm", math.nan)
        if not math.isfinite(v):
            failures.append(f"{what} not available (no frame compared)")
        elif v > limit:
            worst = _worst_point(ev, LOWER_LIMB if key == "lower_limb" else None)
            failures.append(f"{what} {v:.1f} mm > {limit:g} mm{worst}")
    if limits.max_angle_rmse_deg is not None:
        name, v = ev.max_checked_angle_rmse()
        if not math.isfinite(v):
            failures.append("joint-angle RMSE not available")
        elif v > limits.max_angle_rmse_deg:
            failures.append(f"{name} RMSE {v:.1f} deg > {limits.max_angle_rmse_deg:g} deg")
    timing = [(limit, key, unit, digits) for limit, key, unit, digits in
              ((limits.max_event_error_frames, "max_abs_frames", "frames", 2),
               (limits.max_event_error_ms, "max_abs_ms", "ms", 0)) if limit is not None]  # fmt: skip
    if timing:
        if not ev.events or not ev.events.get("n_matched"):
            failures.append("event timing not available (no detected event matched a reference event)")
        else:
            worst = max(ev.events.get("matches") or [{}], key=lambda m: abs(m.get("error_frames", 0.0)))
            for limit, key, unit, digits in timing:
                if (v := ev.events.get(key, math.nan)) > limit:
                    where = (f" (worst: {worst['side']} {worst['event']} at {worst['reference_s']:.3f} s, "
                             f"{worst[f'error_{unit}']:+.{digits}f} {unit})" if worst else "")  # fmt: skip
                    failures.append(f"event timing error {v:.{digits}f} {unit} > {limit:g} {unit}{where}")
        if ev.events and ev.events.get("n_missed"):
            missed = [f"{m['side']} {m['event']} at {m['time_s']:.3f} s" for m in ev.events.get("missed", [])]
            listed = ", ".join(missed[:4]) + (", ..." if len(missed) > 4 else "")
            failures.append(f"{ev.events['n_missed']} of the reference's {ev.events['n_reference']} events not "
                            f"detected in OUT" + (f" ({listed})" if listed else ""))  # fmt: skip
    if limits.min_compared_fraction is not None:
        total, share = ev.compared_share()
        if share < limits.min_compared_fraction:
            if total > ev.n_out_frames:
                failures.append(f"{ev.n_compared} of {total} frames compared ({share:.0%}) < "
                                f"{limits.min_compared_fraction:.0%} (OUT's {ev.n_out_frames} and the reference run's "
                                f"{ev.n_reference_outside} that OUT lacks; flagged, or without a reference frame)")
            else:
                failures.append(f"{ev.n_compared} of OUT's {ev.n_out_frames} frames compared ({share:.0%}) < "
                                f"{limits.min_compared_fraction:.0%} (flagged, or without a reference frame)")
    if limits.require_verdict is not None:
        order = {v: k for k, v in enumerate(VERDICTS)}  # ok < doubtful < failed
        if ev.verdict not in order:
            failures.append(f"no verdict to require {limits.require_verdict!r} of (OUT has no finished track.json)")
        elif order[ev.verdict] > order[limits.require_verdict]:
            failures.append(f"the run's verdict is {ev.verdict}, not {limits.require_verdict}"
                            + ("" if limits.require_verdict == "ok" else " or better"))  # fmt: skip
    return failures
