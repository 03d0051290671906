"""Resampling schemes: pure functions ``ancestors = scheme(W, M, rng)``.

``W`` are normalised weights (N,), ``M`` the number of draws; each scheme returns (M,) indices whose
expected number of copies of particle n is M * W[n].
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

Scheme = Callable[[np.ndarray, int, np.random.Generator], np.ndarray]


def normalise_log_weights(logw: np.ndarray) -> np.ndarray:
    """exp(logw) / sum, computed stably. NaN or -inf weights count as zero."""
    lw = np.where(np.isfinite(logw), logw, -np.inf)
    m = lw.max()
    if not np.isfinite(m):
        return np.full(len(lw), 1.0 / len(lw))
    w = np.exp(lw - m)
    return w / w.sum()


def ess(W: np.ndarray) -> float:
    """Effective sample size 1 / sum W^2 of normalised weights."""
    return float(1.0 / np.sum(W * W))


def _inverse_cdf(u: np.ndarray, W: np.ndarray) -> np.ndarray:
    cdf = np.cumsum(W)
    cdf[-1] = 1.0
    return np.searchsorted(cdf, u, side="right").clip(0, len(W) - 1)


def multinomial(W: np.ndarray, M: int, rng: np.random.Generator) -> np.ndarray:
    return _inverse_cdf(np.sort(rng.uniform(size=M)), W)


def stratified(W: np.ndarray, M: int, rng: np.random.Generator) -> np.ndarray:
    return _inverse_cdf((np.arange(M) + rng.uniform(size=M)) / M, W)


def systematic(W: np.ndarray, M: int, rng: np.random.Generator) -> np.ndarray:
    return _inverse_cdf((np.arange(M) + rng.uniform()) / M, W)


def residual(W: np.ndarray, M: int, rng: np.random.Generator) -> np.ndarray:
    """Deterministic floor(M W) copies, the remainder drawn multinomially from M W - floor(M W)."""
    counts = np.floor(M * W).astype(int)
    rest = M - counts.sum()
    out = np.repeat(np.arange(len(W)), counts)
    if rest > 0:
        r = M * W - counts
        out = np.concatenate([out, multinomial(r / r.sum(), rest, rng)])
    return np.sort(out)


SCHEMES: dict[str, Scheme] = {"multinomial": multinomial, "stratified": stratified, "systematic": systematic,
                              "residual": residual}  # fmt: skip


def resampler(name: str) -> Scheme:
    try:
        return SCHEMES[name]
    except KeyError:
        raise ValueError(f"unknown resampling scheme {name!r} (choose from {', '.join(SCHEMES)})") from None
