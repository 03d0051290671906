"""Factored interval particle filtering (Saboune & Charpillet).

The pose x = (x_1, ..., x_S) is factored along the kinematic chain: node n holds the DOF of
segment n, plus the ``coupled`` DOF of the segments below it (hip flexion with knee flexion, knee
with ankle: the likelihood has a ridge along which they trade off, which one-DOF-group-at-a-time
moves cannot follow). The filter walks the chain in topological order (``factored_ipf.order``); at node n:

    state node        x_n^(i) = x̂_n + δ^(i),  δ^(i)_d ∈ {-m_d, ..., m_d} · step      (children on the
                      discretised interval of each DOF around the current estimate x̂_n)
    observation node  log w^(i) = log p(z_n | x̂_{<n}, x_n^(i)) + log p(x_n^(i))      (likelihood.py:
                      the subtree of n against Img_n = the silhouette left free by the segments
                      already placed; p(x_n): the posture prior on the DOF the image cannot
                      see, base.py)
                      W^(i) = w^(i) / Σ_j w^(j);  resample when ESS = 1 / Σ_i (W^(i))² < τ N
    refinement        further layers with finer steps (down to 2 degrees) around the resampled
                      particles
    drift             x̂_n <- argmax_i w^(i)  (the best is kept; the estimate of x̂_n seeds the
                      next frame: no dynamic model)

then the segment's own capsules at x̂ are drawn into the placed mask, shrinking Img_{n+1}.

Further passes revisit every node against all the other segments at their estimates. There the
root moves alone (``root_refine: alone``): the segments attached to it (trunk, thighs) keep their
orientation in the world, their joint angles re-solved for each root particle,

    x_c^(i) = angles(R_root(x_root^(i))^T · R_root(x̂_root) · R_c(x̂_c))       (BodyModel.local_angles)

(``root_anchored`` thighs are aimed instead from the new hip centres at the knees as they were,
the knee flexion re-solved to keep the shank's orientation: the pelvis can then slide along the
likelihood's ridge of hips behind and thighs leaning forward, :meth:`FactoredIPF._held_angles`)
so that the pelvis is placed by what it carries (the hip centres, the thigh tops, the trunk's
base) and not turned to explain a stride: in the first pass, the whole body moved rigidly from
the previous frame's pose, a pelvis rotation mimics the legs' scissoring, and the hips and lumbar
joint then compensate a rotation the image never had. The re-solved angles enter the posture prior. A point's
uncertainty is the square root of the sum, over the nodes that move it, of the weighted variance
of its position across that node's particles.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from gaitcap.errors import ConfigError
from gaitcap.tracking.base import Estimate, Tracker, weighted_spread
from gaitcap.tracking.chain import subtrees
from gaitcap.tracking.likelihood import FreeRows
from gaitcap.tracking.observation import Observation
from gaitcap.tracking.particles import layer_log_weights, layer_poses
from gaitcap.tracking.resampling import ess, normalise_log_weights, systematic


class FactoredIPF(Tracker):
    name = "factored-ipf"
    STATE = ("q", "_fits", "_before", "_fresh", "_turning")

    def __init__(self, *args, uncertainty: bool = True, **kwargs) -> None:  # type: ignore[no-untyped-def]
        """``uncertainty`` False: the estimates' ``uncertainty`` is NaN, the particles' points are not
        computed (the shape calibration's re-fits read the pose and the fit only)."""
        super().__init__(*args, **kwargs)
        self.uncertainty = uncertainty
        #: the views' sizes and dtypes, their placed masks and free prefix sums' arrays (:meth:`_scratch`)
        self._buffers: tuple[tuple, list[np.ndarray], tuple[np.ndarray, np.ndarray] | None] | None = None
        self.order = self.config.order_indices(self.model)
        self.subtrees = subtrees(self.model)
        self._explored = self.config.explored_dofs(self.model, self.subtrees)
        everything = np.arange(len(self.model.capsule_segment))
        self._outside = [np.setdiff1d(everything, sub.capsules) for sub in self.subtrees]
        self._heading = self.model.dof_index("pelvis_rotation")
        self._hip_flex = (self.model.dof_index("hip_flexion_l"), self.model.dof_index("hip_flexion_r"))
        self._knee_flex = (self.model.dof_index("knee_flexion_l"), self.model.dof_index("knee_flexion_r"))
        self._fits: deque[float] = deque(maxlen=self.config.factored_ipf.swap_fit_frames)  # first-pass fits
        self._fresh = True  # no frame tracked since the last start
        self._before: np.ndarray | None = None  # the estimate of the frame before the previous one
        self._turning = 0  # +-k: the heading moved turn_trigger of its interval or more k frames running, that way
        self._sagittal = np.array([*self._hip_flex, *self._knee_flex])
        legs_dofs = np.concatenate([self.left_leg, self.right_leg])
        self._not_legs = np.setdiff1d(np.arange(self.model.n_dofs), legs_dofs)
        self._root = next(seg.index for seg in self.model.segments if seg.parent < 0)
        if self.config.factored_ipf.root_refine == "alone":
            for c in self.model.children(self._root):
                seg = self.model.segments[c]
                if any(seg.translation) or len(set(seg.axes)) != 3 or seg.n_dofs != 3:
                    raise ConfigError(f"tracking config: factored_ipf.root_refine 'alone' needs three rotation DOF "
                                      f"about distinct axes at every joint of the root; segment '{seg.name}' has "
                                      f"{seg.n_dofs}")  # fmt: skip
        #: anchored children of the root -> their one child, whose joint stays put when the root moves alone
        self._anchors = self.config.anchored_children(self.model)
        #: DOF re-solved when the root moves alone: its children's, and the anchored children's child's
        self._held = np.concatenate([np.arange(self.model.segments[c].dof_start, self.model.segments[c].dof_stop)
                                     for c in [*self.model.children(self._root), *self._anchors.values()]]
                                    or [np.zeros(0, int)])  # fmt: skip
        self._no_legs = np.zeros((0, 6, 3))  # layer_log_weights without the legs' gap
        #: position in the order of the first node that explores a leg DOF (the mirrored search
        #: with ``swap_search: legs`` walks the chain from there)
        self._legs_from = min(i for i, s in enumerate(self.order) if np.intersect1d(self._explored[s], legs_dofs).size)

    def start(self, q0: np.ndarray, fresh: bool = True) -> None:
        super().start(q0, fresh)
        self._fits.clear()
        self._before = None
        self._turning = 0
        self._fresh = fresh  # the next frame weighs both leg assignments of q0 on equal terms

    def _step(self, obs: Observation, widen: float = 1.0) -> Estimate:
        """Track one frame from the previous estimate and, with ``swap_hypothesis``, also from its
        leg-swapped mirror; the better fit wins.

        Seen from the side the two legs are interchangeable, and a chain walk that put the left leg
        on the right leg's pixels settles in a consistent wrong state (heading turned, hips
        compensating) that no single node can leave: the mirrored start lets the silhouettes of
        all cameras decide again. With ``swap_search: legs`` (default) the mirrored hypothesis keeps
        the nodes before the legs (pelvis, trunk, arms) where the first search placed them and walks
        the leg nodes only: the pelvis node, the costliest (the whole body scored with the most
        particles), is not searched twice, and the further pass revisits it for the winner.

        The mirror is searched while the legs are close (``swap_within_deg``), where a swap starts,
        and also whenever the first pass fits worse than the recent frames did (``swap_fit_drop``
        below the median of the last ``swap_fit_frames``): a swap made while the legs crossed lowers
        the fit until it is undone, possibly with the legs far apart. That mirror walks the whole
        chain whatever ``swap_search`` says, since a swap that has lasted turns the pelvis too. The
        mirror replaces the first hypothesis only when it fits ``swap_margin`` better: while the legs
        cross, both assignments fit within a few thousandths and a coin-flip choice swaps them for a
        frame or two. On the first frame after a fresh :meth:`start` (a pose whose leg assignment
        no frame has confirmed) the mirror is always searched over the whole chain and wins on any
        better fit, since neither assignment is the previous frame's: a start with the legs swapped
        and apart would otherwise stand until the legs next cross. (The pipeline's starts are
        settled over several frames instead, :func:`gaitcap.tracking.init.settle_legs`: one frame
        can prefer the swap.)

        With ``keep_previous`` the previous estimate, unchanged, competes with the first pass (the
        drift step keeps the best, and a greedy walk of the chain can end below where it started).

        A first pass that still fits ``swap_fit_drop`` below the recent frames is searched again
        on widened intervals (``recover_widen``, :meth:`_recover`).

        While the body turns faster than its heading's interval reaches, every first pass of the
        frame searches the heading on a wider interval (``turn_widen``, :meth:`_turn_widths`).

        Whatever beat the first hypothesis on the first pass (the mirror, a recovered pose) replaces
        it only if it still fits ``swap_margin`` better once both have had the further passes: a
        first pass's fit is a noisy judge of two leg assignments. Such wins are rare, so the second
        refinement costs little.

        With ``swap_continuity``, two hypotheses within ``swap_margin`` of each other are a tie
        that the silhouettes cannot break (seen from the side or from the front, which leg is
        ahead is ambiguous), and the one nearer the legs' extrapolated motion wins
        (:meth:`_preferred`): without it the first hypothesis always won a tie, and a swing leg
        meeting the stance leg bounced back off it half the time. This is no dynamic model: the
        particles are still drawn around the previous estimate alone, and the extrapolation only
        orders two poses the image scores alike.

        The runs behind these choices are in docs/tuning_history.md (``factored_ipf`` keys); with the
        pipeline's backward pass on, switching them off was measured on the whole suite and made the
        tails worse (docs/validation.md, "The step's swap mechanisms with the backward pass in place";
        again with the restart, the mirror's run and the leg order: "The step's swap mechanisms, again").
        """
        start = self.q.copy()
        cfg = self.config.factored_ipf
        turn = self._turn_widths(start)
        reach = widen * turn  # the first passes' interval factors
        best, spreads = self._search(obs, start, reach, 0, 1)
        if cfg.keep_previous:
            best = self._kept_if_better(obs, start, best)
        first = best
        dropped = self._fit_dropped(best.fit)
        fresh, self._fresh = self._fresh or widen > 1.0, False
        # ties broken by the legs' motion only while tracking is healthy: after a start there is no
        # motion yet, and a first pass that dropped follows a previous estimate gone wrong
        continuity = cfg.swap_continuity and not fresh and not dropped
        if cfg.swap_hypothesis and (fresh or self._legs_close(start) or dropped):  # always after a fresh start
            # both hypotheses get the first pass; the further passes refine the winner (and the
            # first hypothesis too when it lost)
            mirrored = self.mirrored(start)
            if cfg.swap_search == "legs" and not fresh and not dropped:
                other = self._search_legs(obs, mirrored, best, spreads, reach)
            else:
                other, _ = self._search(obs, mirrored, reach, 0, 1)
            evaluations = best.evaluations + other.evaluations
            best = self._preferred(best, other, start, 0.0 if fresh else cfg.swap_margin, continuity)
            best.evaluations = evaluations
        if cfg.recover_widen is not None and widen <= 1.0 and self._fit_dropped(best.fit):
            before_recovery = best
            best = self._recover(obs, start, best, turn)
            continuity = continuity and best is before_recovery
        self._fits.append(best.fit)
        if cfg.passes > 1:
            refined, _ = self._search(obs, best.q, widen, 1, cfg.passes)
            if first is not best:  # replaced only if it still loses by swap_margin once refined
                first_refined, _ = self._search(obs, first.q, widen, 1, cfg.passes)
                spent = refined.evaluations + first_refined.evaluations
                refined = self._preferred(first_refined, refined, start, cfg.swap_margin, continuity)
                refined.evaluations = spent
            refined.evaluations += best.evaluations
            best = refined
        self._before = start
        self.q = best.q
        return best

    def refine(self, obs: Observation, q: np.ndarray) -> Estimate:
        """The factored search's passes from pose q (D,) alone: no mirror, no kept previous estimate,
        no recovery (:meth:`Tracker.refine`)."""
        est, _ = self._search(obs, self.model.clip(np.asarray(q, float)[None])[0], 1.0, 0,
                              self.config.factored_ipf.passes)  # fmt: skip
        self.start(est.q, fresh=False)
        return est

    def _preferred(self, incumbent: Estimate, challenger: Estimate, previous: np.ndarray, margin: float,
                   continuity: bool) -> Estimate:  # fmt: skip
        """The challenger when it fits ``margin`` better than the incumbent. Within the margin (a tie
        that silhouettes cannot break: seen from the side or the front, which leg is ahead is
        ambiguous) with ``continuity``, the one whose hip and knee flexions are nearer their
        extrapolation from the last two frames, 2 q_{t-1} - q_{t-2} (``previous``: q_{t-1}; the legs
        keep moving the way they were: a swing leg passes the stance leg instead of bouncing back
        off it); else the incumbent."""
        if challenger.fit > incumbent.fit + margin:
            return challenger
        if not continuity or self._before is None or incumbent.fit > challenger.fit + margin:
            return incumbent
        k = self._sagittal
        ahead = 2 * previous[k] - self._before[k]
        near = [float(np.sum((e.q[k] - ahead) ** 2)) for e in (incumbent, challenger)]
        return challenger if near[1] < near[0] else incumbent

    def _kept_if_better(self, obs: Observation, start: np.ndarray, best: Estimate) -> Estimate:
        """The previous estimate ``start`` (D,) unchanged, when it fits this frame better than the
        first pass ``best`` did (a greedy walk of the chain can end below where it started)."""
        ll, fit = self.full_fit(obs, start)
        if fit <= best.fit:
            return best
        return Estimate(q=start.copy(), points=self.projector.points(start[None])[0], uncertainty=best.uncertainty,
                        log_likelihood=ll, fit=fit, evaluations=best.evaluations + 1)  # fmt: skip

    def _search_legs(self, obs: Observation, legs: np.ndarray, first: Estimate, spreads: list[np.ndarray],
                     widen: float | np.ndarray) -> Estimate:  # fmt: skip
        """A first pass over the leg nodes only, from the legs' angles of pose ``legs`` (D,) with the
        nodes before them where the first hypothesis ``first`` placed them (``spreads``: its nodes'
        contributions to the points' variance, in the order walked)."""
        q = legs.copy()
        q[self._not_legs] = first.q[self._not_legs]
        before = np.sum(spreads[: self._legs_from], axis=0)
        return self._search(obs, q, widen, 0, 1, from_node=self._legs_from, variance=before)[0]

    def _turn_widths(self, start: np.ndarray) -> float | np.ndarray:
        """The first passes' interval factor per DOF (D,) while the body turns: the heading's is
        ``turn_widen`` when the last ``turn_frames`` frames each moved it by ``turn_trigger`` of its
        interval or more the same way (the last: from the estimate before, ``_before``, to
        ``start``), the others 1; else 1.0. Counts the frames (``_turning``).

        The heading interval is narrow so that the pelvis does not turn to mimic the legs'
        scissoring; a pivot turns faster than it reaches, the heading falls behind and the legs
        are placed from the wrong side (docs/tuning_history.md, ``turn_widen``)."""
        cfg = self.config.factored_ipf
        if cfg.turn_widen is None or self._before is None:
            return 1.0
        k = self._heading
        moved = float(np.angle(np.exp(1j * (start[k] - self._before[k]))))
        way = int(np.sign(moved)) if abs(moved) >= cfg.turn_trigger * self.half_width[k] else 0
        self._turning = self._turning + way if way and np.sign(self._turning) == way else way
        if abs(self._turning) < cfg.turn_frames:
            return 1.0
        widths = np.ones(self.model.n_dofs)
        widths[k] = cfg.turn_widen
        return widths

    def _recover(self, obs: Observation, start: np.ndarray, best: Estimate, turn: float | np.ndarray = 1.0) -> Estimate:
        """A first pass that still fits ``swap_fit_drop`` below the recent frames after the mirrored
        hypothesis: search the whole chain again from the previous estimate and (with
        ``swap_hypothesis``) from its mirror, on intervals widened by ``recover_widen`` (a limb left
        behind in a fast swing, a pelvis turned too far, are out of reach of the usual intervals
        and pull the fit down for many frames); the best first pass is kept."""
        cfg = self.config.factored_ipf
        evaluations = best.evaluations
        for q0 in (start, self.mirrored(start))[: 2 if cfg.swap_hypothesis else 1]:
            other, _ = self._search(obs, q0, cfg.recover_widen * turn, 0, 1)
            evaluations += other.evaluations
            best = other if other.fit > best.fit else best
        best.evaluations = evaluations
        return best

    def _fit_dropped(self, fit: float) -> bool:
        """Whether a first pass's fit is ``swap_fit_drop`` below the median of the recent frames'
        (known after 3 frames at least)."""
        drop = self.config.factored_ipf.swap_fit_drop
        return drop is not None and len(self._fits) >= 3 and fit < float(np.median(self._fits)) - drop

    def _legs_close(self, q: np.ndarray) -> bool:
        """Whether the legs are near enough to each other to be confused: their hip flexions differ
        by less than ``swap_within_deg``."""
        left, right = self._hip_flex
        return bool(abs(q[left] - q[right]) < np.radians(self.config.factored_ipf.swap_within_deg))

    def _search(self, obs: Observation, start: np.ndarray, widen: float | np.ndarray, first: int, stop: int,
                from_node: int = 0, variance: np.ndarray | None = None) -> tuple[Estimate, list[np.ndarray]]:  # fmt: skip
        """Passes ``first`` to ``stop - 1`` of the factored search from ``start``
        (``widen`` > 1 enlarges every interval; an array (D,): each DOF's own factor).

        ``from_node`` > 0 (a first pass only) walks the chain from that position of the order: the
        nodes before it stay at ``start``, drawn into the placed masks, with their points' spread
        given in ``variance`` (P,). Also returns each node's contribution (P,) to the points'
        variance in the last pass, in the order walked.

        The first pass walks the chain with Img_n = the silhouette minus the segments placed so
        far; each further pass (``passes``) revisits every node with Img_n = the silhouette minus
        all the other segments at their current estimates, with the finer layers only.
        """
        model, cfg = self.model, self.config.factored_ipf
        assert from_node == 0 or (first == 0 and stop == 1)
        q = start.copy()
        prior = np.zeros(model.n_points) if variance is None else variance
        evaluations = 0
        for p in range(first, stop):
            layers = cfg.layers if p == 0 else cfg.layers[-1:]
            variance = prior.copy()
            spreads = []
            if p == 0:  # Img_n: the segments placed so far (those before from_node at the start)
                placed, into = self._scratch(obs)
                for s in self.order[:from_node]:
                    self._draw(q, self.subtrees[s].own_capsules, placed)
                free = self.likelihood.free_prefixes(obs, placed, into)
            for s in self.order[from_node:]:
                sub = self.subtrees[s]
                n = cfg.root_particles if model.segments[s].parent < 0 else cfg.particles
                if p > 0:
                    placed, into = self._scratch(obs)
                    self._draw(q, self._outside[s], placed)  # all segments outside s's subtree
                    free = FreeRows(obs, placed, into)  # the rows the node's particles reach
                alone = p > 0 and s == self._root and cfg.root_refine == "alone"
                q, logw, Q = self._node(obs, q, self._explored[s], sub, free, n, widen, layers, alone)
                evaluations += n * len(layers)
                spread = np.zeros(model.n_points)
                if self.uncertainty:  # the spread of the particles' subtree points (N, P_sub, 3)
                    pts = self.projector.points(Q, sub.points)
                    spread[sub.points] = weighted_spread(pts, normalise_log_weights(logw))
                spreads.append(spread)
                variance += spread
                if p == 0:  # Img_n+1: the segment placed, the free pixels' sums updated on its rows
                    self.likelihood.refresh_free(obs, placed, free, self._draw(q, sub.own_capsules, placed))
        ll, fit = self.full_fit(obs, q)
        points = self.projector.points(q[None])[0]
        uncertainty = np.sqrt(variance) if self.uncertainty else np.full(model.n_points, np.nan)
        return (Estimate(q=q, points=points, uncertainty=uncertainty, log_likelihood=ll, fit=fit,
                         evaluations=evaluations), spreads)  # fmt: skip

    def _node(self, obs, q, idx: np.ndarray, sub, free, n: int, widen: float | np.ndarray, layers,
              alone: bool = False):  # fmt: skip
        """Diffuse, weight, resample and keep the best for one node. Returns the new estimate,
        the last layer's log-weights (N,) and particles (N, D). ``alone`` (the
        root only): the segments attached to the root keep their world orientation."""
        model = self.model
        X = np.repeat(q[None, idx], n, axis=0)
        template = model.clip(q[None])[0]  # the DOF outside idx, as every layer's clip leaves them
        prior_dofs = np.union1d(idx, self._held) if alone else idx
        gap = self.needs_leg_gap(prior_dofs)
        logw = np.zeros(n)
        best_x, best_ll = q[idx].copy(), -np.inf
        best_held = q[self._held].copy()
        wrap, lower, upper = model.wrap[idx], model.lower[idx], model.upper[idx]  # for layer_poses' clip
        areas = np.maximum(obs.areas, 1.0)
        for li, layer in enumerate(layers):
            W = normalise_log_weights(logw)
            if li > 0 or ess(W) < self.config.factored_ipf.ess_threshold * n:
                X = X[systematic(W, n, self.rng)]
            K, step = self.grid_steps(n, idx, layer, widen[idx] if isinstance(widen, np.ndarray) else widen)
            X, Q = layer_poses(X, K, step, best_x, idx, wrap, lower, upper, template)  # the best so far competes
            if alone:
                Q[:, self._held] = self._held_angles(q, Q)
            if gap:  # the capsules and the legs' gap from one pass of the kinematics
                proj, legs = self.projector.capsules_and_points(Q, sub.capsules, self.leg_points)
            else:
                proj, legs = self.projector.capsules(Q, sub.capsules), self._no_legs
            I, M = self.likelihood.terms(obs, proj, free.cover(proj) if isinstance(free, FreeRows) else free)
            logw = layer_log_weights(I, M, areas, self.likelihood.beta, Q, prior_dofs, self.prior_sigma, legs,
                                     self._gap_min, self._gap_sigma)  # fmt: skip
            i = int(np.argmax(logw))
            if logw[i] > best_ll:
                best_ll, best_x, best_held = float(logw[i]), X[i].copy(), Q[i, self._held].copy()
        q = q.copy()
        q[idx] = best_x
        if alone:
            q[self._held] = best_held
        return q, logw, Q

    def _held_angles(self, q: np.ndarray, Q: np.ndarray) -> np.ndarray:
        """Joint angles (N, len(_held)) for the root taking the pose of Q (N, D) while what it carries
        stays put (within the joint limits).

        The root's children keep their world orientation under pose q. An anchored child
        (``root_anchored``, a thigh) is turned instead by the smallest rotation A that aims it from
        its new joint at its child's joint as placed under q (the knee stays, the hip moves):
        A u = u' with u, u' the old and new unit directions joint -> child joint,

            A = I + [v]x + [v]x^2 / (1 + u.u'),  v = u x u'

        and its child (a shank) keeps its world orientation as closely as its DOF allow (one
        rotation: the angle of R_c'^T R_g about its axis, R_c', R_g the child's new and the
        grandchild's old world rotations)."""
        model = self.model
        root = model.segments[self._root]
        R_now, o_now = model.segment_frame(root, q[None, root.dofs], None, None)
        R_new, o_new = model.segment_frame(root, Q[:, root.dofs], None, None)
        out = Q.copy()
        for c in model.children(self._root):
            seg = model.segments[c]
            world = R_now[0] @ model.local_rotation(seg, q[None, seg.dofs])[0]
            if c in self._anchors:
                g = model.segments[self._anchors[c]]
                u = world @ g.origin  # (3,) joint -> child joint, world
                far = o_now[0] + R_now[0] @ seg.origin + u
                u_new = far - (o_new + R_new @ seg.origin)  # (N, 3)
                A = _aligning_rotations(u / np.linalg.norm(u), u_new / np.linalg.norm(u_new, axis=1, keepdims=True))
                turned = A @ world  # (N, 3, 3)
                below = world @ model.local_rotation(g, q[None, g.dofs])[0]
                kept = np.swapaxes(turned, 1, 2) @ below  # the child's old world orientation, local
                out[:, g.dofs] = model.local_angles(g, kept) if g.n_dofs == 3 else model.nearest_angle(g, kept)[:, None]
                out[:, seg.dofs] = model.local_angles(seg, np.swapaxes(R_new, 1, 2) @ turned)
            else:
                out[:, seg.dofs] = model.local_angles(seg, np.swapaxes(R_new, 1, 2) @ world)
        return model.clip(out[:, self._held], self._held)

    def _scratch(self, obs: Observation) -> tuple[list[np.ndarray], tuple[np.ndarray, np.ndarray] | None]:
        """Zeroed placed masks (one per view, as the silhouettes) and two (C, h, w + 1) arrays for the
        free pixels' prefix sums (None: views of different sizes), the same arrays from node to node
        and from search to search: new arrays of this size cost more in page faults than the work
        written into them. Valid until the next call."""
        sizes = tuple((m.shape, m.dtype.str) for m in obs.silhouettes)
        if self._buffers is None or self._buffers[0] != sizes:
            placed = [np.zeros_like(m) for m in obs.silhouettes]
            (h, w), C = obs.silhouettes[0].shape, len(placed)
            into = (np.empty((C, h, w + 1)), np.empty((C, h, w + 1))) if len({m.shape for m in placed}) == 1 else None
            self._buffers = (sizes, placed, into)
        _, placed, into = self._buffers
        for m in placed:
            m.fill(0)
        return placed, into

    def _draw(self, q: np.ndarray, caps: np.ndarray, masks: list[np.ndarray]) -> list[tuple[int, int]]:
        """Fill capsules ``caps`` at pose q into every view's mask; returns, per view, the first and
        last rows that may have changed."""
        if len(caps) == 0:
            return [(1, 0)] * len(masks)
        proj = self.projector.capsules(q[None], caps)
        return [self.likelihood.fill(c, proj, m) for c, m in enumerate(masks)]


def _aligning_rotations(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Smallest rotations taking the unit vector u (3,) onto each unit vector v (N, 3): (N, 3, 3)
    (Rodrigues; u and v are never opposite here, a root moves by centimetres)."""
    w = np.cross(u, v)  # (N, 3)
    K = np.zeros((len(v), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    K -= np.swapaxes(K, 1, 2)
    return np.eye(3) + K + (K @ K) / (1.0 + v @ u)[:, None, None]

