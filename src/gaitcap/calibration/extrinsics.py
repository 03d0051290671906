"""Extrinsic calibration: put every camera in one world frame (metres, z up, floor z = 0).

Two sources of world points:

* **A board on the floor.** The board frame of :mod:`gaitcap.calibration.boards` is the world:
  origin at corner 0, x along the rows, z up towards the cameras. Each camera's pose comes from
  ``solvePnP`` on a view of the reference board position. When the board was moved (synchronised
  videos or image sequences: frame k of every camera shows the same position), positions and
  cameras are chained through shared views and then refined jointly by bundle adjustment:

      min over {R_c, t_c} (every camera) and {R_f, t_f} (every position f != reference)
          sum_{c, f, i seen} || π_c(R_c (R_f X_i + t_f) + t_c) - x_cfi ||²

  with π_c the camera's (fixed) intrinsic projection including distortion, solved by
  ``scipy.optimize.least_squares`` with a sparse Jacobian pattern.
* **Scene points**: points of known world coordinates and their pixel positions per camera,
  one ``solvePnP`` per camera (at least 4 points) refined by Levenberg-Marquardt.

Quality figures: per-camera RMS reprojection error (pixels) and a 3D check in millimetres: the
board corners triangulated from all cameras compared with the board's true shape (rigid fit),
or the scene points triangulated and compared with their given coordinates.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from pydantic import Field
from scipy.optimize import least_squares
from scipy.sparse import lil_matrix

from gaitcap.calibration.boards import Board, Detection
from gaitcap.camera import Camera, CameraRig
from gaitcap.config import Strict
from gaitcap.errors import CalibrationError

log = logging.getLogger(__name__)

MIN_PNP_POINTS = 4


@dataclass
class ExtrinsicsResult:
    """Outcome of :func:`calibrate_from_board` or :func:`calibrate_from_points`.

    Attributes:
        rig: the cameras with their poses (intrinsics unchanged).
        rms_px: ``camera -> RMS reprojection error`` in pixels over all its observations.
        check_mm: 3D check, RMS error in millimetres (NaN when no point is seen twice).
        method: ``"board"`` or ``"points"``.
        n_positions: board positions used (1 for scene points).
        adjusted: whether the joint refinement (bundle adjustment) ran.
    """

    rig: CameraRig
    rms_px: dict[str, float]
    check_mm: float
    method: str
    n_positions: int = 1
    adjusted: bool = False
    board_poses: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)

    def metadata(self) -> dict:
        """The ``[metadata]`` table of ``calibration.toml``."""
        errors = list(self.rms_px.values())
        return {
            "adjusted": self.adjusted,
            "error": round(float(np.sqrt(np.mean(np.square(errors)))), 4) if errors else 0.0,
            "extrinsics_method": self.method,
            "extrinsics_positions": self.n_positions,
            "reprojection_rms_px": {k: round(v, 4) for k, v in self.rms_px.items()},
            "check_3d_mm": round(self.check_mm, 3) if np.isfinite(self.check_mm) else -1.0,
        }


# --------------------------------------------------------------------------- geometry
def _pnp(obj: np.ndarray, img: np.ndarray, camera: Camera, where: str) -> tuple[np.ndarray, np.ndarray]:
    """World points (N, 3) and pixels (N, 2) -> Rodrigues rvec (3,), tvec (3,) world -> camera."""
    if len(obj) < MIN_PNP_POINTS:
        raise CalibrationError(f"{where}: {len(obj)} point(s) with known pixels; at least {MIN_PNP_POINTS} are needed")
    obj32, img32 = obj.astype(np.float64).reshape(-1, 1, 3), img.astype(np.float64).reshape(-1, 1, 2)
    planar = np.ptp(obj[:, 2]) < 1e-9 * max(1.0, np.ptp(obj))
    method = cv2.SOLVEPNP_IPPE if planar else (cv2.SOLVEPNP_SQPNP if len(obj) >= 3 else cv2.SOLVEPNP_ITERATIVE)
    ok, rvec, tvec = cv2.solvePnP(obj32, img32, camera.matrix, camera.dist, flags=method)
    if not ok:
        raise CalibrationError(f"{where}: solvePnP found no pose")
    rvec, tvec = cv2.solvePnPRefineLM(obj32, img32, camera.matrix, camera.dist, rvec, tvec)
    return rvec.ravel(), tvec.ravel()


def _compose(r_outer: np.ndarray, t_outer: np.ndarray, r_inner: np.ndarray, t_inner: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(outer ∘ inner) as (rvec, tvec): X -> R_o (R_i X + t_i) + t_o."""
    r, t = cv2.composeRT(r_inner, t_inner, r_outer, t_outer)[:2]
    return r.ravel(), t.ravel()


def _invert(rvec: np.ndarray, tvec: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    R = cv2.Rodrigues(rvec)[0]
    return cv2.Rodrigues(R.T)[0].ravel(), -R.T @ tvec


def _transform(points: np.ndarray, rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    """Points (N, 3) -> R points + t, shape (N, 3)."""
    return points @ cv2.Rodrigues(rvec)[0].T + tvec


def _rms(residuals: np.ndarray) -> float:
    """RMS of 2D residual vectors (N, 2) (OpenCV's reprojection error convention)."""
    return float(np.sqrt(np.mean(np.sum(residuals.reshape(-1, 2) ** 2, axis=1)))) if residuals.size else float("nan")


# ------------------------------------------------------------------- bundle adjustment
@dataclass
class _Obs:
    cam: int
    pos: int  # board position index; -1: world points, no position transform
    obj: np.ndarray  # (N, 3) in the position's frame (board) or the world
    img: np.ndarray  # (N, 2) pixels


def _residuals(x: np.ndarray, cams: Sequence[Camera], obs: Sequence[_Obs], ref: int, n_pos: int) -> np.ndarray:
    cam_p = x[: 6 * len(cams)].reshape(-1, 6)
    pos_p = x[6 * len(cams):].reshape(-1, 6)
    out = []
    for o in obs:
        pts = o.obj
        if o.pos >= 0 and o.pos != ref:
            k = o.pos if o.pos < ref else o.pos - 1
            pts = _transform(pts, pos_p[k, :3], pos_p[k, 3:])
        proj = cv2.projectPoints(pts, cam_p[o.cam, :3], cam_p[o.cam, 3:], cams[o.cam].matrix, cams[o.cam].dist)[0]
        out.append((proj.reshape(-1, 2) - o.img).ravel())
    return np.concatenate(out)


def _sparsity(n_cams: int, obs: Sequence[_Obs], ref: int, n_pos: int) -> lil_matrix:
    n_res = sum(2 * len(o.img) for o in obs)
    J = lil_matrix((n_res, 6 * n_cams + 6 * max(n_pos - 1, 0)), dtype=int)
    row = 0
    for o in obs:
        rows = slice(row, row + 2 * len(o.img))
        J[rows, 6 * o.cam: 6 * o.cam + 6] = 1
        if o.pos >= 0 and o.pos != ref:
            k = o.pos if o.pos < ref else o.pos - 1
            J[rows, 6 * n_cams + 6 * k: 6 * n_cams + 6 * k + 6] = 1
        row += 2 * len(o.img)
    return J


def bundle_adjust(
    cams: Sequence[Camera],
    obs: Sequence[_Obs],
    positions: Sequence[tuple[np.ndarray, np.ndarray]],
    ref: int = 0,
    loss: str = "linear",
) -> tuple[list[Camera], list[tuple[np.ndarray, np.ndarray]]]:
    """Refine camera poses and board positions (the reference position stays the world)."""
    n_pos = len(positions)
    x0 = np.concatenate(
        [np.r_[c.rvec, c.tvec] for c in cams] + [np.r_[r, t] for k, (r, t) in enumerate(positions) if k != ref]
    )
    sol = least_squares(
        _residuals, x0, jac_sparsity=_sparsity(len(cams), obs, ref, n_pos), method="trf", loss=loss,
        f_scale=1.0, x_scale="jac", args=(cams, obs, ref, n_pos), xtol=1e-10, ftol=1e-10,
    )
    if not sol.success:
        raise CalibrationError(f"bundle adjustment did not converge: {sol.message}")
    cam_p = sol.x[: 6 * len(cams)].reshape(-1, 6)
    pos_p = sol.x[6 * len(cams):].reshape(-1, 6)
    new_cams = [replace(c, rvec=p[:3], tvec=p[3:]) for c, p in zip(cams, cam_p)]
    new_pos, it = [], iter(pos_p)
    for k in range(n_pos):
        new_pos.append(positions[k] if k == ref else tuple(np.split(next(it), 2)))  # type: ignore[arg-type]
    return new_cams, new_pos  # type: ignore[return-value]


def _per_camera_rms(cams: Sequence[Camera], obs: Sequence[_Obs], positions: Sequence[tuple[np.ndarray, np.ndarray]]) -> dict[str, float]:
    res: dict[int, list[np.ndarray]] = {}
    for o in obs:
        pts = _transform(o.obj, *positions[o.pos]) if o.pos >= 0 else o.obj
        res.setdefault(o.cam, []).append(cams[o.cam].project(pts) - o.img)
    return {cams[i].name: _rms(np.concatenate(r)) for i, r in sorted(res.items())}


# ------------------------------------------------------------------------ floor board
def calibrate_from_board(
    cameras: Sequence[Camera],
    frames: Mapping[str, Sequence[Detection | None]],
    board: Board,
    adjust: bool = True,
) -> ExtrinsicsResult:
    """Camera poses from a board on the floor seen by every camera.

    Args:
        cameras: cameras with their intrinsics (poses are ignored).
        frames: ``camera name -> detections per frame`` (None where the board is not seen);
            frame k of every camera shows the same board position.
        board: the board.
        adjust: run the joint refinement when there is more than one position or camera.

    The reference position (the world frame) is the first frame seen by the most cameras.
    """
    cams = list(cameras)
    names = [c.name for c in cams]
    missing = [n for n in names if n not in frames]
    if missing:
        raise CalibrationError(f"no board views for camera(s) {', '.join(missing)}")
    n_frames = max(len(frames[n]) for n in names)
    seen = np.array([[k < len(frames[n]) and frames[n][k] is not None for k in range(n_frames)] for n in names])
    for n, row in zip(names, seen):
        if not row.any():
            raise CalibrationError(f"camera {n!r}: the {board.describe()} is not found in any of its views")
    if not board.orientation_is_unique:
        log.warning("%s: the board looks the same turned by 180 degrees; cameras on opposite sides may disagree", board.describe())
    used = np.nonzero(seen.any(axis=0))[0]
    ref_frame = int(used[np.argmax(seen[:, used].sum(axis=0))])
    obj = board.object_points()
    # each camera's view of each position, as a pose board -> camera
    local: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
    obs: list[_Obs] = []
    pos_index = {int(f): k for k, f in enumerate(used)}
    for ci, n in enumerate(names):
        for f in used:
            det = frames[n][f] if f < len(frames[n]) else None
            if det is None:
                continue
            pts = obj[det.ids]
            local[ci, pos_index[int(f)]] = _pnp(pts, det.corners, cams[ci], f"camera {n!r}, view {det.source}")
            obs.append(_Obs(ci, pos_index[int(f)], pts, det.corners))
    ref = pos_index[ref_frame]
    cam_pose, pos_pose = _chain(local, len(cams), len(used), ref, names)
    cams = [replace(c, rvec=cam_pose[i][0], tvec=cam_pose[i][1]) for i, c in enumerate(cams)]
    positions = [pos_pose[k] for k in range(len(used))]
    adjusted = False
    if adjust and len(obs) > len(cams):
        cams, positions = bundle_adjust(cams, obs, positions, ref)
        adjusted = True
    rig = CameraRig(tuple(cams))
    rms = _per_camera_rms(cams, obs, positions)
    check = _board_shape_check(rig, frames, used, board)
    _warn_below_floor(rig)
    return ExtrinsicsResult(rig, rms, check, "board", len(used), adjusted, positions)


def _chain(
    local: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]], n_cams: int, n_pos: int, ref: int, names: list[str]
) -> tuple[dict[int, tuple[np.ndarray, np.ndarray]], dict[int, tuple[np.ndarray, np.ndarray]]]:
    """Initial poses: cameras from the reference position, then alternately positions and cameras."""
    pos: dict[int, tuple[np.ndarray, np.ndarray]] = {ref: (np.zeros(3), np.zeros(3))}
    cam: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    changed = True
    while changed:
        changed = False
        for (c, p), (r, t) in local.items():
            if p in pos and c not in cam:  # camera <- board position (world -> camera = local ∘ pos^-1)
                cam[c] = _compose(r, t, *_invert(*pos[p]))
                changed = True
            elif c in cam and p not in pos:  # position <- camera (board -> world = cam^-1 ∘ local)
                pos[p] = _compose(*_invert(*cam[c]), r, t)
                changed = True
    lost = [names[c] for c in range(n_cams) if c not in cam]
    if lost:
        raise CalibrationError(
            f"camera(s) {', '.join(lost)} share no board position with the reference view; "
            "move the board through the overlap of neighbouring cameras"
        )
    return cam, pos


def _board_shape_check(rig: CameraRig, frames: Mapping[str, Sequence[Detection | None]], used: np.ndarray, board: Board) -> float:
    """RMS distance (mm) between board corners triangulated by every camera and the true board
    shape after a rigid fit (Kabsch), over all positions seen by at least two cameras."""
    errs = []
    obj = board.object_points()
    for f in used:
        px = np.full((len(rig), len(obj), 2), np.nan)
        for ci, cam in enumerate(rig):
            seq = frames[cam.name]
            det = seq[f] if f < len(seq) else None
            if det is not None:
                px[ci, det.ids] = det.corners
        if (np.isfinite(px[:, :, 0]).sum(axis=0) >= 2).sum() < 3:
            continue
        X = rig.triangulate(px)
        ok = np.all(np.isfinite(X), axis=1)
        errs.append(_rigid_fit_residuals(obj[ok], X[ok]))
    return float(np.sqrt(np.mean(np.concatenate(errs) ** 2)) * 1000) if errs else float("nan")


def _rigid_fit_residuals(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances (N,) between b and the best rigid transform of a (Kabsch)."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    U, _, Vt = np.linalg.svd((a - ca).T @ (b - cb))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return np.linalg.norm((a - ca) @ R.T + cb - b, axis=1)


def _warn_below_floor(rig: CameraRig) -> None:
    for cam in rig:
        if cam.center[2] < 0:
            log.warning("camera %r is below the floor (z = %.2f m): is the board upside down?", cam.name, cam.center[2])


# ----------------------------------------------------------------------- scene points
class ScenePoints(Strict):
    """Schema of a scene-calibration file.

    ```yaml
    points:                # name: [x, y, z], metres, world frame (z up, floor z = 0)
      a: [-2.0, 0.3, 0.0]
    pixels:                # camera: {point name: [u, v] or null when not visible}
      cam01: {a: [329.1, 974.1]}
    ```
    """

    points: dict[str, tuple[float, float, float]] = Field(min_length=MIN_PNP_POINTS)
    pixels: dict[str, dict[str, tuple[float, float] | None]]
    notes: str = ""


def calibrate_from_points(cameras: Sequence[Camera], scene: ScenePoints, source: str = "points") -> ExtrinsicsResult:
    """Camera poses from points of known world coordinates and their pixels in each camera."""
    cams = list(cameras)
    uncalibrated = sorted(set(scene.pixels) - {c.name for c in cams})
    if uncalibrated:  # a misspelt camera's clicks, or a camera left out on purpose: said either way
        log.warning("%s: pixels of camera(s) %s left out: no intrinsics describe them (cameras: %s)", source,
                    ", ".join(uncalibrated), ", ".join(c.name for c in cams))  # fmt: skip
    for cam_name, table in scene.pixels.items():
        unknown = sorted(set(table) - set(scene.points))
        if unknown:
            raise CalibrationError(f"{source}: pixels.{cam_name}: unknown point(s) {', '.join(unknown)} (not in 'points')")
    obs: list[_Obs] = []
    for ci, cam in enumerate(cams):
        table = scene.pixels.get(cam.name)
        if table is None:
            raise CalibrationError(f"{source}: no pixels for camera {cam.name!r} (cameras: {', '.join(scene.pixels)})")
        names = [n for n, uv in table.items() if uv is not None]
        obj = np.array([scene.points[n] for n in names], float).reshape(-1, 3)
        img = np.array([table[n] for n in names], float).reshape(-1, 2)
        r, t = _pnp(obj, img, cam, f"{source}: camera {cam.name!r}")
        cams[ci] = replace(cam, rvec=r, tvec=t)
        obs.append(_Obs(ci, -1, obj, img))
    rig = CameraRig(tuple(cams))
    rms = _per_camera_rms(cams, obs, [])
    return ExtrinsicsResult(rig, rms, scene_check_mm(rig, scene), "points", 1, False)


def scene_check_mm(rig: CameraRig, scene: ScenePoints) -> float:
    """RMS distance (mm) between the scene points triangulated by ``rig`` and their coordinates."""
    names = list(scene.points)
    px = np.full((len(rig), len(names), 2), np.nan)
    for ci, cam in enumerate(rig):
        for j, n in enumerate(names):
            uv = scene.pixels.get(cam.name, {}).get(n)
            if uv is not None:
                px[ci, j] = uv
    X = rig.triangulate(px)
    ok = np.all(np.isfinite(X), axis=1)
    if not ok.any():
        return float("nan")
    truth = np.array([scene.points[n] for n in names])[ok]
    return float(np.sqrt(np.mean(np.sum((X[ok] - truth) ** 2, axis=1))) * 1000)


def scene_reprojection(rig: CameraRig, scene: ScenePoints) -> dict[str, dict[str, float]]:
    """``camera -> {point: pixel distance}`` between projected coordinates and the given pixels."""
    out: dict[str, dict[str, float]] = {}
    for cam in rig:
        table = scene.pixels.get(cam.name, {})
        for n, uv in table.items():
            if uv is not None and n in scene.points:
                d = float(np.linalg.norm(cam.project(np.array(scene.points[n], float)[None])[0] - np.asarray(uv)))
                out.setdefault(cam.name, {})[n] = d
    return out


def scene_point_errors(rig: CameraRig, scene: ScenePoints, inlier_px: float = 8.0) -> dict[str, dict[str, float]]:
    """``camera -> {point: pixel distance}`` of each point from where the camera projects it when
    posed from the points that agree (``solvePnPRansac`` with ``inlier_px``, then refined on its
    inliers): a wrong click stands out, where a pose fitted to every point spreads its error over the
    good ones too. Where no such consensus is found (too few points, or most of them off), the
    distance from the given pose (:func:`scene_reprojection`)."""
    out = scene_reprojection(rig, scene)
    for cam in rig:
        table = {n: uv for n, uv in scene.pixels.get(cam.name, {}).items() if uv is not None and n in scene.points}
        if len(table) < 2 * MIN_PNP_POINTS - 2:
            continue
        names = list(table)
        obj = np.array([scene.points[n] for n in names], float)
        img = np.array([table[n] for n in names], float)
        try:
            cv2.setRNGSeed(0)  # its random subsets: the same points named on every run
            ok, _, _, inliers = cv2.solvePnPRansac(obj.reshape(-1, 1, 3), img.reshape(-1, 1, 2), cam.matrix, cam.dist,
                                                   reprojectionError=inlier_px, iterationsCount=200)  # fmt: skip
            if not ok or inliers is None or len(inliers) < max(MIN_PNP_POINTS, len(names) // 2 + 1):
                continue
            keep = inliers.ravel()
            r, t = _pnp(obj[keep], img[keep], cam, f"camera {cam.name!r}")
        except (CalibrationError, cv2.error):
            continue
        uv = replace(cam, rvec=r, tvec=t).project(obj)
        out[cam.name] = {n: float(d) for n, d in zip(names, np.linalg.norm(uv - img, axis=1), strict=True)}
    return out


def scene_pixel_disagreement(a: ScenePoints, b: ScenePoints) -> dict[str, dict[str, float]]:
    """``camera -> {point: pixel distance}`` between two pixel tables of the same points.

    Only the points located (not null) in both tables count; e.g. two clickings of the same scene
    points, whose disagreement is their click noise.
    """
    out: dict[str, dict[str, float]] = {}
    for cam, table in a.pixels.items():
        other = b.pixels.get(cam, {})
        for n, uv in table.items():
            if uv is not None and other.get(n) is not None:
                out.setdefault(cam, {})[n] = float(np.linalg.norm(np.subtract(uv, other[n])))
    return out

# ------------------------------------------------------------------------------ stereo
@dataclass
class StereoResult:
    """Two cameras calibrated together: the left one defines the frame (identity pose)."""

    rig: CameraRig
    rms_px: float
    baseline_m: float
    epipolar_px: float
    n_pairs: int


def calibrate_stereo(left: Camera, right: Camera, pairs: Sequence[tuple[Detection, Detection]], board: Board) -> StereoResult:
    """Relative pose of ``right`` w.r.t. ``left`` from synchronised board views (intrinsics fixed).

    The mean epipolar error is the mean distance (pixels, undistorted) of each corner to the
    epipolar line of its match, symmetric over both images.
    """
    if len(pairs) < 1:
        raise CalibrationError("stereo: no image pair shows the board in both cameras")
    obj = board.object_points().astype(np.float32)
    objs, pl, pr = [], [], []
    for a, b in pairs:
        common = np.intersect1d(a.ids, b.ids)
        ia = np.searchsorted(a.ids, common)
        ib = np.searchsorted(b.ids, common)
        objs.append(obj[common])
        pl.append(a.corners[ia].astype(np.float32).reshape(-1, 1, 2))
        pr.append(b.corners[ib].astype(np.float32).reshape(-1, 1, 2))
    try:
        rms, _, _, _, _, R, T, _, F = cv2.stereoCalibrate(
            objs, pl, pr, left.matrix, left.dist, right.matrix, right.dist, left.size, flags=cv2.CALIB_FIX_INTRINSIC
        )
    except cv2.error as e:
        raise CalibrationError(f"stereo: OpenCV calibration failed: {e.err}") from e
    L = replace(left, rvec=np.zeros(3), tvec=np.zeros(3))
    Rr = replace(right, rvec=cv2.Rodrigues(R)[0].ravel(), tvec=T.ravel())
    ul = np.concatenate([L.undistort_pixels(p.reshape(-1, 2)) for p in pl])
    ur = np.concatenate([Rr.undistort_pixels(p.reshape(-1, 2)) for p in pr])
    epi = epipolar_distances(F, ul, ur)
    return StereoResult(CameraRig((L, Rr)), float(rms), float(np.linalg.norm(T)), float(epi.mean()), len(pairs))


def epipolar_distances(F: np.ndarray, left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Symmetric point-to-epipolar-line distances (N,) for matches left (N, 2) <-> right (N, 2)."""
    lines_r = cv2.computeCorrespondEpilines(left.reshape(-1, 1, 2), 1, F).reshape(-1, 3)
    lines_l = cv2.computeCorrespondEpilines(right.reshape(-1, 1, 2), 2, F).reshape(-1, 3)
    dr = np.abs(np.sum(lines_r[:, :2] * right, axis=1) + lines_r[:, 2]) / np.linalg.norm(lines_r[:, :2], axis=1)
    dl = np.abs(np.sum(lines_l[:, :2] * left, axis=1) + lines_l[:, 2]) / np.linalg.norm(lines_l[:, :2], axis=1)
    return 0.5 * (dr + dl)
