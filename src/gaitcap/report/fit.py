"""What the report shows of the tracking fit: the run's record and verdict, the frames that need a
look, and the joint angles' uncertainty bands.

Frames that need a look ("attention" frames):

- *flagged*: the tracker's per-frame quality is not ok (a fit below ``quality.min_fit``, the subject
  out of view, or not found);
- *uncertain*: the mean uncertainty of the lower-limb points exceeds the run's ``verdict.uncertain_mm``
  (:data:`UNCERTAIN_MM` when its config does not say), the threshold its verdict counted. The
  reported uncertainty is calibrated so that 95 % of the errors fall within two of it
  (gaitcap.quality); on the varied suite the mean lower-limb uncertainty of a run was about 1.6
  times its lower-limb error (median 71 mm for 44 mm, ``scripts/bench_uncertainty.py``), so 90 mm
  marks the frames whose expected error reaches the 60 mm above which a run is not trusted.

The contact sheet takes the detected gait events (foot strikes and foot offs: four frames per
gait cycle at the phases a clinician reads) or, without events, frames spread evenly; and, more
densely, the attention frames (:func:`select_frames`).

Angle bands (:func:`angle_bands`): the per-point uncertainty is propagated through the same angle
code (:func:`gaitcap.gait.angles.joint_angles`) by Monte Carlo: every point of every frame is
displaced at random, independently, by an isotropic Gaussian whose RMS 3D distance is its
reported uncertainty (a standard deviation of sigma / sqrt(3) per axis); the band is the standard
deviation of the angle over the draws. Errors correlated across points and frames (a leg swap, a
whole limb offset) are not in it.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from gaitcap.config import parse_yaml
from gaitcap.evaluation.metrics import runs, wrap_deg
from gaitcap.gait.angles import joint_angles
from gaitcap.gait.events import WalkingDirection
from gaitcap.io.track_h5 import QUALITY_NAMES, QUALITY_OK, TrackRecord, read_track_record
from gaitcap.track_summary import Verdict, read_track_json, read_verdict
from gaitcap.tracking.config import VerdictConfig
from gaitcap.trajectory import LOWER_LIMB, GaitEvent, Trajectory

log = logging.getLogger("gaitcap.report")

#: a frame whose mean lower-limb uncertainty exceeds this (mm) is shown as uncertain, for a run whose
#: config does not say (the verdict's default ``uncertain_mm``, tracking.yaml)
UNCERTAIN_MM = VerdictConfig().uncertain_mm
#: the quality.min_fit of a run whose config does not say
DEFAULT_MIN_FIT = 0.55
#: Monte Carlo draws of the angle bands (seeded: the report is reproducible)
BAND_DRAWS = 32
BAND_SEED = 0
#: at most this many attention frames on the contact sheet, and this many regular ones
MAX_ATTENTION_FRAMES = 12
MAX_REGULAR_FRAMES = 16
@dataclass(frozen=True)
class SheetFrame:
    """One frame of the contact sheet: its index and why it was chosen (short labels)."""

    index: int
    reasons: tuple[str, ...]
    attention: bool = False


@dataclass(frozen=True)
class FitRecord:
    """A tracking run as the report sees it.

    Attributes:
        run_dir: the tracking output folder.
        record: what the tracker recorded per frame (T frames).
        track_json: the ``track.json`` document (empty when absent).
        min_fit: the run's ``quality.min_fit``.
        uncertain_mm: the run's ``verdict.uncertain_mm``: a frame whose mean lower-limb uncertainty
            exceeds it is shown as uncertain.
    """

    run_dir: Path
    record: TrackRecord
    track_json: dict[str, Any] = field(default_factory=dict)
    min_fit: float = DEFAULT_MIN_FIT
    uncertain_mm: float = UNCERTAIN_MM

    @property
    def verdict(self) -> Verdict | None:
        return read_verdict(self.track_json)

    @property
    def flagged(self) -> np.ndarray:
        """(T,) bool: the tracker's quality is not ok."""
        return self.record.quality != QUALITY_OK

    def lower_limb_uncertainty_mm(self) -> np.ndarray:
        """(T,) mean uncertainty of the lower-limb points, mm (NaN where none was estimated)."""
        idx = [self.record.names.index(n) for n in LOWER_LIMB if n in self.record.names]
        u = self.record.uncertainty[:, idx]
        out = np.full(len(u), np.nan)
        ok = np.all(np.isfinite(u), axis=1)
        out[ok] = 1000.0 * u[ok].mean(axis=1)
        return out

    @property
    def uncertain(self) -> np.ndarray:
        """(T,) bool: the lower-limb uncertainty exceeds :attr:`uncertain_mm`."""
        with np.errstate(invalid="ignore"):
            return self.lower_limb_uncertainty_mm() > self.uncertain_mm

    def quality_name(self, t: int) -> str:
        return QUALITY_NAMES.get(int(self.record.quality[t]), "flagged").replace("_", " ")


def load_fit_record(trajectories: Path) -> FitRecord | None:
    """The run of a tracker's ``trajectories.h5`` (with ``track.json`` beside it), or None for a
    trajectory without the tracker's per-frame record (a motion file, another tool's output)."""
    record = read_track_record(trajectories)
    if record is None:
        return None
    run_dir = trajectories.parent
    config = record.attrs.get("config")
    return FitRecord(run_dir, record, read_track_json(run_dir) or {},
                     _config_value(config, "quality", "min_fit", DEFAULT_MIN_FIT),
                     _config_value(config, "verdict", "uncertain_mm", UNCERTAIN_MM))  # fmt: skip


def _config_value(config_yaml: Any, section: str, key: str, default: float) -> float:
    """``section.key`` of the run's tracking config (the YAML text trajectories.h5 keeps), or
    ``default`` when it does not say (an older run, another tool's file)."""
    try:
        value = (parse_yaml(config_yaml) or {}).get(section, {}).get(key)
    except (yaml.YAMLError, AttributeError, TypeError):
        value = None
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else default


def _thin(indices: list[int], n: int) -> list[int]:
    """At most ``n`` of ``indices``, spread evenly."""
    if len(indices) <= n:
        return indices
    return [indices[int(k)] for k in np.linspace(0, len(indices) - 1, n).round()]


def regular_frames(events: list[GaitEvent], rate_hz: float, t0_s: float, n_frames: int) -> dict[int, str]:
    """Frame -> label: the detected gait events, or 8 frames spread evenly without events."""
    out: dict[int, str] = {}
    for e in events:
        t = int(round((e.time_s - t0_s) * rate_hz))
        if 0 <= t < n_frames:
            label = f"{e.side} {e.event.replace('_', ' ')}"
            out[t] = f"{out[t]}, {label}" if t in out else label
    if not out:
        out = {int(t): "evenly spaced" for t in np.unique(np.linspace(0, n_frames - 1, min(8, n_frames)).round())}
    keep = _thin(sorted(out), MAX_REGULAR_FRAMES)
    return {t: out[t] for t in keep}


def attention_frames(fit: FitRecord, spacing: int) -> dict[int, str]:
    """Frame -> label of the frames that need a look: in each run of flagged or uncertain frames,
    its worst frame (lowest fit, else highest uncertainty) and one every ``spacing`` frames; at most
    :data:`MAX_ATTENTION_FRAMES`: every run's worst frame first (flagged runs before uncertain ones,
    the worst first), then the others."""
    unc = fit.lower_limb_uncertainty_mm()
    fit_values = np.nan_to_num(fit.record.fit, nan=0.0)
    picks: list[tuple[bool, float, int, str]] = []  # (a run's worst, severity, frame, label)
    for mask, kind in ((fit.flagged, "flagged"), (fit.uncertain & ~fit.flagged, "uncertain")):
        for a, b in runs(mask):
            if kind == "flagged":
                worst = a + int(np.argmin(fit_values[a:b]))
                severity = 2.0 - fit_values[worst]
            else:
                worst = a + int(np.nanargmax(unc[a:b]))
                severity = float(unc[worst]) / 1000.0
            frames = sorted({worst, *range(a + spacing // 2, b, max(spacing, 1))})
            picks += [(t == worst, severity - 1e-3 * abs(t - worst), t, _attention_label(fit, t, kind)) for t in frames]
    picks.sort(key=lambda p: (not p[0], -p[1]))
    return {t: label for _, _, t, label in picks[:MAX_ATTENTION_FRAMES]}


def _attention_label(fit: FitRecord, t: int, kind: str) -> str:
    if kind == "flagged":
        return fit.quality_name(t)
    return f"uncertainty > {fit.uncertain_mm:g} mm"


def select_frames(fit: FitRecord, events: list[GaitEvent], t0_s: float = 0.0) -> list[SheetFrame]:
    """The contact sheet's frames, in time order (see the module docstring). Within a run of
    attention frames they are half as far apart as the events (an eighth of a stride)."""
    T, rate = fit.record.n_frames, fit.record.rate_hz
    regular = regular_frames(events, rate, t0_s, T)
    spacing = max(1, int(np.median(np.diff(sorted(regular)))) // 2) if len(regular) > 1 else max(1, T // 16)
    attention = attention_frames(fit, spacing)
    for t in regular:  # a regular frame that needs a look says so too
        if t not in attention and (fit.flagged[t] or fit.uncertain[t]):
            attention[t] = _attention_label(fit, t, "flagged" if fit.flagged[t] else "uncertain")
    frames = []
    for t in sorted(set(regular) | set(attention)):
        reasons = tuple(r for r in (attention.get(t), regular.get(t)) if r)
        frames.append(SheetFrame(t, reasons, t in attention))
    return frames


def angle_bands(traj: Trajectory, direction: WalkingDirection, names: tuple[str, ...],
                draws: int = BAND_DRAWS, seed: int = BAND_SEED) -> dict[str, np.ndarray] | None:  # fmt: skip
    """Standard deviation (T,) degrees of each angle of ``names`` (e.g. ``knee_flexion_l``) under the
    trajectory's per-point uncertainty (``traj.meta["uncertainty"]`` (T, P) metres; see the module
    docstring), or None when the trajectory has none. The draws' deviations from the angle of the
    trajectory itself are wrapped to +/-180 degrees first (a draw turning a foot past the Cardan
    angles' wrap is a small deviation, not 360 degrees). NaN where a point is missing."""
    sigma = traj.meta.get("uncertainty")
    if sigma is None or np.shape(sigma) != traj.points.shape[:2]:
        return None
    rng = np.random.default_rng(seed)
    T = traj.n_frames
    noise = rng.normal(size=(draws, *traj.points.shape)) * (np.asarray(sigma)[None, :, :, None] / np.sqrt(3.0))
    noise = np.concatenate([np.zeros((1, *traj.points.shape)), noise])  # draw 0: the trajectory itself
    stacked = (traj.points[None] + noise).reshape((draws + 1) * T, *traj.points.shape[1:])
    angles, _ = joint_angles(replace(traj, points=stacked, events=(), meta={}), direction)
    with warnings.catch_warnings():  # all-NaN frames (flagged) give NaN, not a warning
        warnings.simplefilter("ignore", RuntimeWarning)
        out = {}
        for name in names:
            a = angles[name].reshape(draws + 1, T)
            out[name] = np.nanstd(wrap_deg(a[1:] - a[0]), axis=0)
        return out
