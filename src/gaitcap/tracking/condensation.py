"""Condensation (sampling-importance-resampling over the full state): the paper's baseline.

The weighted particle set persists from frame to frame. Each frame:

    resample    x^(i) ~ Σ_j W^(j) δ(x - x^(j))                      (systematic)
    diffuse     x^(i) <- clip(x^(i) + ε^(i)),  ε_d ~ N(0, (σ_f h_d)²)  (no dynamic model: a random walk)
    weight      W^(i) ∝ p(z | x^(i))
    estimate    x̂ = the particle of largest weight
"""

from __future__ import annotations

import numpy as np

from gaitcap.tracking.base import Estimate, Tracker, weighted_spread
from gaitcap.tracking.observation import Observation
from gaitcap.tracking.resampling import normalise_log_weights, systematic


class Condensation(Tracker):
    name = "condensation"
    STATE = ("q", "X", "W")

    def start(self, q0: np.ndarray, fresh: bool = True) -> None:
        super().start(q0, fresh)
        self.X = np.repeat(self.q[None], self.config.condensation.particles, axis=0)
        self.W = np.full(len(self.X), 1.0 / len(self.X))

    def _step(self, obs: Observation, widen: float = 1.0) -> Estimate:
        model, cfg = self.model, self.config.condensation
        if not hasattr(self, "X"):
            self.start(self.q)
        n = cfg.particles
        X = self.X[systematic(self.W, n, self.rng)]
        sigma = cfg.sigma_fraction * self.half_width * widen
        X = model.clip(X + self.rng.normal(0.0, 1.0, size=X.shape) * sigma)
        logw = self.likelihood.score(obs, self.projector.capsules(X)) + self.log_prior(X)
        self.X, self.W = X, normalise_log_weights(logw)
        i = int(np.argmax(logw))
        self.q = X[i].copy()
        ll, fit = self.full_fit(obs, self.q)
        spread = weighted_spread(self.projector.points(X), self.W)
        return Estimate(q=self.q, points=model.forward(self.q[None])[0], uncertainty=np.sqrt(spread),
                        log_likelihood=ll, fit=fit, evaluations=n)  # fmt: skip
