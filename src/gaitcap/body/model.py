"""The articulated body model and its forward kinematics, vectorised over particles.

A pose is a vector q of D = 31 numbers (radians for rotations, metres for the root translation),
ordered as the DOF appear in ``configs/body.yaml``. For a segment s with parent p:

    R_s = R_p · R_1(q_1) · R_2(q_2) ...      (intrinsic rotations about the segment's signed axes)
    o_s = o_p + R_p · origin_s               (origin_s: the joint's offset in the parent frame)

and a point with local coordinates l in segment s sits at ``o_s + R_s · l``. The root's origin
is its translation DOF and its rotation the root's own DOF.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gaitcap.body.spec import BodySpec
from gaitcap.config import default_config_path, load_yaml_model
from gaitcap.errors import ConfigError

_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class Segment:
    """One rigid segment, as the kinematics sees it."""

    name: str
    index: int
    parent: int  # -1 for the root
    joint: str
    origin: np.ndarray  # (3,) metres, in the parent frame
    dof_start: int
    dof_stop: int
    axes: tuple[int, ...]  # axis index per DOF (0, 1, 2)
    signs: tuple[float, ...]  # +1 / -1 per DOF
    translation: tuple[bool, ...]  # per DOF

    @property
    def dofs(self) -> slice:
        return slice(self.dof_start, self.dof_stop)

    @property
    def n_dofs(self) -> int:
        return self.dof_stop - self.dof_start


#: the two other axes of each principal axis, in cyclic order (x -> y, z; y -> z, x; z -> x, y)
_OTHER_AXES = ((1, 2), (2, 0), (0, 1))


def axis_rotation(axis: int, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices about a principal axis: angles (N,) -> (N, 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    n = angle.shape[0]
    R = np.zeros((n, 3, 3))
    i, j = _OTHER_AXES[axis]
    R[:, axis, axis] = 1.0
    R[:, i, i] = c
    R[:, j, j] = c
    R[:, i, j] = -s
    R[:, j, i] = s
    return R


class BodyModel:
    """The body model scaled to a subject.

    Args:
        spec: the validated ``body.yaml``.
        height_m: subject height (defaults to the spec's ``height_m``).
        scales: optional per-segment anisotropic scale factors ``{segment: (sx, sy, sz)}`` applied
            to everything expressed in that segment's frame (its children's joint offsets, its
            landmarks and its shape end points), to fit a particular subject's proportions.
    """

    def __init__(
        self,
        spec: BodySpec,
        height_m: float | None = None,
        scales: Mapping[str, Sequence[float]] | None = None,
        shifts: Mapping[str, Sequence[float]] | None = None,
    ) -> None:
        self.spec = spec
        self.height_m = float(height_m if height_m is not None else spec.height_m)
        if not (0.5 < self.height_m < 2.6):
            raise ConfigError(f"subject height {self.height_m} m: must be above 0.5 m and below 2.6 m")
        self.scales = _per_segment(spec, "scales", scales, 1.0, positive=True)
        self.shifts = _per_segment(spec, "shifts", shifts, 0.0, positive=False)
        self._build()

    # ------------------------------------------------------------------ build
    def _build(self) -> None:
        H = self.height_m
        names = list(self.spec.segments)
        index = {n: i for i, n in enumerate(names)}
        segments: list[Segment] = []
        dof_names: list[str] = []
        lower: list[float] = []
        upper: list[float] = []
        wrap: list[bool] = []
        is_rot: list[bool] = []
        for i, (name, seg) in enumerate(self.spec.segments.items()):
            parent = -1 if seg.parent is None else index[seg.parent]
            parent_scale = self.scales[seg.parent] if seg.parent is not None else np.ones(3)
            parent_shift = self.shifts[seg.parent] if seg.parent is not None else np.zeros(3)
            start = len(dof_names)
            axes, signs, trans = [], [], []
            for d in seg.dofs:
                axes.append(_AXIS_INDEX[d.axis[-1]])
                signs.append(-1.0 if d.axis.startswith("-") else 1.0)
                trans.append(d.kind == "translation")
                dof_names.append(d.name)
                conv = 1.0 if d.kind == "translation" else np.pi / 180.0
                lo, hi = d.limits if d.limits is not None else (-np.inf, np.inf)
                lower.append(lo * conv)
                upper.append(hi * conv)
                wrap.append(d.wrap)
                is_rot.append(d.kind == "rotation")
            segments.append(
                Segment(
                    name=name,
                    index=i,
                    parent=parent,
                    joint=seg.joint,
                    origin=np.asarray(seg.origin) * H * parent_scale + parent_shift,
                    dof_start=start,
                    dof_stop=len(dof_names),
                    axes=tuple(axes),
                    signs=tuple(signs),
                    translation=tuple(trans),
                )
            )
        self.segments: tuple[Segment, ...] = tuple(segments)
        self.dof_names: tuple[str, ...] = tuple(dof_names)
        self.lower = np.asarray(lower)
        self.upper = np.asarray(upper)
        self.wrap = np.asarray(wrap)
        self._clip_limits: dict[tuple[str, bytes] | None, tuple] = {}  # clip's masks and limits per selection
        self.is_rotation = np.asarray(is_rot)

        # points: joints (at a segment origin) and landmarks
        point_names: list[str] = []
        point_seg: list[int] = []
        point_local: list[np.ndarray] = []
        for seg in self.segments:
            point_names.append(seg.joint)
            point_seg.append(seg.index)
            point_local.append(np.zeros(3))
            for pname, local in self.spec.segments[seg.name].points.items():
                point_names.append(pname)
                point_seg.append(seg.index)
                point_local.append(np.asarray(local) * H * self.scales[seg.name] + self.shifts[seg.name])
        from gaitcap.trajectory import POINT_NAMES

        order = [point_names.index(n) for n in POINT_NAMES if n in point_names]
        self.point_names: tuple[str, ...] = tuple(point_names[k] for k in order)
        self.point_segment = np.asarray([point_seg[k] for k in order])
        self.point_local = np.asarray([point_local[k] for k in order]).reshape(-1, 3)

        # capsules
        cap_seg, cap_a, cap_b, cap_r = [], [], [], []
        for seg in self.segments:
            sc, sh = self.scales[seg.name], self.shifts[seg.name]
            for shape in self.spec.segments[seg.name].shapes:
                a, b = np.asarray(shape.a), np.asarray(shape.b)
                cap_seg.append(seg.index)
                cap_a.append(a * H * sc + sh)
                cap_b.append(b * H * sc + sh)
                cap_r.append(np.asarray(shape.radii) * H * _across_scale(b - a, sc))
        self.capsule_segment = np.asarray(cap_seg, dtype=int)
        self.capsule_a = np.asarray(cap_a).reshape(-1, 3)
        self.capsule_b = np.asarray(cap_b).reshape(-1, 3)
        self.capsule_radii = np.asarray(cap_r).reshape(-1, 2)

    # --------------------------------------------------------------- queries
    @property
    def n_dofs(self) -> int:
        return len(self.dof_names)

    @property
    def n_points(self) -> int:
        return len(self.point_names)

    def dof_index(self, name: str) -> int:
        try:
            return self.dof_names.index(name)
        except ValueError:
            raise ConfigError(f"unknown DOF {name!r}") from None

    def segment(self, name: str) -> Segment:
        for s in self.segments:
            if s.name == name:
                return s
        raise ConfigError(f"unknown segment {name!r}")

    def point_index(self, name: str) -> int:
        try:
            return self.point_names.index(name)
        except ValueError:
            raise ConfigError(f"unknown point {name!r}") from None

    def children(self, index: int) -> list[int]:
        return [s.index for s in self.segments if s.parent == index]

    def with_proportions(
        self, scales: Mapping[str, Sequence[float]] | None = None, shifts: Mapping[str, Sequence[float]] | None = None
    ) -> BodyModel:
        """The same model with other per-segment scales and shifts (see the constructor)."""
        return BodyModel(self.spec, self.height_m, scales, shifts)

    def with_height(self, height_m: float) -> BodyModel:
        return BodyModel(self.spec, height_m, self.proportions()[0], self.proportions()[1])

    def proportions(self) -> tuple[dict[str, tuple[float, ...]], dict[str, tuple[float, ...]]]:
        """(scales, shifts) as plain dictionaries, for saving."""
        return ({k: tuple(map(float, v)) for k, v in self.scales.items()},
                {k: tuple(map(float, v)) for k, v in self.shifts.items()})

    # ---------------------------------------------------------------- limits
    def clip(self, q: np.ndarray, dofs: np.ndarray | None = None) -> np.ndarray:
        """Wrap heading DOF to [-pi, pi) and clip every other DOF to its limits. (N, D) -> (N, D);
        with ``dofs`` (M,), q (N, M) holds only those DOF (each DOF is clipped on its own, so this
        equals the same columns of a clipped full pose)."""
        q = np.array(q, dtype=np.float64, copy=True)
        wrap, nw, lower, upper = self._limits_of(dofs)
        if wrap is not None:
            q[..., wrap] = (q[..., wrap] + np.pi) % (2 * np.pi) - np.pi
        q[..., nw] = np.clip(q[..., nw], lower, upper)
        return q

    def _limits_of(self, dofs: np.ndarray | None) -> tuple[np.ndarray | None, np.ndarray, np.ndarray, np.ndarray]:
        """For :meth:`clip` of the DOF ``dofs`` (None: all): the wrapping columns' mask (None: none),
        the other columns' mask and their lower and upper limits, built once per selection (the
        trackers clip the same few selections thousands of times a frame)."""
        key = None if dofs is None else (np.asarray(dofs).dtype.str, np.asarray(dofs).tobytes())
        if key not in self._clip_limits:
            wrap = self.wrap if dofs is None else self.wrap[dofs]
            lower, upper = (self.lower, self.upper) if dofs is None else (self.lower[dofs], self.upper[dofs])
            self._clip_limits[key] = (wrap if wrap.any() else None, ~wrap, lower[~wrap], upper[~wrap])
        return self._clip_limits[key]

    def within_limits(self, q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Boolean (N,) mask: every non-wrapping DOF within its limits."""
        q = np.atleast_2d(q)
        nw = ~self.wrap
        return np.all((q[:, nw] >= self.lower[nw] - tol) & (q[:, nw] <= self.upper[nw] + tol), axis=1)

    def neutral_pose(self, heading_rad: float = 0.0, x: float = 0.0, y: float = 0.0) -> np.ndarray:
        """Standing pose (D,): every angle 0, the soles on the floor, facing ``heading_rad``."""
        q = np.zeros(self.n_dofs)
        q[self.dof_index("pelvis_rotation")] = heading_rad
        pts = self.forward(q[None])[0]
        q[self.dof_index("pelvis_tx")] = x
        q[self.dof_index("pelvis_ty")] = y
        q[self.dof_index("pelvis_tz")] = -pts[:, 2].min()
        return q

    # ------------------------------------------------------------ kinematics
    def local_rotation(self, seg: Segment, q_seg: np.ndarray) -> np.ndarray:
        """Rotation of a segment relative to its parent: q_seg (N, k) -> (N, 3, 3)."""
        R: np.ndarray | None = None
        for k, (axis, sign, trans) in enumerate(zip(seg.axes, seg.signs, seg.translation)):
            if not trans:
                Rk = axis_rotation(axis, sign * q_seg[:, k])
                R = Rk if R is None else R @ Rk
        if R is None:
            return np.broadcast_to(np.eye(3), (q_seg.shape[0], 3, 3)).copy()
        return R

    def local_angles(self, seg: Segment, R: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`local_rotation` for a segment with three rotation DOF about
        distinct axes: rotations R (N, 3, 3) -> angles (N, 3) radians, the middle one within
        +-90 degrees (joint limits are not applied).

        Raises:
            ValueError: the segment does not have exactly three rotations about distinct axes.
        """
        if any(seg.translation) or len(seg.axes) != 3 or len(set(seg.axes)) != 3:
            raise ValueError(f"segment {seg.name}: local_angles needs three rotations about distinct axes")
        from scipy.spatial.transform import Rotation  # here, not at start-up (gaitcap.pipeline._import_late)

        seq = "".join("XYZ"[a] for a in seg.axes)  # upper case: intrinsic, R = R1 R2 R3
        return Rotation.from_matrix(R).as_euler(seq) / np.asarray(seg.signs)

    def nearest_angle(self, seg: Segment, R: np.ndarray) -> np.ndarray:
        """For a segment with one rotation DOF: the angle (N,) radians whose local rotation is
        nearest to each R (N, 3, 3), the one maximising trace(Rot^T R) (R itself when R is such a
        rotation; joint limits are not applied).

        Raises:
            ValueError: the segment does not have exactly one rotation DOF.
        """
        if any(seg.translation) or len(seg.axes) != 1:
            raise ValueError(f"segment {seg.name}: nearest_angle needs exactly one rotation DOF")
        i, j = _OTHER_AXES[seg.axes[0]]
        return np.arctan2(R[:, j, i] - R[:, i, j], R[:, i, i] + R[:, j, j]) / seg.signs[0]

    def segment_frame(
        self, seg: Segment, q_seg: np.ndarray, parent_R: np.ndarray | None, parent_o: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """World frame of one segment given its parent's: returns R (N, 3, 3) and origin (N, 3)."""
        R_local = self.local_rotation(seg, q_seg)
        if seg.parent < 0:
            o = np.zeros((q_seg.shape[0], 3))
            for k, (axis, sign, trans) in enumerate(zip(seg.axes, seg.signs, seg.translation)):
                if trans:
                    o[:, axis] += sign * q_seg[:, k]
            return R_local, o
        assert parent_R is not None and parent_o is not None
        return parent_R @ R_local, parent_o + parent_R @ seg.origin

    def frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every segment's world frame: q (N, D) -> R (N, S, 3, 3), origins (N, S, 3)."""
        q = self._check_poses(q)
        n, S = q.shape[0], len(self.segments)
        R = np.empty((n, S, 3, 3))
        o = np.empty((n, S, 3))
        for seg in self.segments:
            pR = R[:, seg.parent] if seg.parent >= 0 else None
            po = o[:, seg.parent] if seg.parent >= 0 else None
            R[:, seg.index], o[:, seg.index] = self.segment_frame(seg, q[:, seg.dofs], pR, po)
        return R, o

    def forward(self, q: np.ndarray) -> np.ndarray:
        """Forward kinematics: poses (N, D) -> points (N, P, 3) in :attr:`point_names` order."""
        R, o = self.frames(q)
        Rp = R[:, self.point_segment]  # (N, P, 3, 3)
        return o[:, self.point_segment] + np.einsum("npij,pj->npi", Rp, self.point_local)

    def capsules(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World capsules: poses (N, D) -> ends A (N, C, 3), B (N, C, 3) and radii (C, 2) metres."""
        R, o = self.frames(q)
        return self.capsules_from_frames(R, o)

    def capsules_from_frames(self, R: np.ndarray, o: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        Rc = R[:, self.capsule_segment]
        oc = o[:, self.capsule_segment]
        A = oc + np.einsum("ncij,cj->nci", Rc, self.capsule_a)
        B = oc + np.einsum("ncij,cj->nci", Rc, self.capsule_b)
        return A, B, self.capsule_radii

    def _check_poses(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=np.float64)
        if q.ndim != 2 or q.shape[1] != self.n_dofs:
            raise ValueError(f"poses must have shape (N, {self.n_dofs}), got {q.shape}")
        return q


def _per_segment(
    spec: BodySpec, what: str, values: Mapping[str, Sequence[float]] | None, default: float, positive: bool
) -> dict[str, np.ndarray]:
    """Validated per-segment 3-vectors (scales or shifts), ``default`` for segments not given."""
    values = dict(values or {})
    unknown = set(values) - set(spec.segments)
    if unknown:
        raise ConfigError(f"{what}: unknown segments {', '.join(sorted(unknown))}")
    out = {n: np.asarray(values.get(n, (default,) * 3), dtype=np.float64) for n in spec.segments}
    for n, v in out.items():
        if v.shape != (3,) or not np.all(np.isfinite(v)) or (positive and np.any(v <= 0)):
            raise ConfigError(f"{what}.{n}: must be three {'positive' if positive else 'finite'} numbers")
    return out


def _across_scale(axis: np.ndarray, scale: np.ndarray) -> float:
    """Scale of a capsule's thickness: the segment's scale factors weighted across the capsule axis."""
    n = np.linalg.norm(axis)
    u = axis / n if n > 0 else np.zeros(3)
    w = 1.0 - u * u
    return float(np.sum(w * scale) / np.sum(w))


def load_body_spec(path: str | Path | None = None) -> BodySpec:
    """Load and validate a body model file (the shipped ``configs/body.yaml`` by default)."""
    return load_yaml_model(BodySpec, path or default_config_path("body.yaml"))


def load_body_model(
    path: str | Path | None = None,
    height_m: float | None = None,
    scales: Mapping[str, Sequence[float]] | None = None,
    shifts: Mapping[str, Sequence[float]] | None = None,
) -> BodyModel:
    """Load ``body.yaml`` and scale it to a subject."""
    return BodyModel(load_body_spec(path), height_m=height_m, scales=scales, shifts=shifts)
