"""A calibration that cannot be right is refused before tracking, with the likely cause named:
millimetres given as metres, cameras under or looking away from the floor, silhouettes that do not
meet in 3D where the calibration puts them."""

from __future__ import annotations

import shutil
from dataclasses import replace

import cv2
import numpy as np
import pytest
from click.testing import CliRunner
from session_factory import make_session

from gaitcap.calibration.quality import check_rig, floor_distance, geometry_problems
from gaitcap.camera import Camera, CameraRig
from gaitcap.cli.main import cli
from gaitcap.errors import CalibrationError
from gaitcap.io.calibration_toml import read_calibration, write_calibration
from gaitcap.session_check import check_silhouettes_meet
from gaitcap.tracking.observation import observe, tracking_views


def _rig(n: int = 3, height: float = 1.2, size: tuple[int, int] = (320, 240), focal: float = 260.0) -> CameraRig:
    """Cameras 4 m around the origin looking at (0, 0, 0.9)."""
    return CameraRig(tuple(
        Camera.look_at(f"cam{i}", (4.0 * np.cos(a), 4.0 * np.sin(a), height), (0.0, 0.0, 0.9), size=size, focal_px=focal)
        for i, a in enumerate(np.linspace(0.0, np.pi, n, endpoint=False) + 0.3)
    ))  # fmt: skip


def _scaled(rig: CameraRig, factor: float) -> CameraRig:
    return CameraRig(tuple(replace(c, tvec=c.tvec * factor) for c in rig))


def _rotated(cam: Camera, rvec_cam: tuple[float, float, float]) -> Camera:
    """``cam`` turned about its own axes (x: pitch, y: yaw, z: roll), its centre kept."""
    Rr = cv2.Rodrigues(np.asarray(rvec_cam, dtype=np.float64))[0]
    return replace(cam, rvec=cv2.Rodrigues(Rr @ cam.R)[0].ravel(), tvec=Rr @ cam.tvec)


# --- geometry ----------------------------------------------------------------------------------


def test_a_plausible_rig_has_no_problem() -> None:
    rig = _rig()
    assert geometry_problems(rig) == []
    assert all(2.0 < floor_distance(c) < 10.0 for c in rig)


def test_translations_in_millimetres_are_named() -> None:
    (problem,) = geometry_problems(_scaled(_rig(), 1000.0))
    assert "'cam0' 4,176 m" in problem and "millimetres given as metres" in problem and "divide them by 1000" in problem


def test_cameras_far_away_but_not_in_millimetres() -> None:
    (problem,) = geometry_problems(_scaled(_rig(), 100_000.0))
    assert "farther than 30 m" in problem and "millimetres" not in problem


def test_cameras_below_the_floor() -> None:
    rig = CameraRig(tuple(Camera.look_at(f"c{i}", (4.0 * s, 1.0, -1.2), (0, 0, -0.9)) for i, s in enumerate((1, -1))))
    (problem,) = geometry_problems(rig)
    assert "'c0' (z = -1.20 m)" in problem and "below the floor" in problem and "z axis" in problem


def test_a_stereo_calibration_has_no_floor() -> None:
    """A stereo pair's frame is its first camera's (``calibrate stereo``): named as such, not as a camera below
    the floor (its partner sits at z = -0.00 m)."""
    left = Camera("left", (320, 240), np.array([[260.0, 0, 160], [0, 260, 120], [0, 0, 1]]))
    right = replace(left, name="right", tvec=np.array([-0.0836, 0.0, -1e-4]))
    (problem,) = geometry_problems(CameraRig((left, right)))
    assert "'left' is the world frame itself" in problem and "calibrate extrinsics" in problem
    assert "below the floor" not in problem


def test_a_camera_looking_up_cannot_see_the_feet() -> None:
    rig = _rig(2)
    up = Camera.look_at("sky", (4.0, 0.0, 1.2), (0.0, 0.0, 6.0), size=(320, 240), focal_px=260.0)
    assert floor_distance(up) == np.inf
    (problem,) = geometry_problems(CameraRig((*rig.cameras, up)))
    assert "'sky' look away from the floor" in problem and "'cam0'" not in problem
    assert any("look away from the floor" in p for p in check_rig(CameraRig((*rig.cameras, up))).problems)


def test_millimetres_refused_before_tracking_with_one_line_and_nothing_written(tmp_path) -> None:
    root = make_session(tmp_path / "s")
    toml = root / "calibration.toml"
    write_calibration(toml, _scaled(read_calibration(toml), 1000.0))
    out = tmp_path / "results" / "OUT"
    res = CliRunner().invoke(cli, ["track", str(root), "-o", str(out)])
    assert res.exit_code != 0
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and str(toml) in lines[0] and "millimetres" in lines[0]
    assert not (tmp_path / "results").exists()


# --- silhouettes -------------------------------------------------------------------------------


def _person_masks(rig: CameraRig, centre: tuple[float, float] = (0.2, -0.1), height: float = 1.7) -> list[np.ndarray]:
    """Full-resolution masks of an upright cylinder (radius 0.18 m) standing on the floor."""
    a, z = np.meshgrid(np.linspace(0, 2 * np.pi, 24), np.linspace(0.0, height, 30))
    pts = np.stack([centre[0] + 0.18 * np.cos(a), centre[1] + 0.18 * np.sin(a), z], -1).reshape(-1, 3)
    masks = []
    for cam in rig:
        px = cam.project(pts).reshape(-1, 2)
        m = np.zeros((cam.height, cam.width), np.uint8)
        cv2.fillConvexPoly(m, cv2.convexHull(np.round(px).astype(np.int32)), 255)
        masks.append(m)
    return masks


def test_silhouettes_that_meet_where_the_calibration_puts_them_pass() -> None:
    rig = _rig()
    obs = [observe(tracking_views(rig, 0.5), _person_masks(rig, (0.2 + 0.05 * k, -0.1))) for k in range(5)]
    check_silhouettes_meet(tracking_views(rig, 0.5), obs, "calibration.toml")


def test_frames_without_two_silhouettes_are_not_judged() -> None:
    rig = _rig()
    views = tracking_views(rig, 0.5)
    masks = _person_masks(rig)
    masks[1][:] = 0
    masks[2][:] = 0
    check_silhouettes_meet(views, [observe(views, masks)] * 5, "calibration.toml")


@pytest.mark.parametrize("wrong", ["transposed", "pitched"])
def test_silhouettes_that_cannot_meet_refuse_the_calibration(wrong: str) -> None:
    rig = _rig()
    masks = _person_masks(rig)  # the truth
    cams = list(rig)
    if wrong == "transposed":  # rotations written as their inverse
        cams = [replace(c, rvec=-c.rvec) for c in cams]
    else:  # one camera's rotation 20 degrees off about its own x axis
        cams[1] = _rotated(cams[1], (np.radians(20.0), 0.0, 0.0))
    views = tracking_views(CameraRig(tuple(cams)), 0.5)
    with pytest.raises(CalibrationError) as e:
        check_silhouettes_meet(views, [observe(views, masks)] * 5, "SESSION/calibration.toml")
    msg = str(e.value)
    assert msg.startswith("SESSION/calibration.toml: the cameras' silhouettes do not meet in 3D") and "\n" not in msg
    if wrong == "pitched":
        assert "the others agree without camera 'cam1'" in msg


def test_someone_else_near_a_camera_is_named_as_a_possible_cause() -> None:
    """The right calibration, but a second person stands between camera 0 and the subject: that
    camera's silhouette holds both, the rays miss each other, and the error says to check for
    someone else in view as well as the extrinsics."""
    rig = _rig()
    near = 0.6 * rig.cameras[0].center[:2] + np.array([0.4, -0.3])
    masks = [np.maximum(a, b) for a, b in zip(_person_masks(rig), _person_masks(rig, tuple(near)))]
    views = tracking_views(rig, 0.5)
    check_silhouettes_meet(views, [observe(views, _person_masks(rig))] * 5, "SESSION/calibration.toml")  # alone: passes
    with pytest.raises(CalibrationError) as e:
        check_silhouettes_meet(views, [observe(views, masks)] * 5, "SESSION/calibration.toml")
    msg = str(e.value)
    assert "check the extrinsics" in msg and "no one but the subject is in a camera's view" in msg and "\n" not in msg


def test_tracking_refuses_a_calibration_its_silhouettes_contradict(embedded_session, tmp_path) -> None:
    from gaitcap.pipeline import run_track

    root = tmp_path / "session"
    shutil.copytree(embedded_session.session, root)
    toml = root / "calibration.toml"
    rig = read_calibration(toml)
    write_calibration(toml, CameraRig((rig.cameras[0], _rotated(rig.cameras[1], (np.radians(20.0), 0.0, 0.0)),
                                       *rig.cameras[2:])))  # fmt: skip
    out = tmp_path / "OUT"
    with pytest.raises(CalibrationError, match="silhouettes do not meet in 3D"):
        run_track(root, out, progress=False, max_frames=8)
    assert not out.exists()
