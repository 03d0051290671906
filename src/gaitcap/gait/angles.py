"""Joint angles per frame from joint centres, with Plug-in-Gait-like conventions.

Segment frames (columns X, Y, Z of a rotation matrix, world coordinates), as in Plug-in-Gait:
X anterior, Y to the subject's left, Z proximal (up), for both sides.

- progression frame: X = walking direction (estimated), Y = left, Z = world up; turned round when
  the pelvis faces against the walking direction over the trial (a subject walking backwards), so
  that the pelvis angles stay about the way the subject faces (rotation near 0, not near 180
  degrees; tilt and obliquity with their usual signs).
- pelvis: Y = hip_r -> hip_l. When ASIS and PSIS markers are in the trajectory (``LASI/RASI/LPSI/
  RPSI``, ``LASI/RASI/SACR``, the CAST and OpenSim spellings of :data:`PELVIS_MARKER_SETS`, or
  ``asis_l/asis_r/psis_l/psis_r``), the Plug-in-Gait pelvis:
  Y = RASI -> LASI, X = mid-PSIS (or SACR) -> mid-ASIS made orthogonal to Y. From joint centres
  only, the pelvis tilt is not determined by the two hip centres: Z is taken along pelvis -> thorax when a thorax point exists
  (so "tilt" is then the forward inclination of the pelvis-thorax line, i.e. of the trunk, and
  lacks Plug-in-Gait's anatomical anterior tilt of typically about 10 degrees), else along the
  world vertical (tilt = 0 by construction). Obliquity and rotation are well determined.
- femur: Z = knee -> hip; Y = normal of the hip-knee-ankle plane (pointing left), blended towards
  the pelvis Y when the knee is nearly straight (the plane is then undefined; in frames without a
  pelvis frame, e.g. ASIS markers in a gap, towards the hip centres' line, so the knee and ankle
  angles are still given there while the pelvis and hip angles are not); X = Y x Z. With joint
  centres only the femur's axial rotation comes from the knee's flexion plane, so hip rotation is
  only meaningful when the knee is flexed (swing), and knee ab/adduction and rotation are zero by
  construction (not reported).
- tibia: Z = ankle -> knee, Y = femur Y made orthogonal to Z.
- foot: Z = toe -> heel (the sole line), Y = tibia Y made orthogonal.

Joint angles are the Cardan angles of the distal frame relative to the proximal frame in the
Plug-in-Gait order Y-X-Z (flexion, then ab/adduction about the floating axis, then axial rotation):
``R_prox^T R_dist = Ry(a) Rx(b) Rz(c)``, with Plug-in-Gait signs:

============================  ======================================================
hip_flexion (+ flexion)       -a
hip_adduction (+ adduction)   +b right, -b left
hip_rotation (+ internal)     +c right, -c left
knee_flexion (+ flexion)      +a (tibia relative to femur)
ankle_dorsiflexion (+ dorsi)  -a - 90 (foot relative to tibia; 0 = sole perpendicular to shank)
pelvis_tilt (+ anterior)      +a (pelvis relative to the progression frame)
pelvis_obliquity (+ side up)  +b left, -b right
pelvis_rotation (+ forward)   -c left, +c right
============================  ======================================================

Differences from Plug-in-Gait to keep in mind: the ankle angle uses the heel-toe sole line (no
static-trial offset), so a flat foot under a vertical shank reads 0; the hip centre comes from the
tracker or the motion file, not from the Davis regression.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from gaitcap.gait.events import WalkingDirection, pelvis_track
from gaitcap.trajectory import SIDES, Side, Trajectory, side_suffix

#: per-side angle names (suffix ``_l`` / ``_r``), in output order
ANGLE_NAMES: tuple[str, ...] = (
    "pelvis_tilt", "pelvis_obliquity", "pelvis_rotation",
    "hip_flexion", "hip_adduction", "hip_rotation",
    "knee_flexion", "ankle_dorsiflexion",
)  # fmt: skip

#: ASIS left, ASIS right, PSIS left, PSIS right, as the marker sets of the shipped mappings spell them
#: (Plug-in-Gait, CAST, OpenSim gait2354); a sacral marker stands for both PSIS (their mid-point)
PELVIS_MARKER_SETS = (("LASI", "RASI", "LPSI", "RPSI"), ("LASI", "RASI", "SACR", "SACR"),
                      ("L_IAS", "R_IAS", "L_IPS", "R_IPS"), ("LASIS", "RASIS", "LPSIS", "RPSIS"),
                      ("L.ASIS", "R.ASIS", "V.Sacral", "V.Sacral"),
                      ("asis_l", "asis_r", "psis_l", "psis_r"))  # fmt: skip
_STRAIGHT_KNEE_DEG = 15.0  # below this flexion the femur Y blends towards the pelvis Y


def _unit(v: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _frame(y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Right-handed frames from a Y direction and a Z direction (Z kept, Y made orthogonal).

    Args:
        y, z: shape (T, 3).

    Returns:
        Rotation matrices (T, 3, 3) with columns X, Y, Z.
    """
    z = _unit(z)
    y = _unit(y - np.sum(y * z, axis=-1, keepdims=True) * z)
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=-1)


def _frame_keep_y(y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Frames from a Y direction (kept) and an approximate Z direction, shape (T, 3, 3)."""
    y = _unit(y)
    x = _unit(np.cross(y, z))
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def _frame_xy(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Frames from a Y direction (kept) and an approximate X direction, shape (T, 3, 3)."""
    y = _unit(y)
    z = _unit(np.cross(x, y))
    return np.stack([np.cross(y, z), y, z], axis=-1)


def cardan_yxz(prox: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Cardan angles (a, b, c) in degrees with ``prox^T dist = Ry(a) Rx(b) Rz(c)``.

    Args:
        prox, dist: frames, shape (T, 3, 3); NaN frames give NaN angles.

    Returns:
        Shape (T, 3).
    """
    rel = np.einsum("tji,tjk->tik", prox, dist)
    out = np.full((len(rel), 3), np.nan)
    ok = np.all(np.isfinite(rel), axis=(1, 2))
    if ok.any():
        out[ok] = Rotation.from_matrix(rel[ok]).as_euler("YXZ", degrees=True)
    return out


def _pelvis_markers(traj: Trajectory) -> tuple[np.ndarray, ...] | None:
    for names in PELVIS_MARKER_SETS:
        if all(traj.has(n) for n in names):
            pts = tuple(traj.point(n) for n in names)
            if all(np.isfinite(p).any() for p in pts):
                return pts
    return None


def pelvis_frame(traj: Trajectory) -> tuple[np.ndarray, str]:
    """Pelvis frames (T, 3, 3) and the method used (see the module docstring)."""
    markers = _pelvis_markers(traj)
    if markers is not None:
        lasi, rasi, lpsi, rpsi = markers
        return _frame_xy(0.5 * (lasi + rasi) - 0.5 * (lpsi + rpsi), lasi - rasi), "ASIS/PSIS markers"
    y = traj.point("hip_l") - traj.point("hip_r")
    up = np.broadcast_to([0.0, 0.0, 1.0], y.shape)
    method = "hip centres + world vertical"
    if traj.has("thorax") and np.isfinite(traj.point("thorax")).all(axis=1).mean() > 0.5:
        up = traj.point("thorax") - pelvis_track(traj)
        method = "hip centres + thorax"
    return _frame_keep_y(y, up), method


def leg_frames(traj: Trajectory, side: Side, pelvis: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Femur, tibia and foot frames of one side, each (T, 3, 3) (see the module docstring)."""
    s = side_suffix(side)
    hip, knee, ankle = traj.point(f"hip{s}"), traj.point(f"knee{s}"), traj.point(f"ankle{s}")
    thigh, shank = hip - knee, ankle - knee
    n = np.cross(shank, thigh)  # left-pointing normal of the leg plane for a flexed knee
    sin_k = np.linalg.norm(n, axis=1) / (np.linalg.norm(thigh, axis=1) * np.linalg.norm(shank, axis=1))
    y_pel = pelvis[:, :, 1]
    # where the pelvis frame is missing (a marker file's ASIS markers in a gap) but the hip centres are
    # not, the leg's reference left axis is the hip centres' line: the knee and ankle angles need no pelvis
    hips_y = _unit(traj.point("hip_l") - traj.point("hip_r"))
    y_pel = np.where(np.isfinite(y_pel).all(axis=1, keepdims=True), y_pel, hips_y)
    n_hat = _unit(n)
    n_hat = np.where(np.sum(n_hat * y_pel, axis=1, keepdims=True) < 0, -n_hat, n_hat)  # hyperextension
    w = np.clip(sin_k / np.sin(np.radians(_STRAIGHT_KNEE_DEG)), 0.0, 1.0)[:, None]
    y = np.where(np.isfinite(n_hat), w * np.nan_to_num(n_hat) + (1 - w) * y_pel, y_pel)
    femur = _frame(y, thigh)
    tibia = _frame(femur[:, :, 1], knee - ankle)
    if traj.has(f"heel{s}") and traj.has(f"toe{s}"):
        foot = _frame(tibia[:, :, 1], traj.point(f"heel{s}") - traj.point(f"toe{s}"))
    else:
        foot = np.full_like(tibia, np.nan)
    return femur, tibia, foot


def progression_frame(direction: WalkingDirection, n_frames: int, pelvis: np.ndarray | None = None) -> np.ndarray:
    """The progression frame repeated, shape (T, 3, 3); turned half a turn about the vertical when
    the pelvis frames ``pelvis`` (T, 3, 3), given, face against ``direction`` on average (their X
    axes' mean against its forward: a subject walking backwards)."""
    forward, left = direction.forward, direction.left
    if pelvis is not None:
        facing = np.nanmean(pelvis[:, :, 0], axis=0) if np.isfinite(pelvis[:, :, 0]).any() else np.zeros(3)
        if float(np.dot(facing[:2], forward[:2])) < 0:
            forward, left = -forward, -left
    R = np.stack([forward, left, [0.0, 0.0, 1.0]], axis=-1)
    return np.broadcast_to(R, (n_frames, 3, 3)).copy()


def joint_angles(traj: Trajectory, direction: WalkingDirection) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Joint angles per frame, degrees.

    Args:
        traj: trajectory with hip_l/r, knee_l/r, ankle_l/r (and heel/toe, pelvis, thorax if any).
        direction: the walking direction (pelvis angles are relative to it, or to its opposite
            when the pelvis faces that way: :func:`progression_frame`).

    Returns:
        ``{"<angle>_l" | "<angle>_r": (T,) degrees}`` for every name in :data:`ANGLE_NAMES`, NaN
        where a point is missing; and a dict of notes (``pelvis_frame`` method).
    """
    pel, method = pelvis_frame(traj)
    prog = progression_frame(direction, traj.n_frames, pel)
    p = cardan_yxz(prog, pel)
    out: dict[str, np.ndarray] = {}
    for side in SIDES:
        s = side_suffix(side)
        sign = 1.0 if side == "right" else -1.0
        femur, tibia, foot = leg_frames(traj, side, pel)
        h, k, a = cardan_yxz(pel, femur), cardan_yxz(femur, tibia), cardan_yxz(tibia, foot)
        out[f"pelvis_tilt{s}"] = p[:, 0]
        out[f"pelvis_obliquity{s}"] = -sign * p[:, 1]
        out[f"pelvis_rotation{s}"] = sign * p[:, 2]
        out[f"hip_flexion{s}"] = -h[:, 0]
        out[f"hip_adduction{s}"] = sign * h[:, 1]
        out[f"hip_rotation{s}"] = sign * h[:, 2]
        out[f"knee_flexion{s}"] = k[:, 0]
        out[f"ankle_dorsiflexion{s}"] = -a[:, 0] - 90.0
    ordered = {f"{n}{side_suffix(side)}": out[f"{n}{side_suffix(side)}"] for side in SIDES for n in ANGLE_NAMES}
    return ordered, {"pelvis_frame": method}
