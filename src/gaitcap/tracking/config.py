"""Schema of ``configs/tracking.yaml`` (defaults live there and here, nowhere else)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, field_validator

from gaitcap.body.model import BodyModel
from gaitcap.config import Strict, default_config_path, load_yaml_model
from gaitcap.errors import ConfigError

TrackerName = Literal["condensation", "ipf", "factored-ipf"]


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
    swap_hypothesis: bool = True
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


class InitConfig(Strict):
    heading_step_deg: float = Field(default=15, gt=0, le=90)
    frames: int = Field(default=8, ge=1, le=100)
    refine_passes: int = Field(default=4, ge=0, le=50)
    widen: float = Field(default=2.5, ge=1, le=10)


class SmoothingConfig(Strict):
    cutoff_hz: float | None = Field(default=6.0, gt=0)
    order: int = Field(default=4, ge=1, le=8)


class TrackingConfig(Strict):
    tracker: TrackerName = "factored-ipf"
    scale: float = Field(default=0.5, gt=0.05, le=1)
    beta: float = Field(default=40.0, gt=0)
    intervals: dict[str, float]
    factored_ipf: FactoredIPFConfig
    ipf: IPFConfig
    condensation: CondensationConfig
    quality: QualityConfig = Field(default_factory=QualityConfig)
    init: InitConfig = Field(default_factory=InitConfig)
    smoothing: SmoothingConfig = Field(default_factory=SmoothingConfig)
    seed: int = 0

    @field_validator("intervals")
    @classmethod
    def _check_intervals(cls, v: dict[str, float]) -> dict[str, float]:
        for pattern, width in v.items():
            try:
                re.compile(pattern)
            except re.error as e:
                raise ValueError(f"'{pattern}' is not a valid regular expression ({e})") from e
            if not (np.isfinite(width) and width > 0):
                raise ValueError(f"'{pattern}': half-width must be positive")
        return v

    def half_widths(self, model: BodyModel) -> np.ndarray:
        """Interval half-width per DOF (D,), radians / metres. Each DOF must match one pattern."""
        out = np.zeros(model.n_dofs)
        for i, name in enumerate(model.dof_names):
            hits = [p for p in self.intervals if re.fullmatch(p, name)]
            if len(hits) != 1:
                what = "no pattern" if not hits else f"several patterns ({', '.join(hits)})"
                raise ConfigError(f"tracking config: intervals: DOF '{name}' matches {what}")
            w = self.intervals[hits[0]]
            out[i] = w if not model.is_rotation[i] else np.radians(w)
        return out

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


def load_tracking_config(path: str | Path | None = None) -> TrackingConfig:
    return load_yaml_model(TrackingConfig, path or default_config_path("tracking.yaml"))
