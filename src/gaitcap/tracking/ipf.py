"""Interval particle filtering over the full state (the paper's IPF baseline).

Every particle is drawn on the discretised intervals of all explored DOF around the previous
estimate (step 5 degrees by default) and weighted with the full-body likelihood; further layers, if
configured, refine around the resampled particles; the best particle is kept as the estimate:

    x^(i) = x̂ + δ^(i),  δ^(i)_d ∈ {-m_d..m_d} · step;   w^(i) = p(z | x^(i));   x̂ <- argmax_i w^(i)
"""

from __future__ import annotations

import numpy as np

from gaitcap.tracking.base import Estimate, Tracker, weighted_spread
from gaitcap.tracking.observation import Observation
from gaitcap.tracking.resampling import normalise_log_weights, systematic


class IntervalPF(Tracker):
    name = "ipf"

    def _step(self, obs: Observation, widen: float = 1.0) -> Estimate:
        model, cfg = self.model, self.config.ipf
        n = cfg.particles
        all_dofs = np.arange(model.n_dofs)
        X = np.repeat(self.q[None], n, axis=0)
        logw = np.zeros(n)
        best_q, best_ll = self.q.copy(), -np.inf
        for li, layer in enumerate(cfg.layers):
            if li > 0:
                X = X[systematic(normalise_log_weights(logw), n, self.rng)]
            X = model.clip(X + self.grid_offsets(n, all_dofs, layer, widen))
            X[0] = best_q
            logw = self.likelihood.score(obs, self.projector.capsules(X)) + self.log_prior(X)
            i = int(np.argmax(logw))
            if logw[i] > best_ll:
                best_ll, best_q = float(logw[i]), X[i].copy()
        self.q = best_q
        W = normalise_log_weights(logw)
        spread = weighted_spread(self.projector.points(X), W)
        ll, fit = self.full_fit(obs, best_q)
        return Estimate(q=best_q, points=model.forward(best_q[None])[0], uncertainty=np.sqrt(spread),
                        log_likelihood=ll, fit=fit, evaluations=n * len(cfg.layers))  # fmt: skip
