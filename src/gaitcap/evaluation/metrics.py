"""Error measures between a tracked trajectory and a reference (pure functions, no I/O).

Positions: the Euclidean distance per frame and point, in millimetres; MPJPE (mean per-joint
position error) is its mean over frames and points. Angles: RMSE of the wrapped difference, in
degrees. Events: detected events are matched one-to-one to reference events of the same side and
kind, closest pairs first, within ``max_match_s``; error = detected - reference.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gaitcap.timeseries import finite_runs
from gaitcap.trajectory import EVENT_KINDS, GaitEvent, exchanged_frames

#: the left/right point pairs of the legs, exchanged by a left/right swap
LEG_PAIRS: tuple[tuple[str, str], ...] = (
    ("hip_l", "hip_r"), ("knee_l", "knee_r"), ("ankle_l", "ankle_r"), ("heel_l", "heel_r"), ("toe_l", "toe_r"),
)  # fmt: skip


def _nan_stats(values: np.ndarray) -> dict[str, float]:
    """mean, median, p95, max of the finite ``values`` (NaN when there are none)."""
    v = values[np.isfinite(values)]
    if len(v) == 0:
        return {"mean": math.nan, "median": math.nan, "p95": math.nan, "max": math.nan}
    return {"mean": float(v.mean()), "median": float(np.median(v)), "p95": float(np.percentile(v, 95)), "max": float(v.max())}


def point_distances_mm(est: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Euclidean distance per frame and point.

    Args:
        est, ref: positions in metres, shape (F, P, 3).

    Returns:
        (F, P) millimetres; NaN where either is missing.
    """
    if est.shape != ref.shape or est.ndim != 3 or est.shape[2] != 3:
        raise ValueError(f"positions must both have shape (F, P, 3), got {est.shape} and {ref.shape}")
    return 1000.0 * np.linalg.norm(est - ref, axis=2)


def group_errors(dist_mm: np.ndarray, names: Sequence[str], group: Sequence[str]) -> dict[str, float] | None:
    """MPJPE statistics of the points of ``group`` present in ``names``.

    Args:
        dist_mm: (F, P) distances of the evaluated frames.

    Returns:
        ``mpjpe_mm`` (mean over frames and points) and the ``median``/``p95``/``max`` of the
        per-frame mean, plus ``n_points``; None when no point of the group is present.
    """
    idx = [i for i, n in enumerate(names) if n in group]
    if not idx:
        return None
    sub = dist_mm[:, idx]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        per_frame = np.nanmean(sub, axis=1) if len(sub) else np.zeros(0)
    stats = _nan_stats(per_frame)
    finite = sub[np.isfinite(sub)]
    return {
        "mpjpe_mm": float(finite.mean()) if len(finite) else math.nan,
        "frame_median_mm": stats["median"],
        "frame_p95_mm": stats["p95"],
        "frame_max_mm": stats["max"],
        "n_points": len(idx),
    }


def point_bias_mm(est: np.ndarray, ref: np.ndarray, names: Sequence[str], forward: np.ndarray | None
                  ) -> dict[str, dict[str, float]]:  # fmt: skip
    """The systematic part of each point's error: its mean signed error over the frames, in the
    walking frame.

    ``forward`` is the unit horizontal walking direction (2,) (None: unknown; then only ``up`` is
    given). ``outward`` is away from the body's midline: to the left for a ``_l`` point, to the right
    for a ``_r`` point, to the left for a point of the midline; ``up`` is world z. ``share`` is the
    length of the mean error vector over the mean distance (0: the errors cancel over the frames,
    1: the same offset in every frame); a point missing in every frame is left out.

    Args:
        est, ref: positions (F, P, 3), metres (NaN: missing).
        names: the P point names.
        forward: (2,) unit horizontal vector, or None.

    Returns:
        name -> {forward, outward, up (mm), share}.
    """
    if est.shape != ref.shape or est.ndim != 3 or est.shape[2] != 3 or est.shape[1] != len(names):
        raise ValueError(f"positions must both have shape (F, {len(names)}, 3), got {est.shape} and {ref.shape}")
    left = None if forward is None else np.array([-forward[1], forward[0]])
    out: dict[str, dict[str, float]] = {}
    for i, name in enumerate(names):
        e = est[:, i] - ref[:, i]
        e = 1000.0 * e[np.all(np.isfinite(e), axis=1)]
        if not len(e):
            continue
        mean = e.mean(axis=0)
        side = -1.0 if name.endswith("_r") else 1.0
        out[name] = {
            "forward": math.nan if forward is None else float(mean[:2] @ forward),
            "outward": math.nan if left is None else float(side * (mean[:2] @ left)),
            "up": float(mean[2]),
            "share": float(np.linalg.norm(mean) / np.linalg.norm(e, axis=1).mean()) if np.any(e) else 0.0,
        }
    return out


def swap_mask(est: np.ndarray, ref: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """Frames where exchanging the left and right leg points of ``est`` fits ``ref`` better.

    The leg points are :data:`LEG_PAIRS` present in ``names``; the fit is their mean distance.

    Args:
        est, ref: (F, P, 3) metres.

    Returns:
        (F,) bool; False where a distance is NaN or the trajectory has no leg pair.
    """
    pairs = [(names.index(a), names.index(b)) for a, b in LEG_PAIRS if a in names and b in names]
    if not pairs:
        return np.zeros(len(est), dtype=bool)
    return exchanged_frames(est, ref, pairs)


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` of each run of True in a (F,) bool array (:func:`gaitcap.timeseries.finite_runs`)."""
    return finite_runs(mask)


def wrap_deg(d: np.ndarray) -> np.ndarray:
    """Angle differences wrapped to [-180, 180) degrees."""
    return (np.asarray(d) + 180.0) % 360.0 - 180.0


def _angle_differences(est: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """The wrapped differences est - ref (degrees) of two (T,) angle series where both are finite."""
    d = wrap_deg(np.asarray(est) - np.asarray(ref))
    return d[np.isfinite(d)]


def angle_rmse_deg(est: np.ndarray, ref: np.ndarray) -> tuple[float, int]:
    """RMSE of the wrapped difference of two (T,) angle series in degrees, and the frames used."""
    d = _angle_differences(est, ref)
    return (float(np.sqrt(np.mean(d**2))) if len(d) else math.nan), len(d)


def angle_bias_deg(est: np.ndarray, ref: np.ndarray) -> tuple[float, int]:
    """Mean of the wrapped difference est - ref of two (T,) angle series in degrees (the systematic
    part of :func:`angle_rmse_deg`: RMSE^2 = bias^2 + variance of the difference), and the frames used."""
    d = _angle_differences(est, ref)
    return (float(np.mean(d)) if len(d) else math.nan), len(d)


@dataclass(frozen=True)
class EventMatch:
    """A detected event matched to a reference event (error = detected - reference)."""

    side: str
    event: str
    reference_s: float
    detected_s: float

    @property
    def error_s(self) -> float:
        return self.detected_s - self.reference_s


def match_events(
    detected: Sequence[GaitEvent], reference: Sequence[GaitEvent], max_match_s: float
) -> tuple[list[EventMatch], list[GaitEvent], list[GaitEvent]]:
    """Match events one-to-one by side and kind, closest pairs first, within ``max_match_s``.

    Returns:
        The matches (sorted by reference time), the reference events left unmatched (missed) and
        the detected events left unmatched (extra).
    """
    pairs = sorted(
        (abs(d.time_s - r.time_s), i, j)
        for i, r in enumerate(reference)
        for j, d in enumerate(detected)
        if d.side == r.side and d.event == r.event and abs(d.time_s - r.time_s) <= max_match_s
    )
    used_r: set[int] = set()
    used_d: set[int] = set()
    matches = []
    for _, i, j in pairs:
        if i in used_r or j in used_d:
            continue
        used_r.add(i)
        used_d.add(j)
        r, d = reference[i], detected[j]
        matches.append(EventMatch(r.side, r.event, r.time_s, d.time_s))
    matches.sort(key=lambda m: m.reference_s)
    missed = [r for i, r in enumerate(reference) if i not in used_r]
    extra = [d for j, d in enumerate(detected) if j not in used_d]
    return matches, missed, extra


def event_error_summary(matches: Sequence[EventMatch], rate_hz: float) -> dict[str, float | int]:
    """Timing error statistics in ms and frames: overall and per kind (``foot_strike``...)."""

    def stats(errors: list[float]) -> dict[str, float | int]:
        e = np.asarray(errors, dtype=np.float64)
        if len(e) == 0:
            return {"n": 0, "mean_ms": math.nan, "mean_abs_ms": math.nan, "max_abs_ms": math.nan,
                    "mean_abs_frames": math.nan, "max_abs_frames": math.nan}  # fmt: skip
        return {
            "n": len(e),
            "mean_ms": float(1000 * e.mean()),
            "mean_abs_ms": float(1000 * np.abs(e).mean()),
            "max_abs_ms": float(1000 * np.abs(e).max()),
            "mean_abs_frames": float(np.abs(e).mean() * rate_hz),
            "max_abs_frames": float(np.abs(e).max() * rate_hz),
        }

    out: dict[str, float | int] = dict(stats([m.error_s for m in matches]))
    for kind in EVENT_KINDS:
        for key, value in stats([m.error_s for m in matches if m.event == kind]).items():
            out[f"{kind}_{key}"] = value
    return out


def mask_iou(est: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Intersection over union of two stacks of silhouettes, frame by frame.

    Args:
        est, ref: (F, H, W) masks, nonzero = person.

    Returns:
        (F,) float; NaN where both masks are empty.
    """
    if est.shape != ref.shape:
        raise ValueError(f"masks must have the same shape, got {est.shape} and {ref.shape}")
    a, b = est.astype(bool), ref.astype(bool)
    inter = np.logical_and(a, b).sum(axis=(1, 2))
    union = np.logical_or(a, b).sum(axis=(1, 2))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(union > 0, inter / np.maximum(union, 1), np.nan)


def iou_summary(iou: np.ndarray) -> dict[str, float | int]:
    """mean, median and 10th percentile of the finite values of a (F,) IoU series, and their count."""
    v = iou[np.isfinite(iou)]
    if len(v) == 0:
        return {"n_frames": 0, "mean": math.nan, "median": math.nan, "p10": math.nan}
    return {"n_frames": len(v), "mean": float(v.mean()), "median": float(np.median(v)), "p10": float(np.percentile(v, 10))}
