"""The silhouette likelihood (declares; the filters only call it).

For camera c with silhouette S_c (soft, in [0, 1]) and a particle's projected model M_c (the union
of its capsules), the overlap I_c = sum_{M_c} S_c and the model area A_c = |M_c| give the symmetric
difference |M_c xor S_c| = |S_c| + A_c - 2 I_c, which rewards model area inside the silhouette and
silhouette area covered by the model (the paper's interleaving zone). The log-likelihood is

    log p(z | x) = beta / C * sum_c (2 I_c - A_c) / |S_c|          (= -beta/C sum_c xor_c/|S_c| + const)

For a node of the factored filter the sums run only over the pixels that the segments already
placed leave free (Img_n of the paper): free_c = 1 - placed_c, and

    log p(z_n | x_n) = beta / C * sum_c (2 sum_{M_c} S_c free_c - sum_{M_c} free_c) / |S_c|

so pixels explained by earlier segments neither reward nor penalise the segment being placed.
"""

from __future__ import annotations

import numpy as np

from gaitcap.tracking.observation import Observation, TrackingView
from gaitcap.tracking.projector import Projected
from gaitcap.tracking.raster import (capsule_sums_views, fill_capsules, free_prefix_rows, free_prefixes,
                                    free_prefixes_views, rows_reached)


class SilhouetteLikelihood:
    """Scores capsule sets against an observation in every view."""

    def __init__(self, views: list[TrackingView], beta: float) -> None:
        self.views = views
        self.beta = beta

    def project(self, view: TrackingView, A: np.ndarray, B: np.ndarray, radii: np.ndarray):
        """Capsules (N, K, 3) -> 2D ends (N, K, 2) and radii (N, K) in the view's pixels."""
        a, za = view.project(A)
        b, zb = view.project(B)
        f = view.focal
        return a, b, f * radii[:, 0] / za, f * radii[:, 1] / zb

    @staticmethod
    def free_prefixes(obs: Observation, placed: list[np.ndarray], into: tuple[np.ndarray, np.ndarray] | None = None
                      ) -> list[tuple[np.ndarray, np.ndarray]]:  # fmt: skip
        """Row prefix sums of (silhouette x free, free) per camera, free = 1 - placed (placed: the
        pixels already explained, (h, w) float32 0/1 masks, one per camera), for :meth:`terms`.
        ``into``: two (C, h, w + 1) arrays to write them into (views of one size only; else ignored)."""
        if len({s.shape for s in obs.silhouettes}) > 1:  # views of different sizes: one by one
            return [free_prefixes(s, p) for s, p in zip(obs.silhouettes, placed)]
        C1, C2 = free_prefixes_views(tuple(obs.silhouettes), tuple(placed), into)
        return list(zip(C1, C2))

    def projected(self, A: np.ndarray, B: np.ndarray, radii: np.ndarray) -> Projected:
        """World capsules A, B (N, K, 3), radii (K, 2) -> every view's 2D capsules (numpy path;
        the trackers use the compiled :class:`~gaitcap.tracking.projector.PoseProjector`)."""
        parts = [self.project(view, A, B, radii) for view in self.views]
        return Projected(*(np.stack([p[i] for p in parts]) for i in range(4)))

    def terms(
        self, obs: Observation, proj: Projected, free: list[tuple[np.ndarray, np.ndarray]] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per camera overlap I (C, N) and model area A (C, N) of projected capsules, over the free
        pixels when ``free`` (from :meth:`free_prefixes`) is given."""
        prefixes = [obs.prefix(c) for c in range(len(self.views))] if free is None else free
        return capsule_sums_views(proj.a, proj.b, proj.ra, proj.rb, tuple(p[0] for p in prefixes),
                                  tuple(p[1] for p in prefixes))  # fmt: skip

    def score(
        self, obs: Observation, proj: Projected, free: list[tuple[np.ndarray, np.ndarray]] | None = None
    ) -> np.ndarray:
        """log p(z | x) of N particles' projected capsules: shape (N,)."""
        return self._log_likelihood(*self.terms(obs, proj, free), obs)

    def fit_of(self, obs: Observation, proj: Projected) -> np.ndarray:
        """1 - xor/|S| averaged over the cameras, shape (N,): 1 is a perfect fit, <= 0 no overlap."""
        return self._fit(*self.terms(obs, proj), obs)

    def evaluate(self, obs: Observation, proj: Projected) -> tuple[np.ndarray, np.ndarray]:
        """(:meth:`score`, :meth:`fit_of`) against the full silhouettes, from one pass of the kernel."""
        I, M = self.terms(obs, proj)
        return self._log_likelihood(I, M, obs), self._fit(I, M, obs)

    def _log_likelihood(self, I: np.ndarray, M: np.ndarray, obs: Observation) -> np.ndarray:
        areas = np.maximum(obs.areas, 1.0)[:, None]
        return self.beta * (np.add.reduce((2 * I - M) / areas, axis=0) / len(areas))  # the mean over the cameras

    @staticmethod
    def _fit(I: np.ndarray, M: np.ndarray, obs: Observation) -> np.ndarray:
        areas = np.maximum(obs.areas, 1.0)[:, None]
        xor = areas + M - 2 * I
        return np.mean(1.0 - xor / areas, axis=0)

    def fill(self, view_index: int, proj: Projected, into: np.ndarray, pose: int = 0) -> tuple[int, int]:
        """Set the pixels of one pose's projected capsules to 1 in ``into`` (h, w) of a view: exactly
        the pixels the likelihood counts. Returns the first and last rows that may have changed."""
        a, b, ra, rb = proj.camera(view_index)
        return fill_capsules(into, a[pose], b[pose], ra[pose], rb[pose], 1.0)

    @staticmethod
    def refresh_free(obs: Observation, placed: list[np.ndarray], free: list[tuple[np.ndarray, np.ndarray]],
                     rows: list[tuple[int, int]]) -> None:  # fmt: skip
        """Bring :meth:`free_prefixes` ``free`` up to date, in place, after ``placed`` changed on the
        rows ``rows`` (first, last) of each view only: the same values as computing them anew."""
        for s, p, (C1, C2), (y0, y1) in zip(obs.silhouettes, placed, free, rows):
            free_prefix_rows(s, p, C1, C2, y0, y1)


class FreeRows:
    """:meth:`SilhouetteLikelihood.free_prefixes` computed row by row, as the capsules scored reach
    them (:meth:`cover`): a node of the factored filter's further passes, scored against the pixels
    all the other segments leave free, reaches a fraction of the image's rows. The rows read are
    the same values as computing every row; the others hold whatever the arrays held."""

    def __init__(self, obs: Observation, placed: list[np.ndarray], into: tuple[np.ndarray, np.ndarray] | None) -> None:
        self._obs, self._placed = obs, placed
        if into is None:  # views of different sizes
            into_views = [(np.empty((h, w + 1)), np.empty((h, w + 1))) for h, w in (s.shape for s in obs.silhouettes)]
        else:
            into_views = list(zip(into[0], into[1]))
        #: the prefix sums per view, as :meth:`SilhouetteLikelihood.free_prefixes` returns them
        self.free: list[tuple[np.ndarray, np.ndarray]] = into_views
        self._heights = np.array([s.shape[0] for s in obs.silhouettes], np.int64)
        self._done = [(1, 0)] * len(placed)  # per view, the rows computed (first > last: none)

    def cover(self, proj: Projected) -> list[tuple[np.ndarray, np.ndarray]]:
        """Compute the rows the projected capsules reach that are not yet computed; returns :attr:`free`."""
        need = rows_reached(proj.a, proj.b, proj.ra, proj.rb, self._heights)
        for c, (lo, hi) in enumerate(need):
            if lo > hi:
                continue
            s, p, (C1, C2) = self._obs.silhouettes[c], self._placed[c], self.free[c]
            d0, d1 = self._done[c]
            if d0 > d1:
                free_prefix_rows(s, p, C1, C2, lo, hi)
                self._done[c] = (lo, hi)
                continue
            # the computed rows stay one interval: the gaps on either side are filled
            free_prefix_rows(s, p, C1, C2, lo, d0 - 1)
            free_prefix_rows(s, p, C1, C2, d1 + 1, hi)
            self._done[c] = (min(lo, d0), max(hi, d1))
        return self.free
