"""Compiled steps of one layer of a particle search (the factored IPF's nodes call them thousands of
times a frame, on a few hundred particles each, where numpy's per-call overhead outweighed the work).

- :func:`layer_poses`: the particles of a node's DOF moved by their grid steps, the best so far put
  back as particle 0, each DOF wrapped or clipped to its limits, and made into whole poses;
- :func:`layer_log_weights`: log w = the silhouette log-likelihood from the kernel's sums
  (:class:`~gaitcap.tracking.likelihood.SilhouetteLikelihood`) + the posture prior over the searched
  DOF + the legs' gap prior (:meth:`~gaitcap.tracking.base.Tracker.log_prior`).

Each computes bit for bit what the numpy expressions they replace computed: the same operations in
the same order.
"""

from __future__ import annotations

import math

import numpy as np

from gaitcap.jit import cached_njit
from gaitcap.tracking.contact import _PAIRS, _leg_gap


@cached_njit(nogil=True)
def layer_poses(X: np.ndarray, K: np.ndarray, step: np.ndarray, best: np.ndarray, idx: np.ndarray, wrap: np.ndarray,
                lower: np.ndarray, upper: np.ndarray, template: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Particles X (N, k) of the DOF ``idx`` (k,) moved by K (N, k) whole grid steps of ``step`` (k,),
    particle 0 replaced by ``best`` (k,); each DOF wrapped to [-pi, pi) (``wrap`` (k,) bool) or clipped
    to [``lower``, ``upper``] (k,); -> (the particles (N, k), the poses (N, D): ``template`` (D,)
    with the particles' DOF set)."""
    N, k = X.shape
    out = np.empty((N, k))
    Q = np.empty((N, template.shape[0]))
    for n in range(N):
        for d in range(template.shape[0]):
            Q[n, d] = template[d]
        for j in range(k):
            x = best[j] if n == 0 else X[n, j] + K[n, j] * step[j]
            if wrap[j]:
                x = (x + math.pi) % (2 * math.pi) - math.pi
            elif not np.isnan(x):  # np.clip's comparisons (NaN stays NaN), not max / min
                x = x if x > lower[j] else lower[j]  # noqa: FURB136
                x = x if x < upper[j] else upper[j]  # noqa: FURB136
            out[n, j] = x
            Q[n, idx[j]] = x
    return out, Q


@cached_njit(nogil=True)
def layer_log_weights(I: np.ndarray, M: np.ndarray, areas: np.ndarray, beta: float, Q: np.ndarray, dofs: np.ndarray,
                      sigma: np.ndarray, legs: np.ndarray, gap_min: float, gap_sigma: float) -> np.ndarray:  # fmt: skip
    """log w (N,) of poses Q (N, D) from the kernel's sums I, M (C, N) against silhouettes of ``areas``
    (C,) (each at least 1): beta / C sum_c (2 I_c - M_c) / area_c, plus -1/2 sum_d (Q_d / sigma_d)^2
    over ``dofs``, plus (``legs`` (N, 6, 3) non-empty) the legs' gap prior -1/2 (max(gap_min - gap,
    0) / gap_sigma)^2."""
    C, N = I.shape
    k = dofs.shape[0]
    gaps = _leg_gap(legs, _PAIRS) if legs.shape[0] > 0 else np.empty(0)
    out = np.empty(N)
    for n in range(N):
        s = (2 * I[0, n] - M[0, n]) / areas[0]
        for c in range(1, C):
            s += (2 * I[c, n] - M[c, n]) / areas[c]
        ll = beta * (s / C)
        acc = 0.0  # in numpy's order for Q[:, dofs] (a column-major copy): DOF after DOF
        for j in range(k):
            z = Q[n, dofs[j]] / sigma[dofs[j]]
            acc += z * z
        prior = -0.5 * acc
        if legs.shape[0] > 0:
            short = gap_min - gaps[n]
            short = (short if short >= 0.0 or np.isnan(short) else 0.0) / gap_sigma
            prior += -0.5 * short * short
        out[n] = ll + prior
    return out


def warm_up() -> None:
    """Compile the kernels with the argument types the tracker passes (a no-op when numba's on-disk
    cache already holds them: see :mod:`gaitcap.tracking.precompile`)."""
    i1, f1 = np.zeros(1, np.int64), np.zeros(1)
    _, Q = layer_poses(np.zeros((1, 1)), np.zeros((1, 1), np.int64), f1, f1, i1, np.zeros(1, np.bool_), f1 - 1, f1 + 1,
                       f1)  # fmt: skip
    sums = np.zeros((1, 1))
    for legs in (np.zeros((0, 6, 3)), np.zeros((1, 6, 3))):
        layer_log_weights(sums, sums, np.ones(1), 1.0, Q, i1, np.ones(1), legs, 0.1, 0.01)
