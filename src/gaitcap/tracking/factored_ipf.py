"""Factored interval particle filtering (Saboune & Charpillet).

The pose x = (x_1, ..., x_S) is factored along the kinematic chain: node n holds the DOF of
segment n. The filter walks the chain in topological order (``factored_ipf.order``); at node n:

    state node        x_n^(i) = x̂_n + δ^(i),  δ^(i)_d ∈ {-m_d, ..., m_d} · step      (children on the
                      discretised interval of each DOF around the current estimate x̂_n)
    observation node  log w^(i) = log p(z_n | x̂_{<n}, x_n^(i))                        (likelihood.py:
                      the subtree of n against Img_n = the silhouette left free by the segments
                      already placed)
                      W^(i) = w^(i) / Σ_j w^(j);  resample when ESS = 1 / Σ_i (W^(i))² < τ N
    refinement        further layers with finer steps (down to 2 degrees) around the resampled
                      particles
    drift             x̂_n <- argmax_i w^(i)  (the best is kept; the estimate of x̂_n seeds the
                      next frame: no dynamic model)

then the segment's own capsules at x̂ are drawn into the placed mask, shrinking Img_{n+1}. A point's
uncertainty is the square root of the sum, over the nodes that move it, of the weighted variance
of its position across that node's particles.
"""

from __future__ import annotations

import numpy as np

from gaitcap.tracking.base import Estimate, Tracker, weighted_spread
from gaitcap.tracking.chain import capsules_of, points_of, subtree_frames, subtrees
from gaitcap.tracking.observation import Observation
from gaitcap.tracking.resampling import ess, normalise_log_weights, systematic


class FactoredIPF(Tracker):
    name = "factored-ipf"

    def __init__(self, *args, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(*args, **kwargs)
        self.order = self.config.order_indices(self.model)
        self.subtrees = subtrees(self.model)
        names = self.model.dof_names
        legs = ("hip_", "knee_", "ankle_")
        self._left = np.array([i for i, n in enumerate(names) if n.endswith("_l") and n.startswith(legs)])
        self._right = np.array([names.index(names[i][:-2] + "_r") for i in self._left])

    def step(self, obs: Observation, widen: float = 1.0) -> Estimate:
        """Track one frame from the previous estimate and, with ``swap_hypothesis``, also from its
        leg-swapped mirror; the better fit wins.

        Seen from the side the two legs are interchangeable, and a chain walk that put the left leg
        on the right leg's pixels settles in a consistent wrong state (heading turned, hips
        compensating) that no single node can leave: the mirrored start, searched in full, lets
        the silhouettes of all cameras decide again.
        """
        start = self.q.copy()
        cfg = self.config.factored_ipf
        best = self._search(obs, start, widen, 0, 1)
        if cfg.swap_hypothesis:
            # both hypotheses get the first pass; the further passes refine the winner only
            mirrored = start.copy()
            mirrored[self._left], mirrored[self._right] = start[self._right], start[self._left]
            other = self._search(obs, mirrored, widen, 0, 1)
            evaluations = best.evaluations + other.evaluations
            best = other if other.fit > best.fit else best
            best.evaluations = evaluations
        if cfg.passes > 1:
            refined = self._search(obs, best.q, widen, 1, cfg.passes)
            refined.evaluations += best.evaluations
            best = refined
        self.q = best.q
        return best

    def _search(self, obs: Observation, start: np.ndarray, widen: float, first: int, stop: int) -> Estimate:
        """Passes ``first`` to ``stop - 1`` of the factored search from ``start``
        (``widen`` > 1 enlarges every interval).

        The first pass walks the chain with Img_n = the silhouette minus the segments placed so
        far; each further pass (``passes``) revisits every node with Img_n = the silhouette minus
        all the other segments at their current estimates, with the finer layers only.
        """
        model, cfg = self.model, self.config.factored_ipf
        q = start.copy()
        variance = np.zeros(model.n_points)
        evaluations = 0
        for p in range(first, stop):
            layers = cfg.layers if p == 0 else cfg.layers[-1:]
            variance[:] = 0.0
            placed = [np.zeros_like(s) for s in obs.silhouettes]
            R_all, o_all = model.frames(q[None])
            for s in self.order:
                seg = model.segments[s]
                sub = self.subtrees[s]
                n = cfg.root_particles if seg.parent < 0 else cfg.particles
                parent_R = None if seg.parent < 0 else R_all[0, seg.parent]
                parent_o = None if seg.parent < 0 else o_all[0, seg.parent]
                if p == 0:
                    free = self.likelihood.free_prefixes(obs, [1.0 - m for m in placed])
                else:
                    free = self.likelihood.free_prefixes(obs, self._free_outside(q, sub, R_all, o_all, obs))
                q, W, X, pts = self._node(obs, q, seg.dofs, sub, parent_R, parent_o, free, n, widen, layers)
                evaluations += n * len(layers)
                variance[sub.points] += weighted_spread(pts, W)
                R_all, o_all = model.frames(q[None])
                if p == 0:
                    self._place(q, sub.own_capsules, placed, R_all, o_all)
        ll, fit = self.full_fit(obs, q)
        points = model.forward(q[None])[0]
        return Estimate(q=q, points=points, uncertainty=np.sqrt(variance), log_likelihood=ll, fit=fit,
                        evaluations=evaluations)  # fmt: skip

    def _node(self, obs, q, dofs: slice, sub, parent_R, parent_o, free, n: int, widen: float, layers):
        """Diffuse, weight, resample and keep the best for one node. Returns the new estimate,
        the final weights (N,), the particles' node DOF values and their subtree points."""
        model = self.model
        idx = np.arange(model.n_dofs)[dofs]
        base = np.repeat(q[None], n, axis=0)
        X = base[:, idx].copy()
        logw = np.zeros(n)
        best_x, best_ll = q[idx].copy(), -np.inf
        for li, layer in enumerate(layers):
            W = normalise_log_weights(logw)
            if li > 0 or ess(W) < self.config.factored_ipf.ess_threshold * n:
                X = X[systematic(W, n, self.rng)]
            X = X + self.grid_offsets(n, idx, layer, widen)
            X[0] = best_x  # the best so far competes unchanged
            Q = base.copy()
            Q[:, idx] = X
            Q = model.clip(Q)
            X = Q[:, idx]
            Rs, os_ = subtree_frames(model, sub, Q, parent_R, parent_o)
            A, B, r = capsules_of(model, sub.capsules, Rs, os_)
            logw = self.likelihood.log_likelihood(obs, A, B, r, free)
            i = int(np.argmax(logw))
            if logw[i] > best_ll:
                best_ll, best_x = float(logw[i]), X[i].copy()
        q = q.copy()
        q[idx] = best_x
        pts = points_of(model, sub.points, Rs, os_)
        return q, normalise_log_weights(logw), X, pts

    def _free_outside(self, q, sub, R_all, o_all, obs: Observation) -> list[np.ndarray]:
        """1 - (all segments outside the subtree, drawn at the estimate), per view."""
        others = np.setdiff1d(np.arange(len(self.model.capsule_a)), sub.capsules)
        placed = [np.zeros_like(s) for s in obs.silhouettes]
        self._place(q, others, placed, R_all, o_all)
        return [1.0 - m for m in placed]

    def _place(self, q, caps, placed, R_all, o_all) -> None:
        """Draw the segment's own capsules at the estimate into every view's placed mask."""
        if len(caps) == 0:
            return
        Rs = {s: R_all[:, s] for s in range(len(self.model.segments))}
        os_ = {s: o_all[:, s] for s in range(len(self.model.segments))}
        A, B, r = capsules_of(self.model, caps, Rs, os_)
        for c in range(len(placed)):
            self.likelihood.render(c, A[0], B[0], r, placed[c])
