"""What every tracker shares: the model, the likelihood, the search intervals, the estimate."""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from gaitcap.body.model import BodyModel
from gaitcap.tracking.config import Layer, TrackingConfig
from gaitcap.tracking.contact import LEG_POINTS, leg_gap
from gaitcap.tracking.likelihood import SilhouetteLikelihood
from gaitcap.tracking.observation import Observation
from gaitcap.tracking.projector import PoseProjector


@dataclass
class Estimate:
    """One frame's result."""

    q: np.ndarray  # (D,) pose
    points: np.ndarray  # (P, 3) metres
    uncertainty: np.ndarray  # (P,) metres: spread of the weighted particles
    log_likelihood: float
    fit: float  # 1 - xor/|S|, mean over cameras
    evaluations: int  # particles scored this frame


@dataclass(frozen=True)
class Track:
    """Frames tracked once from a settled start (:func:`gaitcap.tracking.init.settle_legs`): the
    start (D,) as the tracker holds it, and per frame its observation, its estimate and the
    tracker's state after it (:meth:`Tracker.snapshot`)."""

    start: np.ndarray
    observations: tuple[Observation, ...]
    estimates: tuple[Estimate, ...]
    states: tuple[dict[str, Any], ...]


def weighted_spread(points: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Per-point variance (sum over x, y, z) of weighted samples: points (N, P, 3), W (N,) -> (P,)."""
    mean = np.einsum("n,npi->pi", W, points)
    d = points - mean
    return np.einsum("n,npi->p", W, d * d)


class Tracker:
    """Base class: holds the estimate of the previous frame (there is no dynamic model)."""

    name = "tracker"
    #: what a step reads and changes besides the random stream (:meth:`snapshot`)
    STATE: tuple[str, ...] = ("q",)

    def __init__(self, model: BodyModel, likelihood: SilhouetteLikelihood, config: TrackingConfig,
                 rng: np.random.Generator) -> None:  # fmt: skip
        self.model = model
        self.likelihood = likelihood
        self.config = config
        self.rng = rng
        self.half_width = config.half_widths(model)
        self.prior_sigma = config.prior_sigmas(model)
        self.projector = PoseProjector(model, likelihood.views)
        self.q = model.neutral_pose()
        names = model.dof_names
        legs = ("hip_", "knee_", "ankle_")
        #: the left legs' DOF and their right counterparts, index for index
        self.left_leg = np.array([i for i, n in enumerate(names) if n.endswith("_l") and n.startswith(legs)], int)
        self.right_leg = np.array([names.index(names[i][:-2] + "_r") for i in self.left_leg], int)
        #: the legs' gap prior (log_prior): the DOF that move a leg's axis (hips and knees: not the
        #: ankles, which turn the feet), its points, its floor and width (metres)
        self._moves_leg = np.array([n.startswith(("hip_", "knee_")) and n.endswith(("_l", "_r")) for n in names])
        self.leg_points = np.array([model.point_index(p) for p in LEG_POINTS], int)  #: LEG_POINTS' indices
        gap = config.leg_gap
        self._gap_min, self._gap_sigma = gap.min * model.height_m, gap.sigma * model.height_m
        self._grids: dict[tuple, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}  # grid_offsets' cache
        self._remembered: Track | None = None  # frames tracked once from a settled start (remember)
        self._replayed = 0  # how many of them the steps since that start have taken
        #: whether the last :meth:`step` took a remembered frame instead of searching it
        self.last_step_remembered = False

    def start(self, q0: np.ndarray, fresh: bool = True) -> None:
        """Set the previous estimate (after initialisation or recovery). ``fresh``: q0 is a guess
        whose leg assignment nothing has confirmed yet, so a tracker may weigh the other one on
        the next frame (factored IPF); False when it was chosen over several frames
        (:func:`gaitcap.tracking.init.settle_legs`). A start elsewhere, or fresh, forgets the
        frames :meth:`remember` kept."""
        self.q = self.model.clip(np.asarray(q0, float)[None])[0]
        self._replayed = 0
        if self._remembered is not None and (fresh or not np.array_equal(self._remembered.start, self.q)):
            self._remembered = None

    def snapshot(self) -> dict[str, Any]:
        """The tracker's state between two frames (copies of :attr:`STATE`), for :meth:`restore`."""
        return {k: copy.deepcopy(getattr(self, k)) for k in self.STATE if hasattr(self, k)}

    def restore(self, state: dict[str, Any]) -> None:
        """Put back a state :meth:`snapshot` took."""
        for k, v in state.items():
            setattr(self, k, copy.deepcopy(v))

    def remember(self, track: Track) -> None:
        """Keep frames already tracked from the settled start the tracker stands at (``track.start``;
        :func:`~gaitcap.tracking.init.settle_legs` picks that start by tracking them): the next steps
        on the same observations, from there, take those estimates and states instead of tracking
        the frames again. The first frames of a run are tracked that way three times otherwise
        (the facing and leg checks, the shape window, the run itself). The random stream goes on
        from where it is: the frames after them are a draw as good as the one they save."""
        self._remembered = track if np.array_equal(track.start, self.q) and track.observations else None
        self._replayed = 0

    def step(self, obs: Observation, widen: float = 1.0) -> Estimate:
        """Track one frame from the previous estimate (``widen`` > 1: wider search intervals), or take it
        as :meth:`remember` kept it when it is the next of those frames."""
        track, k = self._remembered, self._replayed
        if track is not None and widen == 1.0 and k < len(track.observations) and track.observations[k] is obs:
            self.restore(track.states[k])
            self._replayed = k + 1
            self._remembered = track if k + 1 < len(track.observations) else None
            self.last_step_remembered = True
            return replace(track.estimates[k])
        self._remembered = None
        self.last_step_remembered = False
        return self._step(obs, widen)

    def _step(self, obs: Observation, widen: float = 1.0) -> Estimate:
        raise NotImplementedError

    def mirrored(self, q: np.ndarray) -> np.ndarray:
        """Pose q (D,) with the left and right legs' angles exchanged."""
        out = np.array(q, float, copy=True)
        out[self.left_leg], out[self.right_leg] = q[self.right_leg], q[self.left_leg]
        return out

    def refine(self, obs: Observation, q: np.ndarray) -> Estimate:
        """Frame ``obs`` searched from pose q (D,) alone, as a pose chosen elsewhere (another pass, the
        legs exchanged) is checked against the silhouettes: no other hypothesis competes (a tracker
        with hypotheses, :class:`~gaitcap.tracking.factored_ipf.FactoredIPF`, leaves them out).
        The tracker is left started at the result (:meth:`start`, not fresh)."""
        self.start(q, fresh=False)
        est = self.step(obs)
        self.start(est.q, fresh=False)
        return est

    # ---------------------------------------------------------------- shared steps
    def grid_offsets(self, n: int, dofs: np.ndarray, layer: Layer, widen: float | np.ndarray = 1.0) -> np.ndarray:
        """IPF diffusion: offsets (n, len(dofs)) drawn on each DOF's discretised interval.

        The interval [-h, h] (h: the DOF's half-width x shrink x widen; ``widen`` one factor, or one
        per DOF of ``dofs``) is cut into steps of ``layer.step_deg`` (``step_m`` for translations);
        each offset is a whole number of steps.
        """
        k, step = self.grid_steps(n, dofs, layer, widen)
        return k * step

    def grid_steps(self, n: int, dofs: np.ndarray, layer: Layer,
                   widen: float | np.ndarray = 1.0) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """:meth:`grid_offsets` as whole numbers of steps (n, len(dofs)) int64 and the steps (len(dofs),)."""
        key = (np.asarray(dofs).dtype.str, np.asarray(dofs).tobytes(), layer.step_deg, layer.step_m, layer.shrink,
               np.asarray(widen, float).tobytes())  # fmt: skip
        if key not in self._grids:  # the grid of a node's DOF and layer, built once
            rot = self.model.is_rotation[dofs]
            step = np.where(rot, np.radians(layer.step_deg), layer.step_m)
            h = self.half_width[dofs] * layer.shrink * widen
            m = np.maximum(1, np.floor(h / step + 1e-9)).astype(int)
            self._grids[key] = (step, -m, m + 1)
        step, lo, hi = self._grids[key]
        return self.rng.integers(lo, hi, size=(n, len(step))), step

    def log_prior(self, Q: np.ndarray, dofs: np.ndarray | slice = slice(None), legs: np.ndarray | None = None) -> np.ndarray:
        """The posture prior over the DOF ``dofs`` of poses Q (N, D): shape (N,).

        log p(x) = -1/2 sum_d (x_d / sigma_d)^2 over the DOF with a prior (``prior`` in the YAML):
        the rotations a silhouette cannot see (the pelvis about its own capsule axis, the limbs
        about their long axes, the lumbar joint whose rotation the torso and pelvis trade off),
        centred on the anatomical neutral and wide enough that the image overrides it;
        plus, where ``dofs`` move a leg (:meth:`needs_leg_gap`), :meth:`log_leg_gap`. ``legs``: the
        poses' leg points (N, 6, 3) in :data:`~gaitcap.tracking.contact.LEG_POINTS` order when the
        caller has them (``projector.capsules_and_points`` with :attr:`leg_points`).
        """
        z = Q[:, dofs] / self.prior_sigma[dofs]
        out = -0.5 * np.add.reduce(z * z, axis=1)  # np.sum's reduction without its wrappers (called per layer)
        if self.needs_leg_gap(dofs):
            out += self.log_leg_gap(Q, legs)
        return out

    def needs_leg_gap(self, dofs: np.ndarray | slice = slice(None)) -> bool:
        """Whether :meth:`log_prior` over ``dofs`` includes the legs' gap: the prior is on and they move a
        leg's axis."""
        return bool(self._gap_min > 0 and self._moves_leg[dofs].any())

    def log_leg_gap(self, Q: np.ndarray, legs: np.ndarray | None = None) -> np.ndarray:
        """The legs' gap prior of poses Q (N, D): (N,). The legs cannot pass through each other:
        log p = -1/2 ((g_min - g) / sigma)^2 where the gap g between their axes
        (:func:`gaitcap.tracking.contact.leg_gap`) is below g_min, 0 above (``leg_gap`` in the YAML:
        g_min and sigma are fractions of the height). Without it, a leg the silhouettes lose is
        drawn over the other one, where it costs nothing. ``legs``: Q's leg points (N, 6, 3) if
        already computed."""
        if legs is None:
            legs = self.projector.points(Q, self.leg_points)
        short = np.maximum(self._gap_min - leg_gap(legs), 0.0) / self._gap_sigma
        return -0.5 * short * short

    def full_fit(self, obs: Observation, q: np.ndarray) -> tuple[float, float]:
        """(log-likelihood, fit) of one pose against the full silhouettes."""
        ll, fit = self.likelihood.evaluate(obs, self.projector.capsules(q[None]))
        return float(ll[0]), float(fit[0])
