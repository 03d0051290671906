from __future__ import annotations

import logging

import pytest
from session_factory import SIZE, make_session

from gaitcap.camera import CameraRig
from gaitcap.errors import CalibrationError, InputError
from gaitcap.io.calibration_toml import read_calibration, write_calibration
from gaitcap.session import Session
from gaitcap.session_check import check_session_videos, count_frames


def test_consistent_session(tmp_path):
    s = Session.open(make_session(tmp_path / "s"))
    checked = check_session_videos(s)
    assert checked.n_frames == 20 and checked.frame_range == (0, 20)
    assert checked.fps == pytest.approx(25.0)
    assert set(checked.videos) == {"cam0", "cam1"}
    assert checked.videos["cam0"].info.size == SIZE
    assert checked.notes == ()
    assert checked.rig.names == s.rig.names


def test_different_frame_counts_use_the_common_range_with_a_warning(tmp_path, caplog):
    s = Session.open(make_session(tmp_path / "s", frames={"cam0": 20, "cam1": 14}))
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        checked = check_session_videos(s)
    assert checked.n_frames == 14
    assert "videos of different lengths (cam0 20, cam1 14 frames); using the 14 frames common to all cameras" in caplog.text
    assert len(checked.notes) == 1


def test_skip_frames_shorten_a_camera_and_are_checked(tmp_path, caplog):
    """session.yaml's skip_frames: the frames common to all cameras are counted after each camera's skip;
    a skip of a camera the calibration does not have, or of every frame a video has, is refused naming
    session.yaml and the camera; a skip that is not a whole number of frames at least 0 names the key."""
    import yaml

    from gaitcap.errors import ConfigError

    root = make_session(tmp_path / "s", frames={"cam0": 20, "cam1": 18})
    (root / "session.yaml").write_text(yaml.safe_dump({"skip_frames": {"cam0": 2}}))
    s = Session.open(root)
    assert s.offsets == {"cam0": 2, "cam1": 0}
    from gaitcap.silhouette.run import sources_from_session

    assert [(src.camera, src.skip) for src in sources_from_session(root)] == [("cam0", 2), ("cam1", 0)]
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        checked = check_session_videos(s)
    assert checked.n_frames == 18 and checked.notes == ()  # 20 - 2 = 18: the same length, nothing to say
    (root / "session.yaml").write_text(yaml.safe_dump({"skip_frames": {"cam0": 5}}))
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        checked = check_session_videos(Session.open(root))
    assert checked.n_frames == 15
    assert "videos of different lengths after skip_frames (cam0 15, cam1 18 frames)" in caplog.text
    (root / "session.yaml").write_text(yaml.safe_dump({"skip_frames": {"cam1": 18}}))
    with pytest.raises(InputError, match=r"session\.yaml: skip_frames leaves no frame of camera 'cam1' \(18 skipped of the 18"):
        check_session_videos(Session.open(root))
    (root / "session.yaml").write_text(yaml.safe_dump({"skip_frames": {"cam2": 1}}))
    with pytest.raises(InputError, match=r"session\.yaml: skip_frames names 'cam2', not a camera of calibration\.toml "
                                         r"\(its cameras: cam0, cam1\)"):  # fmt: skip
        Session.open(root)
    for bad in (-1, 1.5, "two"):
        (root / "session.yaml").write_text(yaml.safe_dump({"skip_frames": {"cam0": bad}}))
        with pytest.raises(ConfigError, match=r"session\.yaml.*skip_frames\.cam0"):
            Session.open(root)


def test_different_frame_rates_are_an_error_unless_allowed(tmp_path, caplog):
    s = Session.open(make_session(tmp_path / "s", fps={"cam0": 25.0, "cam1": 30.0}))
    with pytest.raises(InputError, match="the cameras' frame rates differ: cam0 25 fps, cam1 30 fps"):
        check_session_videos(s)
    checked = check_session_videos(s, allow_fps_mismatch=True)
    assert checked.fps == pytest.approx(25.0)
    assert "using 25 fps as allowed" in caplog.text


def test_small_centred_crop_is_fitted_and_said(tmp_path):
    # 100x64 calibrated, 96x64 decoded: 4 columns, like the 1088 -> 1080 encoder crop
    s = Session.open(make_session(tmp_path / "s", calib_size=(100, 64), video_size={"cam0": (96, 64), "cam1": (96, 64)}))
    checked = check_session_videos(s)
    cam = checked.rig["cam0"]
    assert cam.size == (96, 64)
    assert cam.matrix[0, 2] == pytest.approx(s.rig["cam0"].matrix[0, 2] - 2.0)
    assert "video cam0.avi is 96x64 but calibration.toml says 100x64: assumed a centred crop" in checked.notes[0]


def test_video_size_not_matching_the_calibration(tmp_path):
    s = Session.open(make_session(tmp_path / "s", video_size={"cam1": (48, 32)}))
    with pytest.raises(InputError) as e:
        check_session_videos(s)
    assert str(e.value) == (
        "camera 'cam1': video cam1.avi is 48x32 but calibration.toml says 96x64; "
        "recalibrate at the video size (a resize is not a crop)"
    )


def test_truncated_video_is_counted_by_decoding(tmp_path, caplog):
    root = make_session(tmp_path / "s", frames={"cam0": 30, "cam1": 30})
    video = root / "videos" / "cam1.avi"
    data = video.read_bytes()
    video.write_bytes(data[: len(data) // 2])
    s = Session.open(root)
    checked = check_session_videos(s)
    assert 0 < checked.n_frames < 30
    assert checked.videos["cam0"].n_frames == 30
    assert checked.videos["cam1"].info.frame_count == 30  # the header still says 30
    assert f"cam1.avi: decoding stopped at frame {checked.n_frames} of 30 declared (truncated or corrupt file?)" in caplog.text
    assert "videos of different lengths" in caplog.text


def test_count_frames_without_a_declared_count(tmp_path):
    root = make_session(tmp_path / "s", frames={"cam0": 7})
    assert count_frames(root / "videos" / "cam0.avi", 0) == 7


def test_a_recorded_reprojection_error_is_refused_when_too_large_and_noted_when_poor(tmp_path, caplog):
    """calibration.toml's [metadata] records each camera's reprojection error (``calibrate extrinsics``):
    above 5 px the session is refused before any work, above 1 px (``calibrate check``'s limit) tracked with
    a warning and a note; an overall error counts when no camera's is recorded, -1 (not measured) does not."""
    root = make_session(tmp_path / "s")
    rig = read_calibration(root / "calibration.toml")
    write_calibration(root / "calibration.toml", rig, {"reprojection_rms_px": {"cam0": 0.4, "cam1": 54.5}})
    with pytest.raises(CalibrationError) as e:
        check_session_videos(Session.open(root))
    assert "calibration.toml: the reprojection error it records ([metadata]) is camera 'cam1' 54.50 px: above 5 px" in str(e.value)
    assert "cam0" not in str(e.value)
    write_calibration(root / "calibration.toml", rig, {"error": 1.5})
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        checked = check_session_videos(Session.open(root))
    assert len(checked.notes) == 1 and "records is 1.50 px overall (above 1 px: a poor calibration" in checked.notes[0]
    assert checked.notes[0] in caplog.text
    for fine in ({"error": -1.0}, {"error": 0.9, "reprojection_rms_px": {"cam0": 0.5, "cam1": 0.9}}):
        write_calibration(root / "calibration.toml", rig, fine)
        assert check_session_videos(Session.open(root)).notes == ()


def test_a_calibration_of_one_camera_is_refused_naming_the_videos_it_leaves_out(tmp_path):
    root = make_session(tmp_path / "s")
    rig = read_calibration(root / "calibration.toml")
    write_calibration(root / "calibration.toml", CameraRig((rig["cam0"],)))
    with pytest.raises(CalibrationError) as e:
        check_session_videos(Session.open(root))
    assert str(e.value) == (f"{root / 'calibration.toml'}: calibrates one camera (cam0); tracking needs two or more: "
                            "videos/ also holds cam1.avi, not in it (calibrate all the cameras together)")
