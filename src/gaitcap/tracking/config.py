"""Schema of ``configs/tracking.yaml`` (defaults live there and here, nowhere else)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, field_validator

from gaitcap.body.model import BodyModel
from gaitcap.config import Strict, default_config_path, load_config_file
from gaitcap.errors import ConfigError
from gaitcap.tracking.chain import Subtree, subtrees

TrackerName = Literal["condensation", "ipf", "factored-ipf"]


def _check_patterns(v: dict[str, float]) -> dict[str, float]:
    """{regular expression: positive number}: raises ValueError naming a bad pattern or value."""
    for pattern, value in v.items():
        try:
            re.compile(pattern)
        except re.error as e:
            raise ValueError(f"'{pattern}' is not a valid regular expression ({e})") from e
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"'{pattern}': must be a positive number")
    return v


def _check_around_one(v: tuple[float, float], what: str) -> tuple[float, float]:
    """A (low, high) range of factors that holds 1: raises ValueError naming ``what``."""
    if not (0 < v[0] <= 1 <= v[1]):
        raise ValueError(f"{what} must satisfy 0 < low <= 1 <= high")
    return v


class Layer(Strict):
    step_deg: float = Field(gt=0, le=30)
    step_m: float = Field(gt=0, le=0.5)
    shrink: float = Field(default=1.0, gt=0, le=1)


class FactoredIPFConfig(Strict):
    particles: int = Field(default=250, ge=10, le=100_000)
    root_particles: int = Field(default=600, ge=10, le=100_000)
    order: list[str] = Field(default_factory=list)
    layers: list[Layer] = Field(min_length=1)
    passes: int = Field(default=2, ge=1, le=10)
    root_refine: Literal["alone", "rigid"] = "alone"
    root_anchored: list[str] = Field(default_factory=list)
    coupled: dict[str, list[str]] = Field(default_factory=dict)
    swap_hypothesis: bool = True
    swap_search: Literal["full", "legs"] = "legs"
    swap_within_deg: float = Field(default=25.0, gt=0, le=180)
    swap_fit_drop: float | None = Field(default=0.04, gt=0, le=1)
    swap_fit_frames: int = Field(default=10, ge=1, le=1000)
    swap_margin: float = Field(default=0.008, ge=0, le=1)
    swap_continuity: bool = True
    recover_widen: float | None = Field(default=3.0, gt=1, le=10)
    turn_widen: float | None = Field(default=2.0, gt=1, le=10)
    turn_trigger: float = Field(default=0.8, gt=0, le=2)
    turn_frames: int = Field(default=2, ge=1, le=25)
    keep_previous: bool = True
    ess_threshold: float = Field(default=0.5, ge=0, le=1)


class IPFConfig(Strict):
    particles: int = Field(default=3000, ge=10, le=1_000_000)
    layers: list[Layer] = Field(min_length=1)


class CondensationConfig(Strict):
    particles: int = Field(default=3000, ge=10, le=1_000_000)
    sigma_fraction: float = Field(default=0.4, gt=0, le=2)


class QualityConfig(Strict):
    min_fit: float = Field(default=0.55, le=1)
    min_silhouette_fraction: float = Field(default=0.002, ge=0, lt=1)


class VerdictConfig(Strict):
    """Thresholds of a run's verdict (gaitcap.quality.judge)."""

    min_ok_fraction: float = Field(default=0.1, ge=0, le=1)
    max_flagged_fraction: float = Field(default=0.5, ge=0, le=1)
    max_crossed_fraction: float = Field(default=0.1, gt=0, le=1)
    crossed_margin_m: float = Field(default=0.02, ge=0)
    min_exchanged_frames: int = Field(default=3, ge=1)
    exchanged_margin_m: float = Field(default=0.03, ge=0)
    max_floor_offset_m: float = Field(default=0.1, gt=0)
    segment_ratio: tuple[float, float] = (0.75, 1.33)
    min_image_height_px: float = Field(default=60.0, ge=0)
    min_oblique_deg: float = Field(default=15.0, ge=0, le=45)
    min_leg_support: float = Field(default=0.5, ge=0, le=1)
    max_unsupported_fraction: float = Field(default=0.25, gt=0, le=1)
    uncertain_mm: float = Field(default=90.0, gt=0)
    max_uncertain_fraction: float = Field(default=0.25, gt=0, le=1)

    @field_validator("segment_ratio")
    @classmethod
    def _check_ratio(cls, v: tuple[float, float]) -> tuple[float, float]:
        return _check_around_one(v, "segment_ratio")


class UncertaintyCoefficients(Strict):
    """log u = intercept + log_residual log r + fit (1 - fit) + crossed_run c + floor |z| + crossed_frame x
    (gaitcap.quality.calibrated_uncertainty)."""

    intercept: float = -2.01
    log_residual: float = Field(default=0.22, ge=0)
    fit: float = Field(default=1.85, ge=0)
    crossed_run: float = Field(default=0.67, ge=0)
    floor: float = Field(default=2.57, ge=0)
    crossed_frame: float = Field(default=0.52, ge=0)


class UncertaintyConfig(Strict):
    cutoff_hz: float = Field(default=6.0, gt=0)
    min_residual_m: float = Field(default=0.001, gt=0)
    min_m: float = Field(default=0.005, ge=0)
    coefficients: UncertaintyCoefficients = Field(default_factory=UncertaintyCoefficients)
    #: point name (regular expression) -> multiplier of its uncertainty; points not matched: 1
    point_scale: dict[str, float] = Field(default_factory=dict)

    @field_validator("point_scale")
    @classmethod
    def _check_scale(cls, v: dict[str, float]) -> dict[str, float]:
        return _check_patterns(v)

    def scales(self, names: tuple[str, ...]) -> np.ndarray:
        """The multiplier of each point (P,): the first pattern matching its name, else 1."""
        return np.array([next((f for p, f in self.point_scale.items() if re.fullmatch(p, n)), 1.0) for n in names])


class InitConfig(Strict):
    heading_step_deg: float = Field(default=15, gt=0, le=90)
    frames: int = Field(default=8, ge=1, le=100)
    refine_passes: int = Field(default=4, ge=0, le=50)
    widen: float = Field(default=2.5, ge=1, le=10)
    leg_frames: int = Field(default=8, ge=0, le=100)


_TARGET = re.compile(r"(?P<inv>1/)?(?P<seg>\w+)\.(?P<axis>[xyz])(\^(?P<power>[-+]?\d+(\.\d*)?))?")


def parse_target(target: str, parameter: str = "") -> tuple[str, int, float]:
    """A shape parameter's target -> (segment, axis index, power): ``seg.axis`` scales that axis by
    the parameter's factor f, ``1/seg.axis`` by 1/f, ``seg.axis^p`` by f**p (a compensating move:
    ``[foot_l.z, shank_l.z^-0.16]`` raises the ankle and keeps the knee where it was)."""
    m = _TARGET.fullmatch(target)
    if m is None or (m["inv"] and m["power"]):
        raise ValueError(f"{parameter}: '{target}' is not 'segment.axis', '1/segment.axis' or 'segment.axis^power' "
                         f"(axis x, y or z)")  # fmt: skip
    power = -1.0 if m["inv"] else float(m["power"] or 1.0)
    return m["seg"], "xyz".index(m["axis"]), power


class ShapeConfig(Strict):
    """The shape calibration (tracking/shape.py); defaults as in the shipped tracking.yaml, but off and
    without parameters unless configured."""

    enabled: bool = False
    #: per-parameter (low, high) range of the factor, overriding ``bounds``
    limits: dict[str, tuple[float, float]] = Field(default_factory=dict)
    #: accepted (low, high) ratio of each calibrated length to the height (gaitcap.body.measures
    #: names); a calibrated body outside them is rejected and the shipped proportions are tracked
    ranges: dict[str, tuple[float, float]] = Field(default_factory=dict)
    frames: int = Field(default=13, ge=2, le=250)
    samples: int = Field(default=5, ge=1, le=100)
    steps: list[float] = Field(default_factory=lambda: [0.06], min_length=1)
    bounds: tuple[float, float] = (0.7, 1.35)
    parameters: dict[str, list[str]] = Field(default_factory=dict)
    #: particles / root particles of the one-pass re-fit that scores each candidate (the search
    #: compares candidates on a paired random stream, so a small budget is enough)
    refit_particles: tuple[int, int] = (40, 100)
    #: moves of one parameter in one round while the fit keeps improving (pattern search)
    max_moves: int = Field(default=3, ge=1)
    #: also score each candidate with the window's poses moved vertically so that its lowest point
    #: stays on the floor (tracking/shape.py); the better of the two counts
    planted: bool = True
    #: after the coordinate search, this many random candidates moving every parameter at once
    #: (each factor times exp(sigma z), z ~ N(0, 1)); a better one replaces the current shape
    random_candidates: int = Field(default=0, ge=0)
    random_sigma: float = Field(default=0.04, gt=0.0, lt=0.5)
    #: track the window again with the shape found so far before each round of ``steps`` but the
    #: first (the re-fits of a round start from poses tracked with a wrong shape otherwise)
    retrack: bool = False
    #: threads that score candidates side by side (their re-fits are independent, the result the
    #: same as one after the other); the compiled kernels of each run on ``threads``. The
    #: calibration's serial parts (initialisation, the window tracked, the legs settled again) run
    #: their kernels on max(``threads``, this) threads: the prefetch thread has little to do then
    workers: int = Field(default=2, ge=1, le=64)
    #: calibrations run side by side (one thread each) with their own random streams, their factors
    #: averaged (geometric mean): one calibration's factors are noisy at the same fit
    repeats: int = Field(default=1, ge=1, le=8)

    @field_validator("refit_particles")
    @classmethod
    def _check_refit(cls, v: tuple[int, int]) -> tuple[int, int]:
        if min(v) < 2:
            raise ValueError("both budgets (particles, root particles) must be at least 2")
        return v

    @field_validator("steps")
    @classmethod
    def _check_steps(cls, v: list[float]) -> list[float]:
        if not all(0 < s < 0.5 for s in v):
            raise ValueError("every step must be in (0, 0.5)")
        return v

    @field_validator("bounds")
    @classmethod
    def _check_bounds(cls, v: tuple[float, float]) -> tuple[float, float]:
        return _check_around_one(v, "bounds")

    @field_validator("limits")
    @classmethod
    def _check_limits(cls, v: dict[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
        for name, span in v.items():
            _check_around_one(span, f"{name}: a range")
        return v

    @field_validator("ranges")
    @classmethod
    def _check_ranges(cls, v: dict[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
        from gaitcap.body.measures import LENGTHS

        for name, (low, high) in v.items():
            if name not in LENGTHS:
                raise ValueError(f"{name}: not a length ({', '.join(LENGTHS)})")
            if not 0 < low < high < 1:
                raise ValueError(f"{name}: a range of fractions of the height must satisfy 0 < low < high < 1")
        return v

    @field_validator("parameters")
    @classmethod
    def _check_targets(cls, v: dict[str, list[str]]) -> dict[str, list[str]]:
        for name, targets in v.items():
            for t in targets:
                parse_target(t, name)
        return v

    def limits_of(self) -> dict[str, tuple[float, float]]:
        """Every parameter's factor range: its ``limits`` entry, else ``bounds``."""
        return {name: self.limits.get(name, self.bounds) for name in self.parameters}

    def check_segments(self, model: BodyModel) -> None:
        unknown = sorted(set(self.limits) - set(self.parameters))
        if unknown:
            raise ConfigError(f"tracking config: shape.limits: {', '.join(unknown)} not in shape.parameters")
        known = {s.name for s in model.segments}
        for name, targets in self.parameters.items():
            for t in targets:
                seg = parse_target(t, name)[0]
                if seg not in known:
                    raise ConfigError(f"tracking config: shape.parameters.{name}: unknown segment '{seg}'")


class SmoothingConfig(Strict):
    cutoff_hz: float | None = Field(default=4.5, gt=0)
    order: int = Field(default=4, ge=1, le=8)


class BackwardConfig(Strict):
    """The second pass over the clip, backwards in time (tracking/backward.py)."""

    enabled: bool = True
    agree_m: float = Field(default=0.03, gt=0, le=0.5)
    leg_order: bool = True
    crossing_m: float = Field(default=0.10, gt=0, le=0.5)
    order_fit_tolerance: float = Field(default=0.015, ge=0, le=1)
    restart: bool = True
    stretch_frames: int | None = Field(default=25, ge=2)
    #: a run that no camera views obliquely (quality.no_oblique_view) is also tracked from its legs'
    #: mirror, forwards and backwards and merged the same way; the mirror's run replaces it whole if it
    #: holds the legs the other way round and fits better (gaitcap.pipeline._mirror_run)
    mirror_run: bool = True
    #: where the merged estimate and the other pass agree (agree_m), the frame takes their mean pose
    average: bool = True


class LegGapConfig(Strict):
    """The legs cannot pass through each other: a posture prior on the gap between their axes
    (gaitcap.tracking.contact.leg_gap), as fractions of the subject's height."""

    min: float = Field(default=0.045, ge=0, le=0.2)
    sigma: float = Field(default=0.005, gt=0, le=0.2)


class LostLegsConfig(Strict):
    """A run whose legs lie off a camera's masks (``verdict.min_leg_support``: the masks lost them) is
    tracked again with the faint pixels outside the masks counted as doubtful (gaitcap.pipeline)."""

    retrack: bool = True
    doubt_min: float = Field(default=0.3, ge=0, lt=1)


class FrameSyncConfig(Strict):
    """Cameras whose videos look out of step (gaitcap.sync_check): tracked again with the frames found
    skipped at the start of the late-starting cameras' videos (session.yaml's ``skip_frames``)."""

    retrack: bool = True


class TrackingConfig(Strict):
    tracker: TrackerName = "factored-ipf"
    scale: float = Field(default=0.5, gt=0.05, le=1)
    beta: float = Field(default=40.0, gt=0)
    soft_silhouettes: bool = False
    intervals: dict[str, float]
    prior: dict[str, float] = Field(default_factory=dict)
    leg_gap: LegGapConfig = Field(default_factory=LegGapConfig)
    factored_ipf: FactoredIPFConfig
    ipf: IPFConfig
    condensation: CondensationConfig
    quality: QualityConfig = Field(default_factory=QualityConfig)
    verdict: VerdictConfig = Field(default_factory=VerdictConfig)
    uncertainty: UncertaintyConfig = Field(default_factory=UncertaintyConfig)
    init: InitConfig = Field(default_factory=InitConfig)
    smoothing: SmoothingConfig = Field(default_factory=SmoothingConfig)
    shape: ShapeConfig = Field(default_factory=ShapeConfig)
    backward: BackwardConfig = Field(default_factory=BackwardConfig)
    lost_legs: LostLegsConfig = Field(default_factory=LostLegsConfig)
    frame_sync: FrameSyncConfig = Field(default_factory=FrameSyncConfig)
    threads: int | None = Field(default=None, ge=1)
    seed: int = Field(default=0, ge=0)  # numpy's seed sequences take no negative number

    @field_validator("intervals", "prior")
    @classmethod
    def _check_patterns(cls, v: dict[str, float]) -> dict[str, float]:
        return _check_patterns(v)

    def check(self, model: BodyModel) -> None:
        """Every check that needs the body model (DOF and segment names), at once: raises
        :class:`ConfigError` naming the key."""
        self.half_widths(model)
        self.prior_sigmas(model)
        self.order_indices(model)
        self.explored_dofs(model, subtrees(model))
        self.anchored_children(model)
        self.shape.check_segments(model)

    def half_widths(self, model: BodyModel) -> np.ndarray:
        """Interval half-width per DOF (D,), radians / metres. Each DOF must match one pattern."""
        return _per_dof("intervals", self.intervals, model, required=True)

    def prior_sigmas(self, model: BodyModel) -> np.ndarray:
        """Standard deviation of the posture prior per DOF (D,), radians / metres; inf: no prior."""
        return _per_dof("prior", self.prior, model, required=False)

    def order_indices(self, model: BodyModel) -> list[int]:
        """Segment indices of the factored chain walk; every segment once, parents first."""
        names = self.factored_ipf.order or [s.name for s in model.segments]
        known = {s.name for s in model.segments}
        unknown = [n for n in names if n not in known]
        if unknown:
            raise ConfigError(f"tracking config: factored_ipf.order: unknown segments {', '.join(unknown)}")
        if sorted(names) != sorted(known):
            missing = sorted(known - set(names))
            raise ConfigError(f"tracking config: factored_ipf.order must list every segment once (missing: {', '.join(missing) or 'none'})")
        idx = [model.segment(n).index for n in names]
        seen: set[int] = set()
        for i in idx:
            p = model.segments[i].parent
            if p >= 0 and p not in seen:
                raise ConfigError(f"tracking config: factored_ipf.order: '{model.segments[i].name}' comes before its parent")
            seen.add(i)
        return idx

    def anchored_children(self, model: BodyModel) -> dict[int, int]:
        """``factored_ipf.root_anchored`` as {segment index of a child of the root: index of its one
        child, whose joint stays put when the root moves alone}."""
        key = "tracking config: factored_ipf.root_anchored"
        names = self.factored_ipf.root_anchored
        if names and self.factored_ipf.root_refine != "alone":
            raise ConfigError(f"{key}: needs root_refine 'alone' (the root moves rigidly with 'rigid')")
        out = {}
        for name in names:
            if name not in {s.name for s in model.segments}:
                raise ConfigError(f"{key}: unknown segment '{name}'")
            seg = model.segment(name)
            below = model.children(seg.index)
            if seg.parent < 0 or model.segments[seg.parent].parent >= 0 or len(below) != 1:
                raise ConfigError(f"{key}: '{name}' must be a child of the root with exactly one child segment")
            child = model.segments[below[0]]
            if any(child.translation) or child.n_dofs not in (1, 3) or len(set(child.axes)) != child.n_dofs:
                raise ConfigError(f"{key}: '{name}': the joint below it ('{child.name}') needs one or three "
                                  f"rotation DOF about distinct axes")  # fmt: skip
            out[seg.index] = child.index
        return out

    def explored_dofs(self, model: BodyModel, trees: list[Subtree]) -> list[np.ndarray]:
        """DOF indices each node of the factored chain explores: its segment's own, then the
        ``coupled`` DOF of segments below it (which its subtree score sees)."""
        out = [np.arange(seg.dof_start, seg.dof_stop) for seg in model.segments]
        for name, dofs in self.factored_ipf.coupled.items():
            try:
                seg = model.segment(name)
            except ConfigError:
                raise ConfigError(f"tracking config: factored_ipf.coupled: unknown segment '{name}'") from None
            for dof in dofs:
                if dof not in model.dof_names:
                    raise ConfigError(f"tracking config: factored_ipf.coupled.{name}: unknown DOF '{dof}'")
                i = model.dof_index(dof)
                owner = next(s.index for s in model.segments if s.dof_start <= i < s.dof_stop)
                if owner == seg.index or owner not in trees[seg.index].segments:
                    raise ConfigError(f"tracking config: factored_ipf.coupled.{name}: '{dof}' is not a DOF of a "
                                      f"segment below {name}")  # fmt: skip
                out[seg.index] = np.r_[out[seg.index], i]
        return out


def _per_dof(key: str, patterns: dict[str, float], model: BodyModel, required: bool) -> np.ndarray:
    """Value per DOF (D,) from {regular expression: degrees or metres}; a DOF may match at most one
    pattern (exactly one when ``required``); unmatched DOF get inf."""
    out = np.full(model.n_dofs, np.inf)
    for i, name in enumerate(model.dof_names):
        hits = [p for p in patterns if re.fullmatch(p, name)]
        if len(hits) > 1 or (required and not hits):
            what = "no pattern" if not hits else f"several patterns ({', '.join(hits)})"
            raise ConfigError(f"tracking config: {key}: DOF '{name}' matches {what}")
        if hits:
            w = patterns[hits[0]]
            out[i] = w if not model.is_rotation[i] else np.radians(w)
    return out


def load_tracking_config(path: str | Path | None = None, model: BodyModel | None = None) -> TrackingConfig:
    """Load and validate ``tracking.yaml`` (the shipped one by default); with ``model``, also check
    it against the body model's DOF and segments, the file named in any error."""
    cfg = load_config_file(TrackingConfig, path, "tracking.yaml")
    path = path or default_config_path("tracking.yaml")
    if model is not None:
        try:
            cfg.check(model)
        except ConfigError as e:
            raise ConfigError(f"{path}: {e}") from None
    return cfg
