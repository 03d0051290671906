"""The imported Qualisys calibration of the Pose2Sim demo against the floor points clicked for Pose2Sim.

The references (``floor_points_demo.yaml``, ``floor_points_singleperson.yaml``) are the 8 floor
points projected through Pose2Sim's two scene calibrations of the same cameras, each solved from
points clicked in ``camNN_ext.png`` (see the fixture README). Their disagreement is the click noise;
the bounds below are that measured noise, not a number chosen to pass.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from gaitcap.calibration.extrinsics import ScenePoints, scene_pixel_disagreement
from gaitcap.calibration.formats import QUALISYS_TO_OPENCV, read_qualisys
from gaitcap.camera import Camera, CameraRig
from gaitcap.config import load_yaml_model
from gaitcap.io.calibration_toml import read_calibration, write_calibration

QUALISYS = Path(__file__).resolve().parent / "fixtures" / "calibration" / "pose2sim_qualisys"
REFERENCES = ("floor_points_demo.yaml", "floor_points_singleperson.yaml")


@pytest.fixture(scope="module")
def refs() -> list[ScenePoints]:
    return [load_yaml_model(ScenePoints, QUALISYS / name) for name in REFERENCES]


@pytest.fixture(scope="module")
def click_noise_px(refs) -> float:
    """Largest disagreement (px) between the two clickings over all cameras and points."""
    noise = scene_pixel_disagreement(*refs)
    assert sorted(noise) == ["cam01", "cam02", "cam03", "cam04"] and all(len(v) == 8 for v in noise.values())
    return max(max(v.values()) for v in noise.values())


@pytest.fixture(scope="module")
def imported(tmp_path_factory) -> CameraRig:
    """The Qualisys import as a session holds it: written to calibration.toml and read back."""
    path = tmp_path_factory.mktemp("qualisys") / "calibration.toml"
    write_calibration(path, read_qualisys(QUALISYS / "Calib.qca.txt"))
    return read_calibration(path)


def _residuals(cam: Camera, ref: ScenePoints) -> np.ndarray:
    """Projection minus reference pixel, (8, 2); NaN for points behind the camera."""
    names = list(ref.points)
    ours = cam.project(np.array([ref.points[n] for n in names]))
    return ours - np.array([ref.pixels[cam.name][n] for n in names])


def _layout_error(rig: CameraRig, ref: ScenePoints) -> dict[str, float]:
    """Per camera, the largest residual (px) once the camera's mean offset is removed (NaN if any point is behind)."""
    out = {}
    for cam in rig:
        r = _residuals(cam, ref)
        out[cam.name] = float(np.max(np.linalg.norm(r - r.mean(axis=0), axis=1)))
    return out


def _with_orientation(rig: CameraRig, convention) -> CameraRig:
    """The same cameras (centres, intrinsics) with R_world->cam = convention(M) instead of diag(1,-1,-1) @ M."""
    cams = []
    for cam in rig:
        M = QUALISYS_TO_OPENCV @ cam.R  # the r11..r33 of the file (the fix is its own inverse)
        R = convention(M)
        cams.append(replace(cam, rvec=cv2.Rodrigues(R)[0].ravel(), tvec=-R @ cam.center))
    return CameraRig(tuple(cams))


def test_references_describe_the_imported_cameras(refs, imported):
    # same cameras, same image size; every floor point inside each image for both clickings
    for ref in refs:
        assert sorted(ref.pixels) == imported.names
        for cam in imported:
            uv = np.array(list(ref.pixels[cam.name].values()))
            assert cam.in_image(uv).all(), cam.name


def test_floor_point_layout_within_click_noise(refs, imported, click_noise_px):
    # The per-camera mean offset depends on where the lab frame was realised on the floor for
    # each system (Qualisys wand / the clicker's idea of the floor points); what remains, the
    # layout of the 8 points in the image, is set by the orientation convention, focal length and
    # distortion. It must agree with the clicks to within the click noise.
    for ref in refs:
        for cam, err in _layout_error(imported, ref).items():
            assert err <= click_noise_px, f"{cam}: {err:.1f} px > click noise {click_noise_px:.1f} px"


@pytest.mark.parametrize(
    "convention",
    [
        pytest.param(lambda M: M, id="M as world->cam (no diag(1,-1,-1))"),
        pytest.param(lambda M: M.T, id="M transposed"),
        pytest.param(lambda M: np.diag([-1.0, -1.0, 1.0]) @ QUALISYS_TO_OPENCV @ M, id="half turn about the optical axis"),
    ],
)
def test_wrong_orientation_convention_fails_the_floor_points(refs, imported, click_noise_px, convention):
    wrong = _with_orientation(imported, convention)
    for ref in refs:
        errors = _layout_error(wrong, ref)
        # NaN (points behind the camera) counts as failing
        assert not all(err <= click_noise_px for err in errors.values()), errors


@pytest.mark.xfail(
    strict=True,
    reason="measured: per-camera mean error 19.5/26.3/24.2/7.9 px (vs Demo) and 18.3/23.6/26.7/8.8 px "
    "(vs SinglePerson) against a click noise of at most 19.2 px: the Qualisys lab frame and the clicked "
    "floor points do not coincide to click precision (scripts/check_calibration.py --only qualisys); the "
    "import equals Pose2Sim's own conversion of the file (test below), so the offsets are the data's",
)
def test_floor_points_land_within_click_noise(refs, imported, click_noise_px):
    for ref in refs:
        for cam in imported:
            mean = float(np.mean(np.linalg.norm(_residuals(cam, ref), axis=1)))
            assert mean <= click_noise_px, f"{cam.name}: {mean:.1f} px"


def test_import_equals_pose2sims_own_conversion_of_the_same_file(refs, imported):
    # Pose2Sim's Calib_qualisys.toml (its conversion of this Calib.qca.txt, fixture README): the
    # same intrinsics and the same world->camera rotation and translation. So the floor-point
    # offsets of the xfail below belong to the data (the Qualisys calibration vs the clicked scene
    # calibrations), not to the import. Pose2Sim divides the distortion coefficients by 64 as well;
    # we keep them as written (the file's units for them are undocumented): on the 8 floor points
    # the two readings differ by at most 2.7 px (measured), against offsets of 8-27 px.
    theirs = read_calibration(QUALISYS / "Calib_qualisys_pose2sim.toml")
    assert theirs.names == imported.names
    for ours, ref in zip(imported, theirs, strict=True):
        assert ours.size == ref.size
        np.testing.assert_allclose(ours.matrix, ref.matrix, atol=1e-6)
        np.testing.assert_allclose(ours.R, ref.R, atol=1e-7)
        np.testing.assert_allclose(ours.tvec, ref.tvec, atol=1e-7)
        np.testing.assert_allclose(np.asarray(ours.dist)[:4] / 64.0, np.asarray(ref.dist)[:4], rtol=1e-6)
        pts = np.array(list(refs[0].points.values()))
        assert np.max(np.linalg.norm(ours.project(pts) - ref.project(pts), axis=1)) <= 3.0
