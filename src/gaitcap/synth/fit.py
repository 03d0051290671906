"""Fit the body model to marker-derived joint centres: the synthetic subject and its true poses.

1. Subject proportions: per-segment scales from the median distances between joint centres over
   the trial (thigh = hip-knee, shank = knee-ankle, hip width, foot heel/toe geometry, arms, trunk).
2. Poses: per frame, bounded least squares (scipy ``least_squares``, joint limits as bounds) of
   the model's points against the observed joint centres, warm-started from the previous frame,
   with a weak pull towards it so that poorly observed DOF (hip rotation with a straight knee)
   stay continuous. DOF that move no observed point (the upper body of a lower-body marker set)
   are set from a plausible walking prior (arms swinging against the legs).

The fitted model's points are the ground truth: bone lengths are constant by construction, and the
residual to the marker-derived joint centres is reported.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from gaitcap.body.model import BodyModel
from gaitcap.body.spec import BodySpec
from gaitcap.errors import InputError
from gaitcap.trajectory import Trajectory

log = logging.getLogger("gaitcap.synth.fit")

#: weight of each observed point in the fit (joint centres are better defined than landmarks)
POINT_WEIGHTS = {"heel_l": 0.7, "heel_r": 0.7, "toe_l": 0.7, "toe_r": 0.7, "thorax": 0.3, "neck": 0.3,
                 "head": 0.3, "shoulder_l": 0.3, "shoulder_r": 0.3, "elbow_l": 0.5, "elbow_r": 0.5}  # fmt: skip
SMOOTHNESS = 0.02  # metres of residual per radian (or metre) of change from the previous frame
#: pull towards the neutral pose (metres per radian). Joint centres alone leave some combinations
#: unobservable: pelvis tilt trades against both hip flexions (the hip centres lie on the tilt
#: axis) and against lumbar flexion; the pull resolves them towards an upright pelvis and trunk.
NEUTRAL_PULL = {"pelvis_tilt": 0.08, "pelvis_obliquity": 0.02, "lumbar_flexion": 0.02, "lumbar_bending": 0.02,
                "lumbar_rotation": 0.02}  # fmt: skip
NEUTRAL_PULL_DEFAULT = 0.003
REQUIRED = ("hip_l", "hip_r", "knee_l", "knee_r", "ankle_l", "ankle_r")


@dataclass(frozen=True)
class FitResult:
    model: BodyModel  # scaled to the subject
    poses: np.ndarray  # (T, D)
    points: np.ndarray  # (T, P, 3) model points (the ground truth)
    residual_m: dict[str, float]  # mean distance model - observed, per observed point


def _median_distance(traj: Trajectory, a: str, b: str) -> float | None:
    if not (traj.has(a) and traj.has(b)):
        return None
    d = np.linalg.norm(traj.point(a) - traj.point(b), axis=1)
    d = d[np.isfinite(d)]
    return float(np.median(d)) if d.size else None


#: a stated height more than this fraction from the legs' estimate is warned about (the legs' own spread
#: between people is a few per cent)
HEIGHT_TOLERANCE = 0.15


def estimate_height(traj: Trajectory) -> float:
    """Subject height: from the file's metadata (or synth --height), else from leg length (thigh + shank
    = 0.491 H, Winter); a stated height :data:`HEIGHT_TOLERANCE` or more from the legs' is warned about."""
    legs_height = _legs_height(traj)
    if traj.meta.get("height_m"):
        stated = float(traj.meta["height_m"])
        if legs_height is not None and abs(stated / legs_height - 1.0) > HEIGHT_TOLERANCE:
            log.warning("%s: the subject's height %.2f m (the file's, or --height) is %+.0f %% from the %.2f m its "
                        "legs show (thigh + shank = 0.491 H): the truth and session.yaml state %.2f m",
                        traj.meta.get("source", "motion"), stated, 100 * (stated / legs_height - 1), legs_height,
                        stated)  # fmt: skip
        return stated
    if legs_height is None:
        raise InputError(f"{traj.meta.get('source', 'motion')}: cannot estimate the subject's height (no leg joint centres)")
    log.info("subject height not in the file: estimated %.3f m from leg length", legs_height)
    return legs_height


def _legs_height(traj: Trajectory) -> float | None:
    """The height the legs' joint centres give (thigh + shank = 0.491 H), or None without them."""
    legs = [
        (_median_distance(traj, f"hip{s}", f"knee{s}") or np.nan) + (_median_distance(traj, f"knee{s}", f"ankle{s}") or np.nan)
        for s in ("_l", "_r")
    ]
    if not np.isfinite(legs).any():
        return None
    return float(np.nanmean(legs) / 0.491)


def estimate_scales(base: BodyModel, traj: Trajectory) -> dict[str, tuple[float, float, float]]:
    """Per-segment scale factors fitting ``base`` (already at the subject's height) to ``traj``."""
    scales: dict[str, list[float]] = {s.name: [1.0, 1.0, 1.0] for s in base.segments}

    def length_ratio(a: str, b: str, model_len: float) -> float | None:
        d = _median_distance(traj, a, b)
        return None if d is None or model_len <= 0 else d / model_len

    def set_axis(seg: str, axis: int, ratio: float | None) -> None:
        if ratio is not None and 0.6 < ratio < 1.6:
            scales[seg][axis] = ratio

    for s in ("_l", "_r"):
        set_axis(f"thigh{s}", 2, length_ratio(f"hip{s}", f"knee{s}", np.linalg.norm(base.segment(f"shank{s}").origin)))
        set_axis(f"shank{s}", 2, length_ratio(f"knee{s}", f"ankle{s}", np.linalg.norm(base.segment(f"foot{s}").origin)))
        set_axis(f"upper_arm{s}", 2, length_ratio(f"shoulder{s}", f"elbow{s}", np.linalg.norm(base.segment(f"forearm{s}").origin)))
        wrist = base.point_local[base.point_index(f"wrist{s}")]
        set_axis(f"forearm{s}", 2, length_ratio(f"elbow{s}", f"wrist{s}", np.linalg.norm(wrist)))
        foot = _foot_scales(base, traj, s)
        if foot is not None:
            scales[f"foot{s}"][0], scales[f"foot{s}"][2] = foot
    hip_half = abs(base.segment("thigh_l").origin[1])
    set_axis("pelvis", 1, length_ratio("hip_l", "hip_r", 2 * hip_half))
    set_axis("pelvis", 2, length_ratio("pelvis", "thorax", np.linalg.norm(base.segment("torso").origin)))
    set_axis("torso", 2, length_ratio("thorax", "neck", np.linalg.norm(base.segment("head").origin)))
    shoulder_half = abs(base.segment("upper_arm_l").origin[1])
    set_axis("torso", 1, length_ratio("shoulder_l", "shoulder_r", 2 * shoulder_half))
    head_local = base.point_local[base.point_index("head")]
    set_axis("head", 2, length_ratio("neck", "head", np.linalg.norm(head_local)))
    return {k: (v[0], v[1], v[2]) for k, v in scales.items()}


def _foot_scales(base: BodyModel, traj: Trajectory, s: str) -> tuple[float, float] | None:
    """(sx, sz) of the foot from the ankle-heel and ankle-toe distances: solves for sx^2, sz^2."""
    dh = _median_distance(traj, f"ankle{s}", f"heel{s}")
    dt = _median_distance(traj, f"ankle{s}", f"toe{s}")
    if dh is None or dt is None:
        return None
    h = base.point_local[base.point_index(f"heel{s}")]
    t = base.point_local[base.point_index(f"toe{s}")]
    A = np.array([[h[0] ** 2, h[2] ** 2], [t[0] ** 2, t[2] ** 2]])
    try:
        a, b = np.linalg.solve(A, [dh**2, dt**2])
    except np.linalg.LinAlgError:
        return None
    if a <= 0 or b <= 0:
        return None
    sx, sz = float(np.sqrt(a)), float(np.sqrt(b))
    return (sx, sz) if 0.6 < sx < 1.6 and 0.6 < sz < 2.2 else None


def _foot_affine(
    model: BodyModel, poses: np.ndarray, traj: Trajectory, s: str
) -> tuple[tuple[float, float, float], tuple[float, float, float]] | None:
    """Foot scale and shift mapping the model's heel/toe onto the observed ones in the foot frame.

    From a first fit: the median position of the observed heel and toe in the fitted foot frame
    gives x' = sx x + dx along the foot (two points, exact) and z' = sz z (both landmarks lie at
    the sole, so their mean height sets sz).
    """
    names = (f"heel{s}", f"toe{s}")
    if not all(traj.has(n) for n in names):
        return None
    seg = model.segment(f"foot{s}")
    R, o = model.frames(poses)
    local = []
    for n in names:
        d = traj.point(n) - o[:, seg.index]
        loc = np.einsum("tji,tj->ti", R[:, seg.index], d)
        local.append(np.nanmedian(loc, axis=0))
    spec_pts = [np.asarray(model.spec.segments[seg.name].points[n]) * model.height_m for n in names]
    (xh, zh), (xt, zt) = ((p[0], p[2]) for p in spec_pts)
    if abs(xt - xh) < 1e-6 or abs(zh + zt) < 1e-6:
        return None
    sx = (local[1][0] - local[0][0]) / (xt - xh)
    dx = local[1][0] - sx * xt
    sz = (local[0][2] + local[1][2]) / (zh + zt)
    if not (0.6 < sx < 1.8 and 0.6 < sz < 2.5) or not np.all(np.isfinite([sx, dx, sz])):
        log.debug("foot%s affine out of range (sx %.2f, sz %.2f): kept the distance-based scales", s, sx, sz)
        return None
    return (float(sx), 1.0, float(sz)), (float(dx), 0.0, 0.0)


def _free_dofs(model: BodyModel, observed: list[str]) -> np.ndarray:
    """Boolean (D,): the DOF that move at least one observed point."""
    moves = np.zeros(model.n_dofs, bool)
    for name in observed:
        seg = model.segments[model.point_segment[model.point_index(name)]]
        while True:
            moves[seg.dofs] = True
            if seg.parent < 0:
                break
            seg = model.segments[seg.parent]
    return moves


def _initial_pose(model: BodyModel, traj: Trajectory, frame: int) -> np.ndarray:
    left = traj.point("hip_l")[frame] - traj.point("hip_r")[frame]
    fwd = np.cross(left, [0.0, 0.0, 1.0])
    heading = float(np.arctan2(fwd[1], fwd[0]))
    pelvis = 0.5 * (traj.point("hip_l")[frame] + traj.point("hip_r")[frame])
    q = model.neutral_pose(heading_rad=heading, x=pelvis[0], y=pelvis[1])
    q[model.dof_index("pelvis_tz")] = pelvis[2]
    return q


def fit_poses(model: BodyModel, traj: Trajectory) -> tuple[np.ndarray, dict[str, float]]:
    """Per-frame bounded least-squares fit. Returns poses (T, D) and the mean residual per point (m)."""
    observed = [n for n in traj.names if n in model.point_names]
    missing = [n for n in REQUIRED if n not in observed]
    if missing:
        raise InputError(f"{traj.meta.get('source', 'motion')}: joint centres missing for the fit: {', '.join(missing)}")
    obs_idx = np.array([model.point_index(n) for n in observed])
    data = traj.subset(observed).points  # (T, K, 3)
    weights = np.array([POINT_WEIGHTS.get(n, 1.0) for n in observed])
    free = _free_dofs(model, observed)
    free_idx = np.where(free)[0]
    lower, upper = model.lower[free_idx].copy(), model.upper[free_idx].copy()
    wrap = model.wrap[free_idx]
    lower[wrap], upper[wrap] = -np.inf, np.inf
    pull = np.array([0.0 if (model.wrap[i] or not model.is_rotation[i])
                     else NEUTRAL_PULL.get(model.dof_names[i], NEUTRAL_PULL_DEFAULT) for i in free_idx])

    T = traj.n_frames
    poses = np.zeros((T, model.n_dofs))
    first = next((t for t in range(T) if np.all(np.isfinite(data[t, :6]))), None)
    if first is None:
        raise InputError(f"{traj.meta.get('source', 'motion')}: no frame with all hip, knee and ankle centres")
    q_prev = _initial_pose(model, traj, first)
    errors = np.full((T, len(observed)), np.nan)
    for t in list(range(first, T)) + list(range(first - 1, -1, -1)):
        if t == first - 1:
            q_prev = poses[first].copy()
        x = data[t]
        ok = np.all(np.isfinite(x), axis=1)
        if ok.sum() < 4:
            poses[t] = q_prev
            continue
        q_full = q_prev.copy()

        def residuals(z: np.ndarray) -> np.ndarray:
            return _residual_batch(z[None])[0]

        def _residual_batch(Z: np.ndarray) -> np.ndarray:
            Q = np.repeat(q_full[None], len(Z), axis=0)
            Q[:, free_idx] = Z
            pts = model.forward(Q)[:, obs_idx]  # (B, K, 3)
            r = ((pts - x) * weights[:, None])[:, ok].reshape(len(Z), -1)
            return np.concatenate([r, SMOOTHNESS * (Z - q_prev[free_idx]), pull * Z], axis=1)

        def jacobian(z: np.ndarray) -> np.ndarray:
            h = 1e-6
            Z = np.repeat(z[None], len(z) + 1, axis=0)
            Z[1:] += np.eye(len(z)) * h
            R = _residual_batch(Z)
            return ((R[1:] - R[0]) / h).T

        z0 = np.clip(q_prev[free_idx], lower + 1e-9, upper - 1e-9)
        sol = least_squares(residuals, z0, jac=jacobian, bounds=(lower, upper), method="trf", xtol=1e-10, ftol=1e-10, max_nfev=200)
        q = q_prev.copy()
        q[free_idx] = sol.x
        poses[t] = q
        q_prev = q
        errors[t, ok] = np.linalg.norm(model.forward(q[None])[0, obs_idx] - x, axis=1)[ok]
    residual = {n: float(np.nanmean(errors[:, i])) for i, n in enumerate(observed)}
    return poses, residual


def walking_prior(model: BodyModel, poses: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Fill DOF that no observation constrains with a plausible walking pattern.

    Arms swing against the same-side leg (shoulder flexion = -0.8 x centred hip flexion), slightly
    abducted, elbows flexed 15-35 degrees; trunk upright, head level.
    """
    out = poses.copy()
    deg = np.pi / 180
    for s in ("_l", "_r"):
        hip = poses[:, model.dof_index(f"hip_flexion{s}")]
        swing = -0.8 * (hip - np.mean(hip))
        prior = {
            f"shoulder_flexion{s}": swing,
            f"shoulder_abduction{s}": np.full(len(poses), 8 * deg),
            f"shoulder_rotation{s}": np.zeros(len(poses)),
            f"elbow_flexion{s}": 20 * deg + 0.6 * np.clip(swing, 0, None),
        }
        for name, values in prior.items():
            i = model.dof_index(name)
            if not free[i]:
                out[:, i] = values
    for name, value in (("lumbar_flexion", 3 * deg), ("lumbar_bending", 0.0), ("lumbar_rotation", 0.0),
                        ("neck_flexion", 5 * deg), ("neck_bending", 0.0)):
        i = model.dof_index(name)
        if not free[i]:
            out[:, i] = value
    return out


def fit_body(spec: BodySpec, traj: Trajectory, height_m: float | None = None) -> FitResult:
    """Scale the body model to the subject of ``traj`` and fit its poses (see the module docstring)."""
    height = height_m or estimate_height(traj)
    base = BodyModel(spec, height_m=height)
    scales = estimate_scales(base, traj)
    model = base.with_proportions(scales)
    poses, residual = fit_poses(model, traj)
    feet = {s: _foot_affine(model, poses, traj, s) for s in ("_l", "_r")}
    if any(v is not None for v in feet.values()):
        scales = dict(scales)
        shifts: dict[str, tuple[float, float, float]] = {}
        for s, affine in feet.items():
            if affine is not None:
                scales[f"foot{s}"], shifts[f"foot{s}"] = affine
        model = base.with_proportions(scales, shifts)
        poses, residual = fit_poses(model, traj)
    observed = [n for n in traj.names if n in model.point_names]
    poses = walking_prior(model, poses, _free_dofs(model, observed))
    poses = model.clip(poses)
    return FitResult(model=model, poses=poses, points=model.forward(poses), residual_m=residual)
