from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from gaitcap.calibration.boards import Board, detect_board, parse_board_size, parse_length
from gaitcap.calibration.extrinsics import (
    ScenePoints,
    calibrate_from_board,
    calibrate_from_points,
    calibrate_stereo,
    scene_reprojection,
)
from gaitcap.calibration.formats import fit_to_frame_size, read_opencv_camera, read_qualisys, write_opencv_camera
from gaitcap.calibration.intrinsics import calibrate_intrinsics, coverage, select_spread
from gaitcap.calibration.synthetic import render_board_view
from gaitcap.calibration.views import ViewSet, detect_views, paired_views
from gaitcap.camera import Camera
from gaitcap.cli.main import cli
from gaitcap.config import load_yaml_model
from gaitcap.errors import CalibrationError, ConfigError, InputError
from gaitcap.io.calibration_toml import read_calibration, read_calibration_metadata, write_calibration

FIX = Path(__file__).resolve().parent / "fixtures" / "calibration"
CHESS = FIX / "opencv_chessboard_9x6"
QUALISYS = FIX / "pose2sim_qualisys"
BOARD96 = Board(9, 6, 0.025)


@pytest.fixture(scope="module")
def left_views():
    return detect_views(sorted(CHESS.glob("left*.jpg")), BOARD96, max_blur=0.25)


# ------------------------------------------------------------------------- boards
def test_parse_board_and_lengths():
    assert parse_board_size("9x6") == (9, 6)
    assert parse_length("25mm") == pytest.approx(0.025)
    assert parse_length("2.5cm") == pytest.approx(0.025)
    assert parse_length("0.06m") == pytest.approx(0.06)
    for bad in ("9by6", "x6"):
        with pytest.raises(ConfigError, match="COLSxROWS"):
            parse_board_size(bad)
    with pytest.raises(ConfigError, match="mm"):
        parse_length("25 inches")


def test_object_points_frame_is_z_up_right_handed():
    pts = Board(4, 3, 0.1).object_points()
    assert pts.shape == (12, 3)
    np.testing.assert_allclose(pts[1], [0.1, 0, 0])
    np.testing.assert_allclose(pts[4], [0, -0.1, 0])


def test_detection_order_is_canonical_under_a_half_turn(left_views):
    img = cv2.imread(str(CHESS / "left01.jpg"), cv2.IMREAD_GRAYSCALE)
    a = detect_board(img, BOARD96, "a")
    b = detect_board(cv2.rotate(img, cv2.ROTATE_180), BOARD96, "b")
    h, w = img.shape
    turned = np.c_[w - 1 - b.corners[:, 0], h - 1 - b.corners[:, 1]]
    np.testing.assert_allclose(turned, a.corners, atol=0.3)


# --------------------------------------------------------------------- intrinsics
def test_opencv_sample_matches_reference(left_views):
    ref = read_opencv_camera(CHESS / "left_intrinsics.yml")
    assert len(left_views.detections) == 13
    res = calibrate_intrinsics(left_views.detections, BOARD96, "left", fix_aspect_ratio=True)
    K, R = res.camera.matrix, ref.matrix
    for (i, j) in [(0, 0), (1, 1), (0, 2), (1, 2)]:
        assert abs(K[i, j] - R[i, j]) < 1.0
    assert abs(res.rms_px - 0.393) < 0.05
    assert K[0, 0] == pytest.approx(K[1, 1])
    worst = max(res.per_view_px, key=res.per_view_px.get)
    assert worst == "left02.jpg"  # the reference also names left02 its worst view (1.18 px)


def test_pose2sim_focal_within_1p5_percent_of_qualisys():
    views = detect_views([QUALISYS / "int_cam01_half"], Board(4, 7, 0.06), max_blur=0.25)
    assert len(views.detections) >= 4 and "cam01_02_int.jpg" in views.rejected
    res = calibrate_intrinsics(views.detections, Board(4, 7, 0.06), "cam01")
    ref = read_qualisys(QUALISYS / "Calib.qca.txt")["cam01"].matrix
    for i in (0, 1):
        assert abs(2 * res.camera.matrix[i, i] / ref[i, i] - 1) < 0.015


def test_select_spread_keeps_distinct_views(left_views):
    dets = left_views.detections
    doubled = dets + [replace(d, source=d.source + "-copy") for d in dets]
    chosen = select_spread(doubled, len(dets))
    assert len(chosen) == len(dets)
    assert len({c.source.removesuffix("-copy") for c in chosen}) >= len(dets) - 2
    frac, empty = coverage(dets[:1], (640, 480))
    assert 0 < frac < 1 and empty


def test_fewer_than_three_views_is_an_error(left_views):
    with pytest.raises(CalibrationError, match="only 2 usable view"):
        calibrate_intrinsics(left_views.detections[:2], BOARD96, "left")


# --------------------------------------------------------------------- extrinsics
def _rig_truth():
    t = [0.5, -0.3, 0.0]
    return [
        Camera.look_at("c1", [2.5, -2.0, 2.2], t, focal_px=800, dist=(-0.1, 0.02, 0.0, 0.0)),
        Camera.look_at("c2", [-1.5, -2.5, 2.0], t, focal_px=800),
        Camera.look_at("c3", [0.8, 2.2, 2.5], t, focal_px=700),
    ]


def _angle_deg(a: Camera, b: Camera) -> float:
    return float(np.degrees(np.linalg.norm(cv2.Rodrigues(a.R @ b.R.T)[0])))


@pytest.mark.parametrize("n_positions", [1, 3])
def test_floor_board_extrinsics_recover_known_cameras(n_positions):
    board = Board(9, 6, 0.12)
    truth = _rig_truth()
    poses = [(np.zeros(3), np.zeros(3)), (np.array([0, 0, 0.5]), np.array([-0.3, 0.4, 0])),
             (np.array([0, 0, -0.4]), np.array([0.3, -0.5, 0]))][:n_positions]
    rng = np.random.default_rng(7)
    frames = {c.name: [detect_board(render_board_view(c, board, p, rng), board, f"{c.name}#{k}") for k, p in enumerate(poses)]
              for c in truth}
    assert all(d is not None for fr in frames.values() for d in fr)
    intr = [Camera(c.name, c.size, c.matrix, c.dist) for c in truth]
    res = calibrate_from_board(intr, frames, board)
    assert res.n_positions == n_positions and res.adjusted == (n_positions > 1)
    for est, true in zip(res.rig, truth):
        assert np.linalg.norm(est.center - true.center) < 0.005
        assert _angle_deg(est, true) < 0.2
        assert est.center[2] > 0  # z up: the cameras are above the floor
    assert max(res.rms_px.values()) < 0.3
    assert res.check_mm < 2.0


def test_scene_points_extrinsics(rng):
    truth = _rig_truth()
    pts = {f"q{i}": tuple(p) for i, p in enumerate(rng.uniform([-1, -1, 0], [1.5, 1, 0.3], size=(8, 3)))}
    pixels = {c.name: {n: tuple(c.project(np.array(p)[None])[0] + rng.normal(0, 0.3, 2)) for n, p in pts.items()} for c in truth}
    pixels["c3"]["q0"] = None
    scene = ScenePoints(points=pts, pixels=pixels)
    res = calibrate_from_points([Camera(c.name, c.size, c.matrix, c.dist) for c in truth], scene)
    for est, true in zip(res.rig, truth):
        assert np.linalg.norm(est.center - true.center) < 0.03
    assert res.check_mm < 10


def test_scene_points_need_four_per_camera(rng):
    cam = _rig_truth()[1]
    pts = {f"q{i}": (float(i), 0.0, 0.0) for i in range(4)}
    scene = ScenePoints(points=pts, pixels={"c2": {"q0": (1, 2), "q1": (3, 4), "q2": None, "q3": None}})
    with pytest.raises(CalibrationError, match=r"camera 'c2'.*2 point"):
        calibrate_from_points([cam], scene, "scene.yaml")


def test_stereo_on_opencv_pairs(left_views):
    right = detect_views(sorted(CHESS.glob("right*.jpg")), BOARD96)
    cl = calibrate_intrinsics(left_views.detections, BOARD96, "left", fix_aspect_ratio=True).camera
    cr = calibrate_intrinsics(right.detections, BOARD96, "right", fix_aspect_ratio=True).camera
    pairs = [(a, b) for a, b in zip(left_views.frames, right.frames) if a is not None and b is not None]
    res = calibrate_stereo(cl, cr, pairs, BOARD96)
    assert res.epipolar_px < 1.0
    assert 0.02 < res.baseline_m < 0.5
    assert res.rig["right"].center[0] < 0 or res.rig["right"].center[0] > 0  # a real translation


# -------------------------------------------------------------------- formats
def test_qualisys_convention_puts_lab_points_where_the_images_show_them():
    rig = read_qualisys(QUALISYS / "Calib.qca.txt")
    assert rig.names == ["cam01", "cam02", "cam03", "cam04"]
    assert rig["cam01"].matrix[0, 0] == pytest.approx(107599.671875 / 64)
    assert rig["cam01"].size == (1088, 1920)
    np.testing.assert_allclose(rig["cam01"].center, [1.4602, -1.9092, 1.8965], atol=1e-3)
    scene = load_yaml_model(ScenePoints, QUALISYS / "scene_points.yaml")
    errors = scene_reprojection(rig, scene)
    worst = max(max(v.values()) for v in errors.values())
    # a half turn about the optical axis (the other convention that keeps the floor in front)
    turned = [replace(c, rvec=cv2.Rodrigues(np.diag([-1.0, -1, 1]) @ c.R)[0].ravel(), tvec=np.diag([-1.0, -1, 1]) @ c.tvec) for c in rig]
    from gaitcap.camera import CameraRig
    worst_turned = min(max(v.values()) for v in scene_reprojection(CameraRig(tuple(turned)), scene).values())
    assert worst < 0.03 * 1920 < worst_turned


def test_qualisys_without_cameras(tmp_path):
    bad = tmp_path / "empty.qca.txt"
    bad.write_text("<?xml version='1.0'?><calibration><cameras></cameras></calibration>")
    with pytest.raises(CalibrationError, match=r"empty.qca.txt.*no active <camera>"):
        read_qualisys(bad)


@pytest.mark.parametrize("suffix", ["yml", "xml"])
def test_opencv_file_round_trip(tmp_path, suffix):
    cam = read_qualisys(QUALISYS / "Calib.qca.txt")["cam02"]
    write_opencv_camera(tmp_path / f"cam02.{suffix}", cam, {"avg_reprojection_error": 0.3})
    back = read_opencv_camera(tmp_path / f"cam02.{suffix}")
    assert back.name == "cam02" and back.size == cam.size
    np.testing.assert_allclose(back.matrix, cam.matrix)
    np.testing.assert_allclose(back.dist, cam.dist)
    np.testing.assert_allclose(back.center, cam.center, atol=1e-9)


def test_toml_round_trip_of_imported_qualisys(tmp_path):
    rig = read_qualisys(QUALISYS / "Calib.qca.txt")
    write_calibration(tmp_path / "calibration.toml", rig, {"source": "Calib.qca.txt"})
    back = read_calibration(tmp_path / "calibration.toml")
    pts = np.array([[0.0, 0.0, 0.0], [-2.0, 0.3, 0.0]])
    np.testing.assert_allclose(back.project(pts), rig.project(pts), atol=1e-6)


def test_opencv_file_missing_key(tmp_path):
    text = (CHESS / "left_intrinsics.yml").read_text()
    bad = tmp_path / "bad.yml"
    bad.write_text(re.sub(r"distortion_coefficients:.*?\]", "", text, flags=re.S))
    with pytest.raises(CalibrationError, match=r"bad.yml: missing key 'distortion_coefficients'"):
        read_opencv_camera(bad)


def test_fit_to_frame_size_is_a_centred_crop():
    cam = read_qualisys(QUALISYS / "Calib.qca.txt")["cam01"]
    fitted = fit_to_frame_size(cam, (1080, 1920))
    assert fitted.size == (1080, 1920)
    p = np.array([[0.0, 0.0, 0.0]])
    np.testing.assert_allclose(fitted.project(p), cam.project(p) - [4.0, 0.0])
    with pytest.raises(CalibrationError, match="cam01"):
        fit_to_frame_size(cam, (540, 960))


# ---------------------------------------------------------------------------- CLI
def _run(*args):
    return CliRunner().invoke(cli, ["calibrate", *map(str, args)])


def test_cli_intrinsics_writes_toml_with_metadata(tmp_path):
    out = tmp_path / "left.toml"
    r = _run("intrinsics", *sorted(CHESS.glob("left0*.jpg")), "--board", "9x6", "--square", "25mm", "-o", out)
    assert r.exit_code == 0, r.output
    assert "RMS reprojection error" in r.output
    assert read_calibration(out).names == ["left"]
    assert read_calibration_metadata(out)["intrinsics_views"]["left"] == 9


def test_cli_wrong_board_size_names_the_files(tmp_path):
    r = _run("intrinsics", CHESS / "left01.jpg", CHESS / "left02.jpg", CHESS / "left03.jpg", "--board", "7x5", "-o", tmp_path / "x.toml")
    assert r.exit_code == 1
    assert "only 0 usable view" in r.output and "left02.jpg: checkerboard 7x5" in r.output


def test_a_board_given_smaller_than_it_is_is_warned_about(tmp_path):
    """--board 8x6 on a 9x6 board: OpenCV finds an 8x6 part of it; the first view is checked for a larger
    pattern and the user told (the origin would be a square off, the board possibly turned round)."""
    images = sorted(CHESS.glob("left0*.jpg"))
    r = _run("intrinsics", *images, "--board", "8x6", "--square", "25mm", "-o", tmp_path / "part.toml")
    assert r.exit_code == 0, r.output
    assert "the board shows 9x6 inner corners or more, more than the 8x6 given: give its full size" in r.output
    r = _run("intrinsics", *images, "--board", "9x6", "--square", "25mm", "-o", tmp_path / "whole.toml")
    assert r.exit_code == 0 and "inner corners or more" not in r.output


def test_cli_no_board_in_image(tmp_path):
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640), 128, np.uint8))
    r = _run("intrinsics", blank, "-o", tmp_path / "x.toml")
    assert r.exit_code == 1 and "usable view" in r.output and "blank.png: checkerboard 9x6" in r.output


def test_cli_images_of_different_sizes(tmp_path):
    small = tmp_path / "small.jpg"
    cv2.imwrite(str(small), cv2.resize(cv2.imread(str(CHESS / "left01.jpg")), (320, 240)))
    r = _run("intrinsics", CHESS / "left01.jpg", small, "-o", tmp_path / "x.toml")
    assert r.exit_code == 1 and "small.jpg" in r.output and "differs" in r.output


def test_cli_refuses_an_existing_output_before_the_work(tmp_path):
    out = tmp_path / "left.toml"
    out.write_text("# a calibration of before\n")
    for args in (("intrinsics", CHESS / "left01.jpg"), ("stereo", CHESS, CHESS)):
        r = _run(*args, "--board", "9x6", "--square", "25mm", "-o", out)
        assert r.exit_code == 1 and "left.toml: exists already (use --force" in r.output
        assert "views used" not in r.output and "pairs:" not in r.output  # refused before detecting any board
    assert out.read_text() == "# a calibration of before\n"
    r = _run("intrinsics", CHESS / "left01.jpg", "--board", "9x6", "--square", "25mm", "-o", tmp_path / "left.txt")
    assert r.exit_code == 1 and "left.txt: unknown calibration file type" in r.output


def test_cli_numeric_options_out_of_range_are_usage_errors(tmp_path):
    """--video-step 0 divided by zero on a video (a traceback), --max-views 0 used every view and 1 or 2
    calibrated from fewer than the 3 views calibrate_intrinsics asks for, a --max-blur or --max-error of
    0 or below refused every view or camera: each is now a usage error naming the option."""
    images = sorted(CHESS.glob("left0*.jpg"))
    video = tmp_path / "board.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10, (640, 480))
    for path in images[:3]:
        writer.write(cv2.imread(str(path)))
    writer.release()
    cases = [("intrinsics", video, "--video-step", "0"), ("intrinsics", *images, "--max-views", "0"),
             ("intrinsics", *images, "--max-views", "2"), ("intrinsics", *images, "--max-blur", "-1"),
             ("stereo", CHESS, CHESS, "--max-error", "0"),
             ("extrinsics", tmp_path, "--video-step", "0"), ("extrinsics", tmp_path, "--max-error", "-1")]
    for i, args in enumerate(cases):
        out = () if args[0] == "extrinsics" else ("-o", tmp_path / f"out{i}.toml")
        r = _run(*args, *out)
        option = next(a for a in args if str(a).startswith("--"))
        assert r.exit_code == 2 and f"Invalid value for '{option}'" in r.output, (args, r.output)
        assert "Traceback" not in r.output and not (tmp_path / f"out{i}.toml").exists()
    r = _run("check", tmp_path, "--max-error", "0")
    assert r.exit_code == 2 and "Invalid value for '--max-error'" in r.output


def test_cli_check_missing_key(tmp_path):
    bad = tmp_path / "calibration.toml"
    bad.write_text('[cam1]\nname = "cam1"\nsize = [640, 480]\nmatrix = [[500,0,320],[0,500,240],[0,0,1]]\n'
                   'distortions = [0,0,0,0]\nrotation = [0,0,0]\n')
    r = _run("check", tmp_path)
    assert r.exit_code == 1 and "calibration.toml" in r.output and "translation" in r.output


def test_cli_import_qualisys_then_check(tmp_path):
    out = tmp_path / "calibration.toml"
    assert _run("import-qualisys", QUALISYS / "Calib.qca.txt", "-o", out).exit_code == 0
    r = _run("check", out)
    assert r.exit_code == 0, r.output
    assert "cam01 - cam02: 2.854" in r.output
    r = _run("import-qualisys", QUALISYS / "Calib.qca.txt", "-o", out)
    assert r.exit_code == 1 and "--force" in r.output


def test_check_keeps_its_table_aligned_with_long_camera_names():
    from gaitcap.calibration.quality import check_rig
    from gaitcap.camera import CameraRig

    rig = read_qualisys(QUALISYS / "Calib.qca.txt")
    named = CameraRig(tuple(replace(c, name=n) for c, n in zip(rig, ("left_intrinsics_cam", "c2", "c3", "c4"))))
    header, *rows = check_rig(named).lines[:5]
    assert len({row.index(f"{cam.width:>5}x{cam.height}") + 5 for row, cam in zip(rows, named)}) == 1
    height = str(named[0].height)
    assert header.index("size") + 4 == rows[0].index(f"x{height}") + 1 + len(height)  # ends under its title


def test_cli_check_flags_poor_calibration(tmp_path):
    rig = read_qualisys(QUALISYS / "Calib.qca.txt")
    write_calibration(tmp_path / "calibration.toml", rig, {"error": 3.2, "reprojection_rms_px": {"cam02": 3.2}})
    r = _run("check", tmp_path)
    assert r.exit_code == 1 and "cam02" in r.output and "3.20 px" in r.output


def test_cli_qualisys_without_cameras(tmp_path):
    bad = tmp_path / "none.qca.txt"
    bad.write_text("<calibration><cameras/></calibration>")
    r = _run("import-qualisys", bad, "-o", tmp_path / "c.toml")
    assert r.exit_code == 1 and "none.qca.txt" in r.output


def test_cli_export_and_reimport(tmp_path):
    out = tmp_path / "opencv"
    assert _run("export", QUALISYS / "Calib.qca.txt", "-o", out, "--format", "xml").exit_code == 0
    r = _run("import-opencv", *sorted(out.glob("*.xml")), "-o", tmp_path / "calibration.toml")
    assert r.exit_code == 0, r.output
    back = read_calibration(tmp_path / "calibration.toml")
    np.testing.assert_allclose(back["cam03"].center, read_qualisys(QUALISYS / "Calib.qca.txt")["cam03"].center, atol=1e-9)


def test_import_and_export_keep_each_cameras_own_error(tmp_path):
    """import-opencv keeps a file's avg_reprojection_error as that camera's intrinsics error (check shows it);
    export writes each camera's own error, and none where none was measured (it wrote the rig's overall
    error, or 0, into every file)."""
    toml = tmp_path / "calibration.toml"
    assert _run("import-opencv", CHESS / "left_intrinsics.yml", "-o", toml).exit_code == 0
    meta = read_calibration_metadata(toml)
    assert meta["intrinsics_rms_px"] == {"left_intrinsics": pytest.approx(0.39259, abs=1e-5)}
    assert "left_intrinsics 0.393" in _run("check", toml).output
    assert _run("export", toml, "-o", tmp_path / "yml").exit_code == 0
    fs = cv2.FileStorage(str(tmp_path / "yml" / "left_intrinsics.yml"), cv2.FILE_STORAGE_READ)
    assert fs.getNode("avg_reprojection_error").real() == pytest.approx(0.39259, abs=1e-5)
    fs.release()
    assert _run("export", QUALISYS / "Calib.qca.txt", "-o", tmp_path / "q").exit_code == 0  # not measured here
    fs = cv2.FileStorage(str(tmp_path / "q" / "cam01.yml"), cv2.FILE_STORAGE_READ)
    assert fs.getNode("avg_reprojection_error").empty()
    fs.release()


def test_cli_extrinsics_from_floor_board(tmp_path):
    board = Board(9, 6, 0.12)
    truth = _rig_truth()[:2]
    session = tmp_path / "s"
    (session / "extrinsics").mkdir(parents=True)
    rng = np.random.default_rng(3)
    for c in truth:
        cv2.imwrite(str(session / "extrinsics" / f"{c.name}.png"), render_board_view(c, board, rng=rng))
    from gaitcap.camera import CameraRig
    write_calibration(session / "calibration.toml", CameraRig(tuple(Camera(c.name, c.size, c.matrix, c.dist) for c in truth)))
    before = (session / "calibration.toml").read_text()
    r = _run("extrinsics", session, "--board", "9x6", "--square", "120mm")
    assert r.exit_code == 0, r.output
    assert (session / "calibration.toml.bak").read_text() == before  # the calibration it replaced, kept
    assert "previous one kept as calibration.toml.bak" in r.output
    rig = read_calibration(session / "calibration.toml")
    for est, true in zip(rig, truth):
        assert np.linalg.norm(est.center - true.center) < 0.005
    meta = read_calibration_metadata(session / "calibration.toml")
    assert set(meta["reprojection_rms_px"]) == {"c1", "c2"} and meta["check_3d_mm"] >= 0
    first = (session / "calibration.toml").read_text()
    r = _run("extrinsics", session, "--board", "9x6", "--square", "120mm")  # again: no earlier copy is replaced
    assert r.exit_code == 0, r.output
    assert "previous one kept as calibration.toml.bak2" in r.output
    assert (session / "calibration.toml.bak").read_text() == before
    assert (session / "calibration.toml.bak2").read_text() == first


def _points_session(tmp_path: Path, rng: np.random.Generator, cameras: int = 2) -> tuple[Path, Path, dict]:
    """A session folder whose calibration.toml holds the intrinsics of ``cameras`` of the known rig, and
    a scene points file of 8 points seen by every camera (0.3 px of click noise); returns both and the YAML."""
    truth = _rig_truth()[:cameras]
    session = tmp_path / "s"
    session.mkdir()
    from gaitcap.camera import CameraRig

    write_calibration(session / "calibration.toml", CameraRig(tuple(Camera(c.name, c.size, c.matrix, c.dist) for c in truth)))
    pts = {f"q{i}": [float(v) for v in p] for i, p in enumerate(rng.uniform([-1, -1, 0], [1.5, 1, 0.3], size=(8, 3)))}
    pixels = {c.name: {n: [float(v) for v in c.project(np.array(p)[None])[0] + rng.normal(0, 0.3, 2)]
                       for n, p in pts.items()} for c in truth}  # fmt: skip
    doc = {"points": pts, "pixels": pixels}
    points = tmp_path / "points.yaml"
    points.write_text(yaml.safe_dump(doc))
    return session, points, doc


def test_cli_extrinsics_refuses_a_poor_result_and_names_the_worst_points(tmp_path, rng):
    """Two of a camera's clicks swapped: its reprojection RMS is tens of pixels; calibration.toml is not
    written (nor a backup made) and the two points are named; --max-error accepts it."""
    session, points, doc = _points_session(tmp_path, rng)
    doc["pixels"]["c2"]["q1"], doc["pixels"]["c2"]["q5"] = doc["pixels"]["c2"]["q5"], doc["pixels"]["c2"]["q1"]
    points.write_text(yaml.safe_dump(doc))
    before = (session / "calibration.toml").read_text()
    r = _run("extrinsics", session, "--points", points)
    assert r.exit_code == 1 and "calibration.toml: not written: a poor calibration" in r.output
    worst = re.search(r"camera 'c2': reprojection RMS [\d.]+ px > 1 px \(worst points, each against the pose the points "
                      r"that agree give: (\w+) [\d.]+ px, (\w+)", r.output)  # fmt: skip
    assert worst and set(worst.groups()) == {"q1", "q5"}, r.output
    assert (session / "calibration.toml").read_text() == before and not (session / "calibration.toml.bak").exists()
    r = _run("extrinsics", session, "--points", points, "--max-error", "100")
    assert r.exit_code == 0, r.output


def test_cli_extrinsics_names_the_one_wrong_click_first(tmp_path, rng):
    """One click 86 px off: a pose fitted to all 8 points spreads its error over the good ones (they were
    named before it); against the pose of the 7 points that agree it stands out, the others within a few px."""
    session, points, doc = _points_session(tmp_path, rng)
    u, v = doc["pixels"]["c1"]["q0"]
    doc["pixels"]["c1"]["q0"] = [u + 70.0, v - 50.0]
    points.write_text(yaml.safe_dump(doc))
    r = _run("extrinsics", session, "--points", points)
    assert r.exit_code == 1, r.output
    worst = re.search(r"camera 'c1': .*that agree give: (\w+) ([\d.]+) px, \w+ ([\d.]+) px", r.output)
    assert worst and worst.group(1) == "q0", r.output
    assert float(worst.group(2)) > 60 and float(worst.group(3)) < 3, r.output


def test_cli_extrinsics_names_the_views_without_a_board_and_the_clicks_left_out(tmp_path, rng, caplog):
    session, points, doc = _points_session(tmp_path, rng)
    doc["pixels"]["cam9"] = doc["pixels"]["c2"]  # a camera no intrinsics describe (a typo, or left out)
    points.write_text(yaml.safe_dump(doc))
    r = _run("extrinsics", session, "--points", points)
    assert r.exit_code == 0, r.output
    assert "pixels of camera(s) cam9 left out: no intrinsics describe them (cameras: c1, c2)" in r.output
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640), 128, np.uint8))
    r = _run("extrinsics", session, "--board", "9x6", "--square", "120mm", "--views", f"c1={blank}",
             "--views", f"c2={blank}")  # fmt: skip
    assert r.exit_code == 1 and f"{blank}: camera 'c1': the checkerboard 9x6" in r.output
    assert "not found in any of its 1 view(s)" in r.output


def test_cli_extrinsics_keeps_the_intrinsics_error_for_check(tmp_path, rng):
    """calibrate intrinsics records each camera's own reprojection error; extrinsics computed from those
    intrinsics keep it in calibration.toml, and check flags a camera whose intrinsics are poor."""
    session, points, _ = _points_session(tmp_path, rng)
    rig = read_calibration(session / "calibration.toml")
    write_calibration(session / "calibration.toml", rig, {"intrinsics_rms_px": {"c1": 0.41, "c2": 1.7},
                                                          "intrinsics_views": {"c1": 14, "c2": 6}})  # fmt: skip
    r = _run("extrinsics", session, "--points", points)
    assert r.exit_code == 0, r.output
    meta = read_calibration_metadata(session / "calibration.toml")
    assert meta["intrinsics_rms_px"] == {"c1": 0.41, "c2": 1.7} and meta["intrinsics_views"] == {"c1": 14, "c2": 6}
    r = _run("check", session)
    assert "intrinsics reprojection RMS (px): c1 0.410, c2 1.700" in r.output
    assert r.exit_code == 1 and "camera 'c2': intrinsics reprojection error 1.70 px > 1 px" in r.output
    assert "c1': intrinsics" not in r.output


def test_cli_extrinsics_of_one_camera_is_not_written(tmp_path, rng):
    session, points, _ = _points_session(tmp_path, rng, cameras=1)
    before = (session / "calibration.toml").read_text()
    r = _run("extrinsics", session, "--points", points)
    assert r.exit_code == 1 and "not written: only c1 calibrated; tracking needs two or more cameras" in r.output
    assert "nan" not in r.output  # no 3D check without two cameras
    assert (session / "calibration.toml").read_text() == before
    r = _run("check", session)
    assert r.exit_code == 1 and "one camera (c1): tracking needs two or more" in r.output


def _views(sources: list[str]) -> ViewSet:
    """A ViewSet of these sources, each detected (its detection: the source's name)."""
    return ViewSet(frames=list(sources), sources=list(sources))  # type: ignore[arg-type]


def test_stereo_views_are_paired_by_the_number_in_their_names():
    left = _views(["left01.jpg", "left02.jpg", "left03.jpg"])
    right = _views(["right01.jpg", "right03.jpg", "right02.jpg"])  # listed in another order
    assert paired_views(left, right) == [("left01.jpg", "right01.jpg"), ("left02.jpg", "right02.jpg"),
                                         ("left03.jpg", "right03.jpg")]  # fmt: skip
    with pytest.raises(InputError, match="views without their pair .*: left02.jpg$"):
        paired_views(left, _views(["right01.jpg", "right03.jpg"]))  # one missing: never shifted onto the others
    video = paired_views(_views(["l.mp4#0", "l.mp4#10"]), _views(["r.mp4#0", "r.mp4#10"]))
    assert video == [("l.mp4#0", "r.mp4#0"), ("l.mp4#10", "r.mp4#10")]  # a video's frame index
    unnumbered = _views(["a.png", "b.png"])
    assert paired_views(unnumbered, _views(["c.png", "d.png"])) == [("a.png", "c.png"), ("b.png", "d.png")]
    with pytest.raises(InputError, match="2 left views and 1 right ones, not numbered"):
        paired_views(unnumbered, _views(["c.png"]))
    undetected = ViewSet(frames=[None, "left02.jpg"], sources=["left01.jpg", "left02.jpg"])  # type: ignore[list-item]
    assert paired_views(undetected, _views(["right01.jpg", "right02.jpg"])) == [("left02.jpg", "right02.jpg")]


def test_cli_stereo_refuses_one_folder_twice_and_a_poor_result(tmp_path):
    r = _run("stereo", CHESS, CHESS, "--board", "9x6", "--square", "25mm", "-o", tmp_path / "s.toml")
    assert r.exit_code == 2 and "given as both LEFT and RIGHT" in r.output
    left, right = tmp_path / "l", tmp_path / "r"
    left.mkdir(), right.mkdir()
    for k in ("01", "02", "03", "04", "05", "06"):
        (left / f"left{k}.jpg").write_bytes((CHESS / f"left{k}.jpg").read_bytes())
        (right / f"right{k}.jpg").write_bytes((CHESS / f"right{k}.jpg").read_bytes())
    r = _run("stereo", left, right, "--board", "9x6", "--square", "25mm", "-o", tmp_path / "s.toml", "--max-error", "0.01")
    assert r.exit_code == 1 and re.search(r"s.toml: not written: stereo reprojection RMS [\d.]+ px > 0.01 px", r.output)
    assert not (tmp_path / "s.toml").exists()
