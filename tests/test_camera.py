from __future__ import annotations

import cv2
import numpy as np
import pytest

from gaitcap.camera import Camera, CameraRig
from gaitcap.errors import CalibrationError
from gaitcap.io.calibration_toml import read_calibration, write_calibration


def _camera(name: str = "cam0", dist=(-0.21, 0.08, 0.001, -0.0015, -0.01)) -> Camera:
    cam = Camera.look_at(name, position=[3.0, -4.0, 1.3], target=[0.0, 0.0, 0.9], focal_px=610.0)
    return Camera(name, cam.size, cam.matrix, np.asarray(dist, float), cam.rvec, cam.tvec)


def test_projection_matches_opencv(rng):
    cam = _camera()
    pts = rng.uniform([-1.5, -1.5, 0.0], [1.5, 1.5, 2.0], size=(500, 3))
    ours = cam.project(pts)
    ref, _ = cv2.projectPoints(pts, cam.rvec, cam.tvec, cam.matrix, cam.dist)
    np.testing.assert_allclose(ours, ref.reshape(-1, 2), atol=1e-6)


def test_projection_keeps_leading_shape(rng):
    cam = _camera()
    pts = rng.uniform(-1, 1, size=(4, 7, 3)) + [0, 0, 1]
    assert cam.project(pts).shape == (4, 7, 2)
    np.testing.assert_allclose(cam.project(pts)[2, 3], cam.project(pts[2, 3][None])[0])


def test_points_behind_camera_are_nan():
    cam = _camera(dist=(0, 0, 0, 0))
    behind = cam.center + (cam.center - np.array([0.0, 0.0, 0.9]))
    assert np.all(np.isnan(cam.project(behind[None])))


def test_look_at_puts_target_at_image_centre():
    cam = Camera.look_at("c", [0.0, -5.0, 1.0], [0.0, 0.0, 1.0], size=(640, 480))
    np.testing.assert_allclose(cam.project(np.array([[0.0, 0.0, 1.0]])), [[319.5, 239.5]], atol=1e-9)
    up = cam.project(np.array([[0.0, 0.0, 1.5]]))[0]
    assert up[1] < 239.5  # world z up is image up


def test_undistort_inverts_distortion(rng):
    cam = _camera()
    pts = rng.uniform([-1, -1, 0], [1, 1, 2], size=(50, 3))
    ideal = cam.project(pts, distort=False)
    np.testing.assert_allclose(cam.undistort_pixels(cam.project(pts)), ideal, atol=0.05)


def test_triangulation_recovers_points(rng):
    rig = CameraRig((_camera("a"), Camera.look_at("b", [-3.5, -3.0, 1.5], [0, 0, 0.9])))
    pts = rng.uniform([-1, -1, 0], [1, 1, 2], size=(20, 3))
    np.testing.assert_allclose(rig.triangulate(rig.project(pts)), pts, atol=1e-4)


def test_calibration_round_trip(tmp_path):
    rig = CameraRig((_camera("left"), _camera("right", dist=(0.01, 0.0, 0.0, 0.0))))
    path = tmp_path / "calibration.toml"
    write_calibration(path, rig)
    back = read_calibration(path)
    assert back.names == ["left", "right"]
    for a, b in zip(rig, back):
        np.testing.assert_allclose(a.matrix, b.matrix)
        np.testing.assert_allclose(a.dist, b.dist)
        np.testing.assert_allclose(a.rvec, b.rvec)
        np.testing.assert_allclose(a.tvec, b.tvec)
        assert a.size == b.size


def test_calibration_missing_key_names_file_camera_and_key(tmp_path):
    path = tmp_path / "calibration.toml"
    path.write_text('[cam1]\nname = "cam1"\nsize = [640, 480]\nmatrix = [[500,0,320],[0,500,240],[0,0,1]]\n'
                    'distortions = [0,0,0,0]\nrotation = [0,0,0]\n')
    with pytest.raises(CalibrationError, match=r"calibration.toml.*cam1.*translation"):
        read_calibration(path)


def test_calibration_not_toml(tmp_path):
    path = tmp_path / "calibration.toml"
    path.write_text("[cam1\n")
    with pytest.raises(CalibrationError, match="not valid TOML"):
        read_calibration(path)


def test_distortions_of_every_opencv_length_are_read_and_another_length_is_named():
    """The message said 4, 5 or 8 coefficients while 12 and 14 were accepted too."""
    K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    for n in (4, 5, 8, 12, 14):
        assert Camera("c", (640, 480), K, np.zeros(n)).dist.size == n
    with pytest.raises(CalibrationError, match=r"camera 'c': distortions must hold 4, 5, 8, 12 or 14 finite "
                                               r"coefficients .*got 6"):
        Camera("c", (640, 480), K, np.zeros(6))
