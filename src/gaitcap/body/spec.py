"""Schema of ``configs/body.yaml`` (see that file for frames, units and sources)."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, field_validator, model_validator

from gaitcap.config import Strict
from gaitcap.trajectory import POINT_NAMES

Vec3 = tuple[float, float, float]
Axis = Literal["x", "y", "z", "-x", "-y", "-z"]


def _finite(values: tuple[float, ...], what: str) -> None:
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"{what} must be finite numbers")


class DofSpec(Strict):
    """One degree of freedom: a rotation (degrees) or a translation (metres) about/along an axis."""

    name: str
    kind: Literal["rotation", "translation"] = "rotation"
    axis: Axis
    limits: tuple[float, float] | None = Field(default=None, description="[min, max]; null = unbounded")
    wrap: bool = Field(default=False, description="angle wraps around (heading)")

    @field_validator("limits")
    @classmethod
    def _check_limits(cls, v: tuple[float, float] | None) -> tuple[float, float] | None:
        if v is None:
            return v
        _finite(v, "limits")
        if v[0] > v[1]:
            raise ValueError(f"limits min {v[0]} is greater than max {v[1]}")
        return v

    @model_validator(mode="after")
    def _check_kind(self) -> DofSpec:
        if self.kind == "rotation" and self.limits is not None and not -180 <= self.limits[0] <= self.limits[1] <= 180:
            raise ValueError(f"{self.name}: limits {list(self.limits)} must lie within [-180, 180] degrees (a rotation "
                             f"beyond a half turn is the same pose as one the other way)")  # fmt: skip
        if self.kind == "translation" and self.wrap:
            raise ValueError(f"{self.name}: wrap is for an angle that wraps round (the heading), not a translation")
        return self


class ShapeSpec(Strict):
    """A tapered capsule from ``a`` to ``b`` (segment frame, fractions of height)."""

    a: Vec3
    b: Vec3
    radius: float | tuple[float, float]

    @field_validator("a", "b")
    @classmethod
    def _check_vec(cls, v: Vec3) -> Vec3:
        _finite(v, "shape end points")
        return v

    @field_validator("radius")
    @classmethod
    def _check_radius(cls, v: float | tuple[float, float]) -> float | tuple[float, float]:
        values = (v,) if isinstance(v, (int, float)) else tuple(v)
        _finite(values, "radius")
        if any(r <= 0 for r in values):
            raise ValueError("radius must be positive")
        return v

    @property
    def radii(self) -> tuple[float, float]:
        return (self.radius, self.radius) if isinstance(self.radius, (int, float)) else tuple(self.radius)  # type: ignore[return-value]


class SegmentSpec(Strict):
    parent: str | None
    joint: str = Field(description="name of the point at this segment's origin")
    origin: Vec3 = (0.0, 0.0, 0.0)
    dofs: list[DofSpec] = Field(default_factory=list)
    points: dict[str, Vec3] = Field(default_factory=dict)
    shapes: list[ShapeSpec] = Field(default_factory=list)

    @field_validator("origin")
    @classmethod
    def _check_origin(cls, v: Vec3) -> Vec3:
        _finite(v, "origin")
        return v


class BodySpec(Strict):
    """The whole body model file."""

    height_m: float = Field(default=1.75, gt=0.5, lt=2.6)
    segments: dict[str, SegmentSpec]

    @model_validator(mode="after")
    def _check_tree(self) -> BodySpec:
        seen: set[str] = set()
        roots = [n for n, s in self.segments.items() if s.parent is None]
        if len(roots) != 1:
            raise ValueError(f"exactly one segment must have parent: null, found {len(roots)}")
        for name, seg in self.segments.items():
            if seg.parent is not None and seg.parent not in seen:
                raise ValueError(
                    f"segments.{name}.parent: '{seg.parent}' must be a segment listed before '{name}'"
                )
            seen.add(name)
        names = [s.joint for s in self.segments.values()] + [p for s in self.segments.values() for p in s.points]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"point names used twice: {', '.join(dup)}")
        unknown = sorted(set(names) - set(POINT_NAMES))
        if unknown:
            raise ValueError(f"unknown point names {', '.join(unknown)} (valid: {', '.join(POINT_NAMES)})")
        dofs = [d.name for s in self.segments.values() for d in s.dofs]
        dup = sorted({n for n in dofs if dofs.count(n) > 1})
        if dup:
            raise ValueError(f"DOF names used twice: {', '.join(dup)}")
        root = self.segments[roots[0]]
        if any(d.kind == "translation" for s in self.segments.values() if s is not root for d in s.dofs):
            raise ValueError("only the root segment may have translation DOF")
        return self
