"""Calibration files labs already have: OpenCV YAML/XML and Qualisys ``.qca.txt``.

``calibration.toml`` itself is read and written by :mod:`gaitcap.io.calibration_toml`.

Qualisys (QTM) calibration, as worked out on the Pose2Sim demo (``Calib.qca.txt``) and checked
against its scene images (see ``scripts/check_calibration.py``):

* ``intrinsic``: ``focalLengthU/V`` and ``centerPointU/V`` are in sub-pixel units of 1/64 pixel
  on the sensor; the video image starts at ``fov_video`` ``left``/``top``. Distortion
  ``radialDistortion1..3`` and ``tangentalDistortion1..2`` are OpenCV's k1, k2, k3, p1, p2 as they
  are (our own checkerboard calibration of the same cameras gives k1 ≈ -0.05, k2 ≈ 0.11).
* ``transform``: ``x, y, z`` is the camera centre in the lab frame, millimetres; ``r11..r33`` (row
  major) is the matrix M whose rows are the camera axes in the lab frame for a camera that looks
  along its -z axis with y up in the image. OpenCV's camera looks along +z with y down, so
  ``R_world->cam = diag(1, -1, -1) @ M`` and ``t = -R @ C``. (The other candidates put the lab's
  floor points behind the cameras or 180° off in the images.) Checked again against the 8 floor
  points clicked for Pose2Sim's two scene calibrations (``tests/test_calibration_floor_points.py``):
  the points' layout in each image agrees within the click noise (19.2 px), the wrong candidates
  miss by 580-900 px or fall behind; the whole pattern is offset by 8-27 px per camera (the lab
  frame realised by each system). Those clicks cannot decide the distortion scaling (k/64, as
  Pose2Sim's qca reader has it, moves them < 1 px); Pose2Sim's own checkerboard calibration of
  these cameras (k1 = -0.053, k2 = 0.151 for cam01) supports taking them as they are.
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from gaitcap.camera import Camera, CameraRig
from gaitcap.errors import CalibrationError
from gaitcap.io.atomic import atomic_path

log = logging.getLogger(__name__)

QUALISYS_SUBPIXEL = 64.0
QUALISYS_TO_OPENCV = np.diag([1.0, -1.0, -1.0])


# ----------------------------------------------------------------------------- Qualisys
def read_qualisys(path: str | Path) -> CameraRig:
    """Read a Qualisys ``.qca.txt`` calibration (XML) into a rig; metres, lab frame."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError as e:
        raise CalibrationError(f"{path}: Qualisys calibration file not found") from e
    except (ET.ParseError, OSError) as e:
        raise CalibrationError(f"{path}: not a readable Qualisys XML calibration ({e})") from e
    cams = [_qualisys_camera(node, path) for node in root.iter("camera") if node.get("active", "1") != "0"]
    if not cams:
        raise CalibrationError(f"{path}: no active <camera> in this Qualisys calibration")
    return CameraRig(tuple(cams))


def _qualisys_camera(node: ET.Element, path: Path) -> Camera:
    name = node.get("serial") or "?"
    where = f"{path}: camera {name!r}"
    transform, intrinsic, fov = node.find("transform"), node.find("intrinsic"), node.find("fov_video")
    for tag, el in (("transform", transform), ("intrinsic", intrinsic), ("fov_video", fov)):
        if el is None:
            raise CalibrationError(f"{where}: missing <{tag}>")
    try:
        M = np.array([[float(transform.attrib[f"r{i}{j}"]) for j in "123"] for i in "123"])  # type: ignore[union-attr]
        centre = np.array([float(transform.attrib[k]) for k in "xyz"]) / 1000.0  # type: ignore[union-attr]
        ia = intrinsic.attrib  # type: ignore[union-attr]
        left, top = float(fov.attrib["left"]), float(fov.attrib["top"])  # type: ignore[union-attr]
        w = int(float(fov.attrib["right"]) - left + 1)  # type: ignore[union-attr]
        h = int(float(fov.attrib["bottom"]) - top + 1)  # type: ignore[union-attr]
        fx, fy = float(ia["focalLengthU"]) / QUALISYS_SUBPIXEL, float(ia["focalLengthV"]) / QUALISYS_SUBPIXEL
        cx = float(ia["centerPointU"]) / QUALISYS_SUBPIXEL - left
        cy = float(ia["centerPointV"]) / QUALISYS_SUBPIXEL - top
        k1, k2, k3 = (float(ia.get(f"radialDistortion{i}", 0.0)) for i in (1, 2, 3))
        p1, p2 = (float(ia.get(f"tangentalDistortion{i}", 0.0)) for i in (1, 2))
    except KeyError as e:
        raise CalibrationError(f"{where}: missing attribute {e.args[0]!r}") from e
    except ValueError as e:
        raise CalibrationError(f"{where}: malformed number ({e})") from e
    R = QUALISYS_TO_OPENCV @ M
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-4) or np.linalg.det(R) < 0:
        raise CalibrationError(f"{where}: r11..r33 is not a rotation matrix")
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return Camera(name, (w, h), K, np.array([k1, k2, p1, p2, k3]), cv2.Rodrigues(R)[0].ravel(), -R @ centre)


# ------------------------------------------------------------------------ OpenCV YAML/XML
def read_opencv_camera(path: str | Path, name: str | None = None) -> Camera:
    """Read an OpenCV ``FileStorage`` calibration (``left_intrinsics.yml`` style, YAML or XML).

    Required: ``camera_matrix``, ``distortion_coefficients``, ``image_width``, ``image_height``.
    Optional extrinsics: ``rotation`` (3x3 matrix or Rodrigues vector, world -> camera) and
    ``translation`` (metres). The camera is named ``name`` or ``camera_name`` or the file stem.
    """
    path = Path(path)
    if not path.is_file():
        raise CalibrationError(f"{path}: OpenCV calibration file not found")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except cv2.error as e:
        raise CalibrationError(f"{path}: not an OpenCV YAML/XML file ({e.err})") from e
    try:
        if not fs.isOpened():
            raise CalibrationError(f"{path}: not an OpenCV YAML/XML file")
        K = _mat(fs, "camera_matrix", path)
        dist = _mat(fs, "distortion_coefficients", path).ravel()
        w, h = _number(fs, "image_width", path), _number(fs, "image_height", path)
        rvec, tvec = np.zeros(3), np.zeros(3)
        if not fs.getNode("rotation").empty():
            rot = _mat(fs, "rotation", path)
            rvec = cv2.Rodrigues(rot)[0].ravel() if rot.size == 9 else rot.ravel()
            tvec = _mat(fs, "translation", path).ravel()
        cam_name = name or (fs.getNode("camera_name").string() if not fs.getNode("camera_name").empty() else "") or path.stem
    finally:
        fs.release()
    try:
        return Camera(cam_name, (int(w), int(h)), K.reshape(3, 3), dist, rvec, tvec)
    except (CalibrationError, ValueError) as e:
        raise CalibrationError(f"{path}: {e}") from e


def read_opencv_error(path: str | Path) -> float | None:
    """The ``avg_reprojection_error`` (px) an OpenCV calibration file records, or None (absent)."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        node = fs.getNode("avg_reprojection_error")
        return None if node.empty() else float(node.real())
    finally:
        fs.release()


def _mat(fs: cv2.FileStorage, key: str, path: Path) -> np.ndarray:
    node = fs.getNode(key)
    if node.empty():
        raise CalibrationError(f"{path}: missing key '{key}'")
    mat = node.mat()
    if mat is None:
        raise CalibrationError(f"{path}: key '{key}' is not an OpenCV matrix")
    return np.asarray(mat, dtype=np.float64)


def _number(fs: cv2.FileStorage, key: str, path: Path) -> float:
    node = fs.getNode(key)
    if node.empty():
        raise CalibrationError(f"{path}: missing key '{key}'")
    return float(node.real())


def write_opencv_camera(path: str | Path, camera: Camera, metadata: dict | None = None) -> None:
    """Write one camera as OpenCV ``FileStorage`` YAML (``.yml``/``.yaml``) or XML (``.xml``)."""
    path = Path(path)
    if path.suffix.lower() not in (".yml", ".yaml", ".xml"):
        raise CalibrationError(f"{path}: an OpenCV calibration file ends in .yml, .yaml or .xml")
    with atomic_path(path, suffix=path.suffix) as tmp:
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE)
        fs.write("camera_name", camera.name)
        fs.write("image_width", int(camera.width))
        fs.write("image_height", int(camera.height))
        fs.write("camera_matrix", camera.matrix)
        fs.write("distortion_coefficients", camera.dist.reshape(-1, 1))
        fs.write("rotation", camera.R)
        fs.write("translation", camera.tvec.reshape(3, 1))
        for key, value in (metadata or {}).items():
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                fs.write(key, float(value))
        fs.release()


# --------------------------------------------------------------------------- frame size
def fit_to_frame_size(camera: Camera, size: tuple[int, int]) -> Camera:
    """The camera for frames of ``size`` (w, h) that are a centred crop (or pad) of its image.

    Some encoders crop a few columns: the Pose2Sim demo declares 1088x1920 but cam01/cam02 decode
    at 1080x1920, 4 columns lost on each side (the best shift between the scene image and the
    first video frame is 3-4 px). The principal point moves by half the difference; focal lengths
    and distortion are unchanged. Differences above 5 % are refused (probably a resize, not a crop).
    """
    w, h = (int(v) for v in size)
    if (w, h) == camera.size:
        return camera
    dw, dh = camera.width - w, camera.height - h
    if abs(dw) > 0.05 * camera.width or abs(dh) > 0.05 * camera.height:
        raise CalibrationError(
            f"camera {camera.name!r}: frames are {w}x{h} but the calibration is {camera.width}x{camera.height}; "
            "recalibrate (a resize is not a crop)"
        )
    log.warning(
        "camera %r: frames are %dx%d, calibration %dx%d: assuming a centred crop, principal point moved by (%g, %g) px",
        camera.name, w, h, camera.width, camera.height, -dw / 2, -dh / 2,
    )
    K = camera.matrix.copy()
    K[0, 2] -= dw / 2
    K[1, 2] -= dh / 2
    return replace(camera, size=(w, h), matrix=K)
