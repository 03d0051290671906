from __future__ import annotations

import csv

import cv2
import numpy as np
import pytest
from click.testing import CliRunner
from silhouette_scene import iou, walk_across, write_video

from gaitcap.camera import Camera, CameraRig
from gaitcap.cli.main import cli
from gaitcap.io.calibration_toml import write_calibration
from gaitcap.io.silhouettes_h5 import read_cameras, read_mask_attrs, read_masks, read_quality


@pytest.fixture(scope="module")
def scene():
    return walk_across(160, 120, 24, seed=7)


@pytest.fixture
def session(tmp_path, scene):
    """A 2-camera session (the same clip twice) with background plates."""
    root = tmp_path / "session"
    (root / "videos").mkdir(parents=True)
    (root / "background").mkdir()
    cams = [
        Camera.look_at(name, [x, -4.0, 1.2], [0.0, 0.0, 0.9], size=(160, 120), focal_px=150.0)
        for name, x in (("cam0", -1.0), ("cam1", 1.0))
    ]
    write_calibration(root / "calibration.toml", CameraRig(tuple(cams)))
    for cam in ("cam0", "cam1"):
        write_video(root / "videos" / f"{cam}.avi", scene.frames)
        cv2.imwrite(str(root / "background" / f"{cam}.png"), scene.plate)
    return root


def _run(*args):
    return CliRunner().invoke(cli, ["silhouettes", *map(str, args)])


def test_session_outputs_masks_quality_png_and_overlay(session, scene, tmp_path):
    out = tmp_path / "out"
    # the same clip for both cameras does not agree with the calibration's floor: no floor check
    config = tmp_path / "silhouette.yaml"
    config.write_text("shadow:\n  floor_check: false\n")
    result = _run(session, "-o", out, "--png", "--overlay", "-c", config)
    assert result.exit_code == 0, result.output
    h5 = out / "silhouettes.h5"
    assert read_cameras(h5) == ["cam0", "cam1"]
    masks = read_masks(h5, "cam1")
    assert masks.shape == (24, 120, 160) and masks.dtype == np.uint8 and set(np.unique(masks)) <= {0, 1}
    visible = [k for k in range(24) if scene.masks[k].sum() > 300]
    # MJPEG-compressed input; 0.865 with one hard threshold, 0.828 with the hysteresis, which extends the
    # soft shadow at the feet (no floor check here: the same clip in both cameras)
    assert np.mean([iou(masks[k], scene.masks[k]) for k in visible]) > 0.8
    q = read_quality(h5, "cam0")
    assert q["fraction"].shape == (24,) and q["bbox"].shape == (24, 4)
    np.testing.assert_allclose(q["fraction"], read_masks(h5, "cam0").mean(axis=(1, 2)), atol=1e-6)
    assert read_mask_attrs(h5, "cam0")["background_source"] == "plate"
    rows = list(csv.DictReader((out / "silhouettes_quality.csv").open()))
    assert len(rows) == 48 and rows[0]["camera"] == "cam0" and rows[0]["time_s"] == "0.0000"
    pngs = sorted((out / "silhouettes" / "cam1").glob("*.png"))
    assert len(pngs) == 24 and pngs[5].name == "000005.png"
    np.testing.assert_array_equal(cv2.imread(str(pngs[5]), cv2.IMREAD_GRAYSCALE) // 255, masks[5])
    assert cv2.VideoCapture(str(out / "overlay" / "cam0.mp4")).get(cv2.CAP_PROP_FRAME_COUNT) == 24
    assert "mean foreground" in result.output


def test_plain_video_without_session(tmp_path, scene):
    video = write_video(tmp_path / "walk.avi", scene.frames)
    out = tmp_path / "out"
    result = _run("--video", video, "-o", out, "--max-frames", "10", "--no-shadow")
    assert result.exit_code == 0, result.output
    assert read_masks(out / "silhouettes.h5", "walk").shape == (10, 120, 160)
    assert read_mask_attrs(out / "silhouettes.h5", "walk")["background_source"] == "video"


def test_neither_a_session_nor_videos_is_said_as_such(tmp_path):
    result = _run("-o", tmp_path / "out")
    assert result.exit_code == 2 and "give a SESSION folder or --video files/folders" in result.output
    assert "not both" not in result.output


def test_an_unusable_background_is_warned_once_and_named_in_the_summary(tmp_path):
    """Someone always in view: the background warning when it is fitted, then the camera's summary line
    says the masks are unreliable (the warning was printed twice)."""
    from silhouette_scene import sway_in_place

    scene = sway_in_place(seed=3)
    video = write_video(tmp_path / "sway.avi", scene.frames)
    result = _run("--video", video, "-o", tmp_path / "out", "--no-shadow")
    assert result.exit_code == 0, result.output
    assert result.output.count("no usable background could be estimated") == 1
    assert "sway: " in result.output and "(unusable: the masks are unreliable, see the warning above)" in result.output


def test_existing_output_needs_force(session, tmp_path):
    out = tmp_path / "out"
    assert _run(session, "-o", out, "--max-frames", "2").exit_code == 0
    result = _run(session, "-o", out, "--max-frames", "2")
    assert result.exit_code == 1 and "--force" in result.output
    assert _run(session, "-o", out, "--max-frames", "2", "--force").exit_code == 0


def test_a_run_replaced_leaves_none_of_its_pngs_or_overlays(session, tmp_path):
    """--force removes the earlier run's PNG masks and overlay videos (5 PNGs and a 5-frame overlay stayed
    beside a 2-frame run); without --force, an earlier run's PNGs alone are refused, not overwritten in part."""
    out = tmp_path / "out"
    assert _run(session, "-o", out, "--max-frames", "5", "--png", "--overlay").exit_code == 0
    assert _run(session, "-o", out, "--max-frames", "2", "--png", "--force").exit_code == 0
    assert len(list((out / "silhouettes" / "cam0").glob("*.png"))) == 2
    assert not list((out / "overlay").glob("*.mp4"))
    (out / "silhouettes.h5").unlink()
    (out / "silhouettes_quality.csv").unlink()
    result = _run(session, "-o", out, "--max-frames", "3", "--png")
    assert result.exit_code == 1 and "000000.png: exists already (use --force" in result.output


def test_a_killed_runs_temporary_files_are_removed_by_the_next(session, tmp_path):
    out = tmp_path / "out"
    (out / "overlay").mkdir(parents=True)
    left = [out / ".silhouettes.h5.x1.h5.part", out / ".silhouettes_quality.csv.x2.part",
            out / "overlay" / ".cam1.mp4.x3.part.mp4"]
    for path in left:
        path.write_bytes(b"a killed run's")
    assert _run(session, "-o", out, "--max-frames", "2", "--overlay").exit_code == 0
    assert not any(path.exists() for path in left) and (out / "silhouettes.h5").is_file()


def test_corrupt_video_is_one_clear_error(session, tmp_path):
    (session / "videos" / "cam1.avi").write_bytes(b"RIFF\x00\x00\x00\x00AVI garbage" * 50)
    result = _run(session, "-o", tmp_path / "out")
    assert result.exit_code == 1
    assert "cam1.avi" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "out" / "silhouettes.h5").exists()


def test_zero_frame_video_is_one_clear_error(tmp_path):
    empty = tmp_path / "empty.avi"
    cv2.VideoWriter(str(empty), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (64, 48)).release()
    result = _run("--video", empty, "-o", tmp_path / "out")
    assert result.exit_code == 1 and "empty.avi" in result.output and "no decodable frame" in result.output


def test_plate_of_another_size_is_one_clear_error(session, scene, tmp_path):
    cv2.imwrite(str(session / "background" / "cam0.png"), cv2.resize(scene.plate, (80, 60)))
    result = _run(session, "-o", tmp_path / "out")
    assert result.exit_code == 1
    assert "cam0.png" in result.output and "80x60" in result.output and "160x120" in result.output


def test_unreadable_plate_is_one_clear_error(session, tmp_path):
    (session / "background" / "cam0.png").write_bytes(b"not a png")
    result = _run(session, "-o", tmp_path / "out")
    assert result.exit_code == 1 and "cam0.png" in result.output


def test_greyscale_plate_of_a_colour_video_is_one_clear_error(session, scene, tmp_path):
    """Found with a session whose cam1.png was saved in greyscale: the plate differed from every colour
    frame, the run went on with a warning ('the plate does not match the video') and masks of a third of the
    image, exit 0. Now refused, naming the plate, before anything is written."""
    cv2.imwrite(str(session / "background" / "cam0.png"), cv2.cvtColor(scene.plate, cv2.COLOR_BGR2GRAY))
    result = _run(session, "-o", tmp_path / "out")
    assert result.exit_code == 1
    assert (f"{session / 'background' / 'cam0.png'}: background plate is greyscale but the video cam0.avi is in "
            "colour" in result.output)  # fmt: skip
    assert not (tmp_path / "out" / "silhouettes.h5").exists()


def test_a_session_whose_cameras_run_at_different_rates_is_refused(session, scene, tmp_path):
    """Found with a session whose cam1 was re-encoded at 30 fps: track refused it, silhouettes took the
    cameras' frames k together (the floor check across cameras) as if they were one instant, exit 0."""
    write_video(session / "videos" / "cam1.avi", scene.frames, fps=30.0)
    result = _run(session, "-o", tmp_path / "out")
    assert result.exit_code == 1
    assert "the cameras' frame rates differ: cam0 25 fps, cam1 30 fps; re-encode the videos at one rate" in result.output
    assert not (tmp_path / "out" / "silhouettes.h5").exists()
    assert _run("--video", session / "videos", "-o", tmp_path / "plain").exit_code == 0  # plain videos: apart


def test_bad_config_key_is_one_clear_error(session, tmp_path):
    cfg = tmp_path / "s.yaml"
    cfg.write_text("foreground:\n  treshold_sigma: 3\n")
    result = _run(session, "-o", tmp_path / "out", "-c", cfg)
    assert result.exit_code == 1 and "did you mean 'threshold_sigma'" in result.output


def test_session_and_video_are_exclusive(session, tmp_path):
    result = _run(session, "--video", session / "videos" / "cam0.avi", "-o", tmp_path / "out")
    assert result.exit_code == 2


def test_the_overlay_label_is_white_on_a_black_box():
    """Every white pixel of the quality label lies inside the black box behind it (an outline drawn as thicker
    text no longer lined up with the text under OpenCV 5)."""
    from gaitcap.silhouette.extract import FrameQuality
    from gaitcap.silhouette.overlay import draw_overlay

    frame = np.full((480, 640, 3), 128, np.uint8)
    out = draw_overlay(frame, np.zeros((480, 640), np.uint8), FrameQuality(100, 0.048, 0.0, 1, None, 0))
    black = np.all(out == 0, axis=2)
    ys, xs = np.nonzero(black)
    assert len(ys) > 0
    white = np.all(out > 200, axis=2)
    wy, wx = np.nonzero(white)
    assert len(wy) > 50  # the text is drawn
    assert ys.min() <= wy.min() and wy.max() <= ys.max() and xs.min() <= wx.min() and wx.max() <= xs.max()
    grey = np.all(out == 128, axis=2)
    assert grey[:, xs.max() + 1:].all() and grey[ys.max() + 1:].all()  # nothing else drawn around it


def test_the_overlay_mask_is_not_drawn_in_the_reports_left_and_right_colours():
    """Found viewing the overlay beside the report: the mask was tinted green and outlined red, the report's
    right and left colours. The tint and outline are now cyan and yellow."""
    from gaitcap.silhouette.overlay import MASK_BGR, OUTLINE_BGR, draw_overlay

    frame = np.full((120, 160, 3), 128, np.uint8)
    mask = np.zeros((120, 160), np.uint8)
    mask[30:90, 60:100] = 1
    out = draw_overlay(frame, mask).astype(int)
    inside = out[60, 80]
    assert inside[0] > inside[2] and inside[1] > inside[2]  # blue and green over red: cyan, not green
    np.testing.assert_array_equal(out[30, 80], OUTLINE_BGR)
    for bgr in (MASK_BGR, OUTLINE_BGR):
        b, g, r = bgr
        assert not (g > 150 and r < 80 and b < 80) and not (r > 150 and g < 80 and b < 80)  # neither green nor red


def test_a_trajectories_file_is_not_read_as_masks(tmp_path):
    """read_cameras on a trajectories.h5 (its /points (T, P, 3) at the root) gave ['points',
    'points_unfiltered'] as cameras; a truth's masks.h5 of uint8 datasets is still read."""
    import h5py

    from gaitcap.errors import InputError
    from gaitcap.io.trajectories_h5 import write_trajectory
    from gaitcap.trajectory import Trajectory

    path = tmp_path / "trajectories.h5"
    write_trajectory(path, Trajectory(("hip_l", "hip_r"), np.zeros((4, 2, 3)), 25.0))
    with pytest.raises(InputError, match=r"trajectories\.h5: no masks \(neither a /masks group nor"):
        read_cameras(path)
    masks = tmp_path / "masks.h5"
    with h5py.File(masks, "w") as f:
        f["cam1"] = np.zeros((4, 6, 8), np.uint8)
        f["points"] = np.zeros((4, 2, 3))
    assert read_cameras(masks) == ["cam1"]
