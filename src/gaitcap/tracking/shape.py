"""Subject shape calibration: the body model's proportions fitted to the silhouettes of the first
frames, before tracking. No clicks, no static trial.

The shipped proportions (``body.yaml``: population means scaled by height) miss a particular
subject by 5-25 % per segment (the thigh, the pelvis width, the ankle height), and a limb of the
wrong length can only be fitted by a wrong pose: on the synthetic walks, tracking with the true
proportions halves the lower-limb error. So, once the subject is found:

1. the first ``frames`` frames are tracked with the current proportions (poses x_k);
2. coordinate search over a few shape parameters p_j (each scales named segment axes together,
   left and right alike, by p_j or a power of it: ``tracking.config.parse_target``): for p_j in
   {p_j (1 - δ), p_j, p_j (1 + δ)} the poses of ``samples`` frames spread over the window are
   re-fitted (one factored pass from x_k, the same random stream for every candidate so that
   they are compared on equal terms) and scored by
       F(p) = sum_k fit_k(p)        (fit = 1 - |M xor S| / |S|, mean over the cameras);
   the best candidate is kept with its re-fitted poses and, with ``max_moves`` > 1, the parameter
   keeps moving the same way while F improves (pattern search); δ shrinks from round to round.
   With ``planted``, each candidate is also re-fitted from the poses x_k moved vertically by
       Δz_k = min_z M(p_current, x_k) - min_z M(p, x_k)      (M: the model's capsules, z up)
   so that its lowest point (a sole) stays where it was, and the better of the two F counts: a
   longer leg then raises the hips instead of pushing the feet through the floor, a move the
   re-fit's root interval (a few cm) cannot make from x_k (a parameter that leaves the soles
   where they were, |Δz_k| <= 0.1 mm, is re-fitted once). With ``retrack``, every round but
   the first starts from the window tracked again with the shape found so far (x_k re-estimated
   from the first frame's pose: the re-fits' single pass cannot undo poses a wrong shape bent);
3. optionally (none by default), ``random_candidates`` random moves of every parameter at once,
   p_j exp(σ z_j), z_j ~ N(0, 1),
   each scored from the planted poses only; a candidate that scores better replaces the current
   shape and poses ((1+1) evolution strategy, fixed σ, its own seeded stream). F is not
   separable: on the OpenSim walk (tracker seed 0) the true shape scores 0.855-0.857 against
   the coordinate search's 0.845, but every partial step towards it (the trunk shortened alone,
   or with the head lengthened, or all parameters but the head) scores lower, 0.817-0.841;
   80 random moves of all parameters climb to 0.858, shortening the trunk and lengthening the
   head as in the truth. On the varied suite 10 such moves changed nothing measurable, so they
   are off by default (docs/tuning_history.md);
4. tracking restarts at the first frame with the calibrated model.

Each parameter stays within ``bounds`` of the shipped proportion.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack
from dataclasses import dataclass, field

import numpy as np

from gaitcap.body.model import BodyModel
from gaitcap.tracking.base import Tracker
from gaitcap.tracking.config import parse_target
from gaitcap.tracking.observation import Observation

log = logging.getLogger("gaitcap.tracking.shape")

#: a planted move smaller than this (metres) is not re-fitted again: the re-fit from the unmoved
#: poses stands for it (a trunk, head or arm parameter leaves the soles exactly where they were)
_PLANT_TOL_M = 1e-4

#: a re-fit's result: the mean fit over the scored frames and the re-fitted poses (D,)
_Scored = tuple[float, list[np.ndarray]]


@dataclass
class ShapeResult:
    """The calibrated model, the first frame's pose under it, and what changed."""

    model: BodyModel
    start: np.ndarray  # (D,) pose of the window's first frame under the calibrated model
    factors: dict[str, float] = field(default_factory=dict)  # parameter -> factor applied
    fit_before: float = float("nan")  # mean fit over the scored frames
    fit_after: float = float("nan")


def scaled_model(model: BodyModel, targets: dict[str, list[str]], factors: dict[str, float]) -> BodyModel:
    """``model`` with each shape parameter's segment axes (``targets``: name -> targets, as
    ``shape.parameters``) scaled by its factor (``factors``: name -> factor; names not given: 1)."""
    scales = {k: v.copy() for k, v in model.scales.items()}
    for name, f in factors.items():
        for target in targets[name]:
            seg, axis, power = parse_target(target, name)
            scales[seg][axis] *= f**power
    return model.with_proportions(scales, model.shifts)


def lowest_points(model: BodyModel, poses: np.ndarray) -> np.ndarray:
    """Height (world z, metres) of the lowest capsule surface point of each pose (N, D): (N,)."""
    A, B, radii = model.capsules(poses)
    return np.minimum((A[..., 2] - radii[:, 0]).min(axis=1), (B[..., 2] - radii[:, 1]).min(axis=1))


def planted_poses(current: BodyModel, candidate: BodyModel, poses: list[np.ndarray]) -> list[np.ndarray]:
    """Poses (D,) moved vertically (pelvis_tz, as :meth:`BodyModel.neutral_pose` places the soles)
    so that ``candidate``'s lowest point is at the height ``current``'s lowest point had in each pose."""
    Q = np.array(poses, dtype=np.float64)
    Q[:, candidate.dof_index("pelvis_tz")] += lowest_points(current, Q) - lowest_points(candidate, Q)
    return list(Q)


def calibrate_shape(
    model: BodyModel,
    make_tracker: Callable[[BodyModel], Tracker],
    observations: list[Observation],
    poses: list[np.ndarray],
    parameters: dict[str, list[str]],
    steps: list[float],
    bounds: tuple[float, float],
    samples: int,
    seed: int = 0,
    max_moves: int = 1,
    planted: bool = False,
    random_candidates: int = 0,
    random_sigma: float = 0.04,
    retrack: Callable[[BodyModel, np.ndarray], list[np.ndarray]] | None = None,
    workers: int = 1,
    worker_setup: Callable[[], object] | None = None,
    limits: dict[str, tuple[float, float]] | None = None,
) -> ShapeResult:
    """Coordinate search, then random search, of the shape ``parameters`` (module docstring).

    ``observations`` and ``poses`` are the tracked calibration window (same length); ``make_tracker``
    builds the re-fitting tracker (a single factored pass) for a candidate model. ``retrack``
    (model, first frame's pose (D,)) -> the window's poses: called before every round of
    ``steps`` but the first, so that the round starts from poses tracked with the shape so far.
    ``limits``: a parameter's own (low, high) range, instead of ``bounds``.
    """
    span = {name: (limits or {}).get(name, bounds) for name in parameters}
    if len(observations) != len(poses) or not observations:
        raise ValueError("calibrate_shape needs one pose per observation")
    with ExitStack() as stack:
        pool = (stack.enter_context(ThreadPoolExecutor(workers, "gaitcap-shape", initializer=worker_setup))
                if workers > 1 else None)  # fmt: skip
        pick = np.unique(np.linspace(0, len(observations) - 1, min(samples, len(observations))).round().astype(int))
        obs = [observations[i] for i in pick]

        def refit(candidate: BodyModel, start: list[np.ndarray]) -> _Scored:
            tracker = make_tracker(candidate)
            tracker.rng = np.random.default_rng(seed)  # paired comparison: one random stream
            fits, out = [], []
            for o, q in zip(obs, start):
                tracker.start(q)
                est = tracker.step(o)
                fits.append(est.fit)
                out.append(est.q)
            return float(np.mean(fits)), out

        factors = {name: 1.0 for name in parameters}
        current = [poses[i] for i in pick]
        best_fit, current = refit(model, current)
        fit_before = best_fit

        def refits_of(trial: dict[str, float], both: bool = True) -> list[tuple[BodyModel, list[np.ndarray]]] | None:
            """The re-fits (candidate model, start poses) that score the parameters at ``trial``; None
            out of bounds. With ``planted`` and ``both``, from the unmoved and from the planted poses
            (the better counts); without ``both``, from the planted poses only."""
            if not all(span[k][0] <= f <= span[k][1] for k, f in trial.items()):
                return None
            candidate = scaled_model(model, parameters, trial)
            if not planted:
                return [(candidate, current)]
            moved = planted_poses(scaled_model(model, parameters, factors), candidate, current)
            if np.max(np.abs(np.array(moved) - np.array(current))) <= _PLANT_TOL_M:
                return [(candidate, current)]  # the lowest point does not move (trunk, arms): one re-fit
            return [(candidate, current), (candidate, moved)] if both else [(candidate, moved)]

        def score_all(trials: list[dict[str, float]], both: bool = True) -> list[_Scored | None]:
            """Mean fit and re-fitted poses of each trial (None: out of bounds), every re-fit of every
            trial run side by side on ``pool``; of a trial's two re-fits the planted one counts only
            when it fits strictly better."""
            plans = [refits_of(t, both) for t in trials]
            jobs = [job for plan in plans if plan for job in plan]
            done = iter(list((pool.map if pool else map)(lambda job: refit(*job), jobs)))
            # max keeps the first of equal fits: the planted re-fit (second) must be strictly better
            return [max((next(done) for _ in plan), key=lambda r: r[0]) if plan else None for plan in plans]

        for round_index, delta in enumerate(steps):
            if round_index > 0 and retrack is not None:  # poses tracked with the shape found so far
                now = scaled_model(model, parameters, factors)
                window = retrack(now, current[0])
                best_fit, current = refit(now, [window[i] for i in pick])
            for name in parameters:
                trial_best = None  # (fit, factor, direction, poses) of the better improving neighbour
                steps_to = {direction: factors[name] * (1 + direction * delta) for direction in (-1, 1)}
                tried_both = score_all([{**factors, name: f} for f in steps_to.values()])
                for (direction, f), tried in zip(steps_to.items(), tried_both):
                    if tried is not None and tried[0] > best_fit and (trial_best is None or tried[0] > trial_best[0]):
                        trial_best = (tried[0], f, direction, tried[1])
                if trial_best is None:
                    continue
                best_fit, factors[name], direction, current = trial_best
                for _ in range(max_moves - 1):  # pattern search: keep going while the fit improves
                    f = factors[name] * (1 + direction * delta)
                    tried = score_all([{**factors, name: f}])[0]
                    if tried is None or tried[0] <= best_fit:
                        break
                    (best_fit, current), factors[name] = tried, f
                log.debug("shape: %s x%.3f (fit %.4f)", name, factors[name], best_fit)
        rng = np.random.default_rng([seed, 1])  # its own stream: the re-fits keep theirs
        draws = [[rng.standard_normal() for _ in factors] for _ in range(random_candidates)]
        i = 0
        while i < len(draws):  # (1+1) evolution strategy, ``workers`` candidates scored side by side: those
            # after an accepted one moved from the shape it replaced, so they are scored again from the new
            # one (the same draws): the result is that of one candidate after the other
            trials = [{k: float(np.clip(f * np.exp(random_sigma * z), *span[k]))
                       for (k, f), z in zip(factors.items(), zs)} for zs in draws[i : i + workers]]  # fmt: skip
            scored = score_all(trials, both=False)  # every parameter moves: the soles stay on the floor
            for trial, tried in zip(trials, scored):
                i += 1
                if tried is not None and tried[0] > best_fit:
                    (best_fit, current), factors = tried, trial
                    log.debug("shape: random move (fit %.4f)", best_fit)
                    break
        return ShapeResult(model=scaled_model(model, parameters, factors), start=current[0], factors=factors,
                           fit_before=fit_before, fit_after=best_fit)


def average_shapes(model: BodyModel, parameters: dict[str, list[str]], results: list[ShapeResult]) -> ShapeResult:
    """The geometric mean of several calibrations' factors; the first one's start, moved vertically
    so that the averaged model's lowest point stays where the first model's was."""
    factors = {k: float(np.exp(np.mean([np.log(r.factors[k]) for r in results]))) for k in results[0].factors}
    averaged = scaled_model(model, parameters, factors)
    start = planted_poses(results[0].model, averaged, [results[0].start])[0]
    return ShapeResult(model=averaged, start=start, factors=factors,
                       fit_before=float(np.mean([r.fit_before for r in results])),
                       fit_after=float(np.mean([r.fit_after for r in results])))
