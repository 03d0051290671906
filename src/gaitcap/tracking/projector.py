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

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

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


@njit(cache=True, inline="always")
def _rotate(R: np.ndarray, axis: int, angle: float) -> None:
    """R <- R · R_axis(angle), in place (R: 3 x 3)."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = (1, 2) if axis == 0 else ((2, 0) if axis == 1 else (0, 1))
    for r in range(3):
        ri, rj = R[r, i], R[r, j]
        R[r, i] = ri * c + rj * s
        R[r, j] = -ri * s + rj * c


@njit(cache=True)
def _frames(q, parent, origin, dof_start, dof_stop, axis, sign, trans) -> tuple[np.ndarray, np.ndarray]:
    """World frames of every segment for one pose q (D,): R (S, 3, 3), o (S, 3)."""
    S = parent.shape[0]
    R = np.empty((S, 3, 3))
    o = np.empty((S, 3))
    for s in range(S):
        p = parent[s]
        if p < 0:
            for i in range(3):
                o[s, i] = 0.0
                for j in range(3):
                    R[s, i, j] = 1.0 if i == j else 0.0
        else:
            for i in range(3):
                o[s, i] = o[p, i] + R[p, i, 0] * origin[s, 0] + R[p, i, 1] * origin[s, 1] + R[p, i, 2] * origin[s, 2]
                for j in range(3):
                    R[s, i, j] = R[p, i, j]
        for d in range(dof_start[s], dof_stop[s]):
            if trans[d]:
                o[s, axis[d]] += sign[d] * q[d]
            else:
                _rotate(R[s], axis[d], sign[d] * q[d])
    return R, o


@njit(cache=True, inline="always")
def _world(R: np.ndarray, o: np.ndarray, s: int, loc: np.ndarray, i: int) -> float:
    """Coordinate i of the point with coordinates ``loc`` in segment s's frame."""
    return o[s, i] + R[s, i, 0] * loc[0] + R[s, i, 1] * loc[1] + R[s, i, 2] * loc[2]


@njit(parallel=True, cache=True)
def _project(Q, parent, origin, dof_start, dof_stop, axis, sign, trans, cap_seg, cap_a, cap_b, cap_r,
             cam_R, cam_t, cam_k):  # fmt: skip
    N, K, C = Q.shape[0], cap_seg.shape[0], cam_R.shape[0]
    a = np.empty((C, N, K, 2))
    b = np.empty((C, N, K, 2))
    ra = np.empty((C, N, K))
    rb = np.empty((C, N, K))
    for n in prange(N):
        R, o = _frames(Q[n], parent, origin, dof_start, dof_stop, axis, sign, trans)
        for k in range(K):
            s = cap_seg[k]
            for end in range(2):
                loc = cap_a[k] if end == 0 else cap_b[k]
                X0, X1, X2 = _world(R, o, s, loc, 0), _world(R, o, s, loc, 1), _world(R, o, s, loc, 2)
                for c in range(C):
                    Rc = cam_R[c]
                    px = Rc[0, 0] * X0 + Rc[0, 1] * X1 + Rc[0, 2] * X2 + cam_t[c, 0]
                    py = Rc[1, 0] * X0 + Rc[1, 1] * X1 + Rc[1, 2] * X2 + cam_t[c, 1]
                    pz = max(Rc[2, 0] * X0 + Rc[2, 1] * X1 + Rc[2, 2] * X2 + cam_t[c, 2], 1e-3)
                    fx, fy, cx, cy = cam_k[c, 0], cam_k[c, 1], cam_k[c, 2], cam_k[c, 3]
                    u, v, rad = fx * px / pz + cx, fy * py / pz + cy, 0.5 * (fx + fy) * cap_r[k, end] / pz
                    if end == 0:
                        a[c, n, k, 0], a[c, n, k, 1], ra[c, n, k] = u, v, rad
                    else:
                        b[c, n, k, 0], b[c, n, k, 1], rb[c, n, k] = u, v, rad
    return a, b, ra, rb


@njit(parallel=True, cache=True)
def _points(Q, parent, origin, dof_start, dof_stop, axis, sign, trans, pt_seg, pt_local):  # fmt: skip
    N, P = Q.shape[0], pt_seg.shape[0]
    out = np.empty((N, P, 3))
    for n in prange(N):
        R, o = _frames(Q[n], parent, origin, dof_start, dof_stop, axis, sign, trans)
        for p in range(P):
            for i in range(3):
                out[n, p, i] = _world(R, o, pt_seg[p], pt_local[p], i)
    return out


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

    def capsules(self, Q: np.ndarray, caps: np.ndarray | None = None) -> Projected:
        """Poses Q (N, D) -> the capsules ``caps`` (default: all) projected in every view."""
        m = self.model
        caps = self._all_capsules if caps is None else np.asarray(caps)
        Q = np.ascontiguousarray(np.atleast_2d(Q), np.float64)
        a, b, ra, rb = _project(Q, *self._chain, m.capsule_segment[caps], np.ascontiguousarray(m.capsule_a[caps]),
                                np.ascontiguousarray(m.capsule_b[caps]), self._radii[caps], *self._cams)  # fmt: skip
        return Projected(a, b, ra, rb)

    def points(self, Q: np.ndarray, pts: np.ndarray | None = None) -> np.ndarray:
        """Poses Q (N, D) -> positions (N, len(pts), 3) of the points ``pts`` (default: all)."""
        m = self.model
        pts = self._all_points if pts is None else np.asarray(pts)
        Q = np.ascontiguousarray(np.atleast_2d(Q), np.float64)
        return _points(Q, *self._chain, m.point_segment[pts], np.ascontiguousarray(m.point_local[pts]))
