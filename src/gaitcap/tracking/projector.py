"""Poses to projected capsules, compiled: the forward kinematics of :mod:`gaitcap.body.model` and
the pinhole projection of :class:`gaitcap.tracking.observation.TrackingView`, fused in one numba
kernel so that a layer of particles costs one call instead of a few hundred small numpy
operations.

The kinematics are the body model's, read from its tables (nothing is redeclared here):

    R_s = R_p · R_1(±q_1) · R_2(±q_2) ...,   o_s = o_p + R_p · origin_s     (the root: o = its translations)

and a capsule end l of segment s projects in camera c (R_c, t_c, pinhole fx, fy, cx, cy) as

    X = o_s + R_s l,   p = R_c X + t_c,   u = fx p_x / p_z + cx,   v = fy p_y / p_z + cy,   r_px = f r / p_z

with p_z clamped at 1 mm and f = (fx + fy) / 2, as in :meth:`TrackingView.project`. Tests check
both against the numpy path to 1e-9.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from gaitcap.jit import cached_njit

if TYPE_CHECKING:  # annotations only: this module needs numpy and numba alone (see gaitcap.tracking.precompile)
    from gaitcap.body.model import BodyModel
    from gaitcap.tracking.observation import TrackingView


@dataclass(frozen=True)
class Projected:
    """Capsules of N poses in C cameras: a, b (C, N, K, 2) pixels; ra, rb (C, N, K) pixels."""

    a: np.ndarray
    b: np.ndarray
    ra: np.ndarray
    rb: np.ndarray

    def camera(self, c: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.a[c], self.b[c], self.ra[c], self.rb[c]


@cached_njit(inline="always")
def _rotate(R: np.ndarray, n: int, s: int, axis: int, angle: float) -> None:
    """R[n, s] <- R[n, s] · R_axis(angle), in place (R: (N, S, 3, 3))."""
    c, sn = np.cos(angle), np.sin(angle)
    i, j = (1, 2) if axis == 0 else ((2, 0) if axis == 1 else (0, 1))
    for r in range(3):
        ri, rj = R[n, s, r, i], R[n, s, r, j]
        R[n, s, r, i] = ri * c + rj * sn
        R[n, s, r, j] = -ri * sn + rj * c


@cached_njit(inline="always")
def _frames(Q, n, need, parent, origin, dof_start, dof_stop, axis, sign, trans, R, o, same) -> None:
    """World frames of the segments ``need`` (S,) bool (closed under parents) for pose Q[n]:
    R[n] (S, 3, 3), o[n] (S, 3), in place. The other segments are left unset.

    A segment whose DOF and whose ancestors' DOF equal pose n - 1's takes that pose's frame, the
    same numbers the arithmetic would give (the particles of a node differ in its DOF only: their
    ancestors' frames are computed once). ``same`` (S,) bool scratch.

    Indexes the arrays element by element: taking row views (Q[n], R[s]) costs two atomic
    reference-count updates each, more than the arithmetic."""
    S = parent.shape[0]
    for s in range(S):
        if not need[s]:
            continue
        p = parent[s]
        same[s] = n > 0 and (p < 0 or same[p])
        for d in range(dof_start[s], dof_stop[s]):  # equal, and of the same sign where zero
            if same[s] and not (Q[n, d] == Q[n - 1, d] and math.copysign(1.0, Q[n, d]) == math.copysign(1.0, Q[n - 1, d])):
                same[s] = False
        if same[s]:
            for i in range(3):
                o[n, s, i] = o[n - 1, s, i]
                for j in range(3):
                    R[n, s, i, j] = R[n - 1, s, i, j]
            continue
        if p < 0:
            for i in range(3):
                o[n, s, i] = 0.0
                for j in range(3):
                    R[n, s, i, j] = 1.0 if i == j else 0.0
        else:
            for i in range(3):
                o[n, s, i] = (o[n, p, i] + R[n, p, i, 0] * origin[s, 0] + R[n, p, i, 1] * origin[s, 1]
                              + R[n, p, i, 2] * origin[s, 2])  # fmt: skip
                for j in range(3):
                    R[n, s, i, j] = R[n, p, i, j]
        for d in range(dof_start[s], dof_stop[s]):
            if trans[d]:
                o[n, s, axis[d]] += sign[d] * Q[n, d]
            else:
                _rotate(R, n, s, axis[d], sign[d] * Q[n, d])


@cached_njit(inline="always")
def _world(R: np.ndarray, o: np.ndarray, n: int, s: int, loc: np.ndarray, k: int, i: int) -> float:
    """Coordinate i of the point with coordinates loc[k] (3,) in segment s's frame of pose n."""
    return o[n, s, i] + R[n, s, i, 0] * loc[k, 0] + R[n, s, i, 1] * loc[k, 1] + R[n, s, i, 2] * loc[k, 2]


@cached_njit(inline="always")
def _project_pose(R, o, n, cap_seg, cap_a, cap_b, cap_r, cam_R, cam_t, cam_k, a, b, ra, rb) -> None:
    """The capsules of pose n, its frames R[n], o[n] computed, projected in every camera: into
    a, b (C, N, K, 2), ra, rb (C, N, K) at n."""
    for k in range(cap_seg.shape[0]):
        s = cap_seg[k]
        for end in range(2):
            loc = cap_a if end == 0 else cap_b
            X0, X1, X2 = _world(R, o, n, s, loc, k, 0), _world(R, o, n, s, loc, k, 1), _world(R, o, n, s, loc, k, 2)
            for c in range(cam_R.shape[0]):
                px = cam_R[c, 0, 0] * X0 + cam_R[c, 0, 1] * X1 + cam_R[c, 0, 2] * X2 + cam_t[c, 0]
                py = cam_R[c, 1, 0] * X0 + cam_R[c, 1, 1] * X1 + cam_R[c, 1, 2] * X2 + cam_t[c, 1]
                pz = max(cam_R[c, 2, 0] * X0 + cam_R[c, 2, 1] * X1 + cam_R[c, 2, 2] * X2 + cam_t[c, 2], 1e-3)
                fx, fy, cx, cy = cam_k[c, 0], cam_k[c, 1], cam_k[c, 2], cam_k[c, 3]
                u, v, rad = fx * px / pz + cx, fy * py / pz + cy, 0.5 * (fx + fy) * cap_r[k, end] / pz
                if end == 0:
                    a[c, n, k, 0], a[c, n, k, 1], ra[c, n, k] = u, v, rad
                else:
                    b[c, n, k, 0], b[c, n, k, 1], rb[c, n, k] = u, v, rad


@cached_njit(inline="always")
def _pose_points(R, o, n, pt_seg, pt_local, out) -> None:
    """The points of pose n, its frames R[n], o[n] computed: into out (N, P, 3) at n."""
    for p in range(pt_seg.shape[0]):
        for i in range(3):
            out[n, p, i] = _world(R, o, n, pt_seg[p], pt_local, p, i)


@cached_njit(nogil=True)
def _kinematics(Q, need, parent, origin, dof_start, dof_stop, axis, sign, trans, cap_seg, cap_a, cap_b, cap_r,
                cam_R, cam_t, cam_k, pt_seg, pt_local):  # fmt: skip
    """Poses Q (N, D) -> their capsules (K) projected in the cameras (C): a, b (C, N, K, 2), ra, rb
    (C, N, K); and their points (P): (N, P, 3); from one pass of the kinematics over the segments
    ``need`` (those of the capsules and the points, and their ancestors). One kernel for the
    capsules, the points or both (an empty selection costs nothing), so that one is loaded."""
    N, K, C, S = Q.shape[0], cap_seg.shape[0], cam_R.shape[0], parent.shape[0]
    a = np.empty((C, N, K, 2))
    b = np.empty((C, N, K, 2))
    ra = np.empty((C, N, K))
    rb = np.empty((C, N, K))
    out = np.empty((N, pt_seg.shape[0], 3))
    R = np.empty((N, S, 3, 3))
    o = np.empty((N, S, 3))
    same = np.zeros(S, np.bool_)
    for n in range(N):
        _frames(Q, n, need, parent, origin, dof_start, dof_stop, axis, sign, trans, R, o, same)
        _project_pose(R, o, n, cap_seg, cap_a, cap_b, cap_r, cam_R, cam_t, cam_k, a, b, ra, rb)
        _pose_points(R, o, n, pt_seg, pt_local, out)
    return a, b, ra, rb, out


def warm_up() -> None:
    """Compile the kernel with the argument types :class:`PoseProjector` passes, on a one-segment
    chain (a no-op when numba's on-disk cache already holds it)."""
    i1, f2 = np.zeros(1, np.int64), np.zeros((1, 3))
    chain = (np.full(1, -1, np.int64), f2, i1, i1 + 1, i1, np.ones(1), np.zeros(1, np.bool_))
    _kinematics(np.zeros((1, 1)), np.ones(1, np.bool_), *chain, i1, f2, f2, np.ones((1, 2)), np.eye(3)[None], f2 + 1,
                np.ones((1, 4)), i1, f2)  # fmt: skip


class PoseProjector:
    """Compiled forward kinematics and projection of one body model into a set of views."""

    def __init__(self, model: BodyModel, views: list[TrackingView]) -> None:
        self.model = model
        segs = model.segments
        self._chain = (
            np.array([s.parent for s in segs], np.int64),
            np.array([s.origin if s.parent >= 0 else np.zeros(3) for s in segs], np.float64).reshape(-1, 3),
            np.array([s.dof_start for s in segs], np.int64),
            np.array([s.dof_stop for s in segs], np.int64),
            np.array([a for s in segs for a in s.axes], np.int64),
            np.array([g for s in segs for g in s.signs], np.float64),
            np.array([t for s in segs for t in s.translation], np.bool_),
        )
        self._cams = (
            np.array([v.camera.R for v in views], np.float64).reshape(-1, 3, 3),
            np.array([v.camera.tvec for v in views], np.float64).reshape(-1, 3),
            np.array([[v.K[0, 0], v.K[1, 1], v.K[0, 2], v.K[1, 2]] for v in views], np.float64).reshape(-1, 4),
        )
        self._radii = np.ascontiguousarray(model.capsule_radii, np.float64)
        self._all_capsules = np.arange(len(model.capsule_segment))
        self._all_points = np.arange(model.n_points)
        self._no_capsules, self._no_points = np.arange(0), np.arange(0)
        #: the kernel's arguments per selection of capsules and points (dtypes + indices), built once
        self._args: dict[tuple[bytes, bytes], tuple] = {}

    def _needed(self, segments: np.ndarray) -> np.ndarray:
        """(S,) bool: the segments ``segments`` and their ancestors, whose frames the kinematics computes."""
        need = np.zeros(len(self.model.segments), np.bool_)
        for s in np.asarray(segments, np.int64):
            while s >= 0 and not need[s]:
                need[s] = True
                s = self.model.segments[s].parent
        return need

    def _selection(self, caps: np.ndarray, pts: np.ndarray) -> tuple:
        """The kernel's arguments for the capsules ``caps`` and the points ``pts``: the segments whose
        frames are needed (S,) bool, the capsules' segments, ends and radii, the points' segments
        and local coordinates."""
        key = (caps.dtype.str.encode() + caps.tobytes(), pts.dtype.str.encode() + pts.tobytes())
        if key not in self._args:
            m = self.model
            seg, pt_seg = np.ascontiguousarray(m.capsule_segment[caps]), np.ascontiguousarray(m.point_segment[pts])
            self._args[key] = (self._needed(np.concatenate([seg, pt_seg])), seg, np.ascontiguousarray(m.capsule_a[caps]),
                               np.ascontiguousarray(m.capsule_b[caps]), self._radii[caps], pt_seg,
                               np.ascontiguousarray(m.point_local[pts]))  # fmt: skip
        return self._args[key]

    def capsules(self, Q: np.ndarray, caps: np.ndarray | None = None) -> Projected:
        """Poses Q (N, D) -> the capsules ``caps`` (default: all) projected in every view."""
        return self.capsules_and_points(Q, self._all_capsules if caps is None else caps, self._no_points)[0]

    def points(self, Q: np.ndarray, pts: np.ndarray | None = None) -> np.ndarray:
        """Poses Q (N, D) -> positions (N, len(pts), 3) of the points ``pts`` (default: all)."""
        return self.capsules_and_points(Q, self._no_capsules, self._all_points if pts is None else pts)[1]

    def capsules_and_points(self, Q: np.ndarray, caps: np.ndarray, pts: np.ndarray) -> tuple[Projected, np.ndarray]:
        """Poses Q (N, D) -> the capsules ``caps`` projected in every view and the positions
        (N, len(pts), 3) of the points ``pts``, from one pass of the kinematics (each bit for bit as
        :meth:`capsules` and :meth:`points` give it alone)."""
        need, seg, cap_a, cap_b, radii, pt_seg, local = self._selection(np.asarray(caps), np.asarray(pts))
        Q = np.ascontiguousarray(np.atleast_2d(Q), np.float64)
        a, b, ra, rb, out = _kinematics(Q, need, *self._chain, seg, cap_a, cap_b, radii, *self._cams, pt_seg, local)
        return Projected(a, b, ra, rb), out
