"""Schema of ``silhouette.yaml``: every parameter of silhouette extraction and its default.

The shipped file ``gaitcap/configs/silhouette.yaml`` documents each key; the defaults live here
only. Grey levels are on the 0-255 scale of 8-bit video.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from gaitcap.config import Strict, load_config_file


class BackgroundConfig(Strict):
    """How the empty scene is obtained and kept up to date."""

    source: Literal["auto", "plate", "video"] = Field(
        default="auto", description="auto: the session's plate when there is one, else estimated from the video"
    )
    samples: int = Field(default=31, ge=5, le=201, description="frames sampled across the video for the median")
    adapt_rate: float = Field(
        default=0.03, ge=0.0, le=1.0, description="running-average rate at background pixels (per frame)"
    )
    gain_compensation: bool = Field(
        default=True, description="rescale the background by the frame's global brightness ratio each frame"
    )
    min_noise: float = Field(default=2.0, gt=0, description="floor of the per-pixel noise estimate, grey levels")
    max_noise_factor: float = Field(default=3.0, ge=1, description="cap of a pixel's noise, times the image's median noise")
    # "no usable background" detection, for backgrounds estimated from the video
    hidden_diff: float = Field(
        default=25.0, gt=0, description="grey-level difference from the median that counts as 'background hidden'"
    )
    hidden_occupancy: float = Field(
        default=0.3, gt=0, lt=1, description="a pixel is ambiguous when hidden in at least this fraction of samples"
    )
    max_ambiguous_fraction: float = Field(
        default=0.02, gt=0, lt=1, description="above this fraction of ambiguous pixels the estimate is unusable"
    )
    max_plate_mismatch: float = Field(
        default=0.2, gt=0, le=1,
        description="a plate is unusable when the samples' median differs from it by hidden_diff in more of the image",
    )


class ForegroundConfig(Strict):
    """Per-pixel foreground test against the background model."""

    threshold_sigma: float = Field(default=4.0, gt=0, description="foreground when |frame - bg| > k * noise sigma")
    min_diff: float = Field(default=18.0, ge=0, description="and when |frame - bg| exceeds this many grey levels")
    hysteresis: float = Field(
        default=0.5, gt=0, le=1,
        description="weak foreground above this fraction of the threshold, kept where connected to confident pixels (1: off)",
    )  # fmt: skip
    texture_ncc: float = Field(
        default=0.4, ge=-1, le=1,
        description="weak foreground where the background is textured and the frame's local correlation with it is "
        "below this (-1: off); texture window and least std from the shadow keys",
    )  # fmt: skip
    chroma_weight: float = Field(
        default=2.0, ge=1, le=10,
        description="weight of the colour part of the difference (orthogonal to the background's colour) against "
        "its brightness part (1: plain RMS over channels)",
    )  # fmt: skip
    chroma_edge: int = Field(
        default=1, ge=0, le=5,
        description="outermost rings of the foreground kept only where the plain RMS difference passes the weak "
        "level (video's half-resolution colour bleeds past the outline; 0: off)",
    )  # fmt: skip
    soft_min: float = Field(
        default=0.75, ge=0, le=1,
        description="soft silhouette (tracking.soft_silhouettes): value of the least confident pixel inside the mask",
    )  # fmt: skip
    doubt_min: float = Field(
        default=1.0, ge=0, le=1,
        description="soft silhouette: outside the mask, a pixel no shadow whose difference passes this fraction of the "
        "threshold is doubtful, 0 here up to 0.5 at the weak level (hysteresis); at or above hysteresis: off",
    )  # fmt: skip

    @property
    def doubts(self) -> bool:
        """Whether the soft silhouette holds doubtful pixels outside the mask (``doubt_min`` below the weak level)."""
        return self.doubt_min < self.hysteresis


class ShadowConfig(Strict):
    """Cast-shadow suppression: darker than the background, same chromaticity, same texture."""

    enabled: bool = True
    min_ratio: float = Field(default=0.45, gt=0, lt=1, description="shadow brightness / background brightness, lowest")
    max_ratio: float = Field(default=0.97, gt=0, le=1, description="shadow brightness / background brightness, highest")
    max_chroma: float = Field(
        default=0.06, gt=0, description="largest change of normalised rgb chromaticity inside a shadow"
    )
    min_ncc: float = Field(
        default=0.35, ge=-1, le=1,
        description="on textured background, least local correlation frame/background inside a shadow",
    )
    texture_min_std: float = Field(
        default=4.0, ge=0, description="background local std (grey levels) above which the texture test applies"
    )
    texture_window: int = Field(default=5, ge=3, le=31, description="window (pixels) of the texture test")
    floor_check: bool = Field(
        default=True,
        description="with calibrated cameras, a shadow must lie on the floor and be darkened in the other cameras too",
    )
    floor_min_ratio: float = Field(
        default=0.25, gt=0, lt=1,
        description="with the floor check, darker candidates down to this brightness ratio are shadows where "
        "another camera sees their floor point darkened (to one camera they look like dark clothes)",
    )  # fmt: skip
    floor_same_ratio: bool = Field(
        default=True,
        description="with the floor check, another camera confirms a shadow only where it sees the floor point "
        "darkened by the same brightness ratio (or hidden behind the person): a shoe on the floor is no shadow",
    )
    floor_ratio_tolerance: float = Field(
        default=0.15, gt=0, le=2.0,
        description="largest difference of log brightness ratio (frame / background) between the two cameras",
    )
    floor_ratio_window: int = Field(
        default=1, ge=0, le=15,
        description="with floor_same_ratio, the other camera's log ratio is looked up within this many pixels "
        "(working scale) of the floor point: a shadow's ratio beside a shoe's outline no longer confirms the shoe",
    )
    floor_footprint: bool = Field(
        default=False,
        description="with the floor check, a candidate that no other camera sees stays a shadow only where the "
        "confirmed shadows have fallen around the person (a lamp casts them the same way all through a walk)",
    )
    floor_tolerance: int = Field(
        default=2, ge=0, le=15, description="slack (pixels at working scale) when looking up a floor point in another camera"
    )
    floor_reach: float = Field(
        default=1.0, gt=0, le=20,
        description="with several cameras, a shadow lies within this many metres of the floor two cameras see",
    )

    @model_validator(mode="after")
    def _ratios_ordered(self) -> ShadowConfig:
        if self.min_ratio >= self.max_ratio:
            raise ValueError(f"min_ratio ({self.min_ratio}) must be below max_ratio ({self.max_ratio})")
        if self.floor_min_ratio > self.min_ratio:
            raise ValueError(f"floor_min_ratio ({self.floor_min_ratio}) must not be above min_ratio ({self.min_ratio})")
        return self


class CleanupConfig(Strict):
    """Morphology and component selection on the raw foreground."""

    open_radius: int = Field(default=1, ge=0, le=15, description="opening radius (pixels at working scale)")
    close_radius: int = Field(default=3, ge=0, le=31, description="closing radius (pixels at working scale)")
    max_hole_fraction: float = Field(
        default=0.02, ge=0, le=1, description="fill holes up to this fraction of their component's area"
    )
    min_component_fraction: float = Field(
        default=0.0005, ge=0, lt=1,
        description="drop components smaller than this fraction of the image, unless the body lies just over or "
        "under them (a foot cut off at the ankle, a head at the neck)",
    )
    keep_relative: float = Field(
        default=0.15, ge=0, le=1, description="components at least this fraction of the largest one are main parts"
    )
    keep_margin: float = Field(
        default=0.15, ge=0, le=2,
        description="smaller components are kept within this fraction of the main parts' box height from the box",
    )
    keep_below: float = Field(
        default=1.0, ge=0, le=3,
        description="and below the box within this fraction of its height (a foot whose leg the foreground lost; "
                    "calibrated cameras: not past the floor beneath the person)",
    )
    keep_radius_m: float = Field(
        default=0.6, ge=0, le=3,
        description="calibrated cameras: a main part lying on the floor with less than a tenth of its pixels within "
                    "this distance (metres) of the person's vertical axis (the previous frame's head top) is dropped; "
                    "0: off",
    )
    matte_outline: bool = Field(
        default=True,
        description="re-decide the outline's pixels (1 outside, 1 inside) by the fraction of the pixel the person "
                    "covers, estimated against the background and the person's nearby colour (kept at 1/2 or more)",
    )


class QualityConfig(Strict):
    """Per-frame flags."""

    empty_fraction: float = Field(default=0.001, ge=0, lt=1, description="flag 'empty' below this foreground fraction")
    large_fraction: float = Field(
        default=0.35, gt=0, le=1, description="flag 'too_large' above this foreground fraction (lighting jump?)"
    )
    border_margin: int = Field(default=1, ge=1, description="flag 'border' when the mask reaches this close to the edge")


class SilhouetteConfig(Strict):
    """Schema of ``silhouette.yaml``."""

    scale: float = Field(
        default=1.0, gt=0.05, le=1.0, description="working resolution / video resolution (masks are returned at full size)"
    )
    background: BackgroundConfig = Field(default_factory=BackgroundConfig)
    foreground: ForegroundConfig = Field(default_factory=ForegroundConfig)
    shadow: ShadowConfig = Field(default_factory=ShadowConfig)
    cleanup: CleanupConfig = Field(default_factory=CleanupConfig)
    quality: QualityConfig = Field(default_factory=QualityConfig)

    @classmethod
    def load(cls, path: str | Path | None = None) -> SilhouetteConfig:
        """Read ``path`` (None: the shipped ``silhouette.yaml``)."""
        return load_config_file(cls, path, "silhouette.yaml")
