from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
import yaml

from gaitcap.data import embedded_walk
from gaitcap.errors import InputError, OutputError
from gaitcap.io.calibration_toml import read_calibration
from gaitcap.session import Session
from gaitcap.synth.checks import bone_length_variation, truth_inside_masks
from gaitcap.synth.session import SynthOptions, synthesize
from gaitcap.synth.truth import read_truth
from gaitcap.trajectory import LOWER_LIMB, POINT_NAMES

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "walking"


@pytest.fixture(scope="module")
def vicon_session(tmp_path_factory):
    out = tmp_path_factory.mktemp("synth") / "vicon"
    return synthesize(embedded_walk(), out, SynthOptions(), progress=False)


@pytest.fixture(scope="module")
def opensim_session(tmp_path_factory):
    out = tmp_path_factory.mktemp("synth") / "opensim"
    opts = SynthOptions(cameras=3, size=(320, 240), seed=3, codec="ffv1")
    return synthesize(FIXTURES / "subject01_walk1.trc", out, opts, progress=False)


def _frames(path: Path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(frame)
    cap.release()
    return frames


def test_session_layout(vicon_session):
    root = vicon_session.session
    session = Session.open(root)
    assert session.camera_names == ["cam1", "cam2"]
    assert set(session.backgrounds) == {"cam1", "cam2"}
    assert session.info.subject.height_m == pytest.approx(1.639)
    for cam in session.rig:
        assert cam.size == (640, 480)
        frames = _frames(session.videos[cam.name])
        assert len(frames) == vicon_session.n_frames == 56  # 2.21 s of 100 Hz data at 25 fps
        assert frames[0].shape == (480, 640, 3)
        plate = cv2.imread(str(session.backgrounds[cam.name]))
        assert plate.shape == (480, 640, 3)
    info = yaml.safe_load((root / "session.yaml").read_text())
    assert "synthetic" in info["notes"]
    assert not list(root.parent.glob("*.partial"))


def test_truth_file_contents(vicon_session):
    truth = read_truth(vicon_session.session / "truth.h5")
    traj = truth.trajectory
    assert traj.names == POINT_NAMES
    assert traj.rate_hz == 25.0 and traj.t0_s == 0.0
    assert truth.poses.shape == (56, 31)
    assert truth.cameras == ("cam1", "cam2")
    assert truth.mask("cam1", 10).shape == (480, 640)
    # the recording's events, moved onto video time (the C3D starts at 1.52 s)
    strikes = [e.time_s for e in traj.events if e.side == "right" and e.event == "foot_strike"]
    np.testing.assert_allclose(strikes, [1.6605 - 1.52, 2.74 - 1.52], atol=1e-6)
    with pytest.raises(InputError, match="no masks for camera 'cam9'"):
        truth.mask("cam9", 0)
    with h5py.File(vicon_session.session / "truth.h5") as f:  # units, as trajectories.h5's
        assert [f[k].attrs["units"] for k in ("points", "times", "raw_points", "fit_residual_m", "events/time_s")] == [
            "m", "s", "m", "m", "s"]  # fmt: skip
        assert list(f["poses"].attrs["dof_units"][:4]) == ["m", "m", "m", "rad"]


def test_truth_points_fall_inside_the_rendered_silhouettes(vicon_session, opensim_session):
    for result in (vicon_session, opensim_session):
        inside = truth_inside_masks(result.session)
        assert len(inside) == len(result.cameras)
        assert min(inside.values()) >= 0.99, inside


def test_truth_is_the_motions_own_joint_centres(vicon_session, opensim_session):
    """The truth's points are the recording's joint centres (not the tracker's model refitted), so
    bones vary in length as marker-based joint centres do, within a real-data range."""
    for result in (vicon_session, opensim_session):
        with h5py.File(result.session / "truth.h5", "r") as f:
            raw, raw_names = f["raw_points"][()], [str(n) for n in f["raw_points"].attrs["names"]]
        truth = result.truth
        for name in LOWER_LIMB:
            obs = raw[:, raw_names.index(name)]
            ok = np.all(np.isfinite(obs), axis=1)
            assert ok.mean() > 0.8
            np.testing.assert_allclose(truth.point(name)[ok], obs[ok], atol=1e-9)
        variation = bone_length_variation(result.session)
        assert len(variation) == 15
        assert max(variation[b] for b in ("hip_l-knee_l", "knee_l-ankle_l", "hip_r-knee_r", "knee_r-ankle_r")) < 0.15
        assert max(variation.values()) > 0.005  # not a rigid model's points


def test_body_fit_follows_the_real_joint_centres(vicon_session, opensim_session):
    for result, bound in ((vicon_session, 0.006), (opensim_session, 0.012)):
        lower = [result.fit.residual_m[n] for n in LOWER_LIMB]
        assert max(lower) < bound, result.fit.residual_m


def test_masks_agree_with_the_video(vicon_session):
    """Where the truth mask says body, the frame differs from the empty background."""
    root = vicon_session.session
    truth = read_truth(root / "truth.h5")
    frames = _frames(root / "videos" / "cam1.mp4")
    plate = cv2.imread(str(root / "background" / "cam1.png")).astype(float)
    diff = np.abs(frames[30].astype(float) - plate).sum(axis=2)
    mask = truth.mask("cam1", 30).astype(bool)
    assert mask.sum() > 2000
    assert np.median(diff[mask]) > 5 * np.median(diff[~mask])


def test_opensim_walk_in_place_has_force_plate_events(opensim_session):
    truth = read_truth(opensim_session.session / "truth.h5")
    sources = {e.source for e in truth.trajectory.events}
    assert sources == {"grf"}
    assert len(truth.trajectory.events) == 8
    rig = read_calibration(opensim_session.session / "calibration.toml")
    assert rig.names == ["cam1", "cam2", "cam3"] and rig[0].size == (320, 240)
    assert (opensim_session.session / "videos" / "cam3.mkv").is_file()


def test_existing_output_is_refused_without_force(vicon_session, tmp_path):
    with pytest.raises(OutputError, match="already exists"):
        synthesize(embedded_walk(), vicon_session.session, SynthOptions(), progress=False)


def test_bad_motion_file_leaves_nothing_behind(tmp_path):
    bad = tmp_path / "walk.trc"
    bad.write_text("not a trc file\n")
    with pytest.raises(InputError):
        synthesize(bad, tmp_path / "out", SynthOptions(), progress=False)
    assert not (tmp_path / "out").exists()
    assert not list(tmp_path.glob("*.partial"))


def test_a_stated_height_the_legs_contradict_is_warned_about(caplog):
    """A height stated by the file or ``synth --height`` is used as it is, but one 15 % or more from what the
    legs' joint centres give (thigh + shank = 0.491 H) is warned about: the truth and session.yaml state it."""
    import logging
    from dataclasses import replace

    from gaitcap.markers.motion import read_motion
    from gaitcap.synth.fit import _legs_height, estimate_height

    walk = read_motion(embedded_walk())
    legs = _legs_height(walk)
    assert legs is not None and 1.4 < legs < 2.0
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        assert estimate_height(replace(walk, meta={**walk.meta, "height_m": legs * 1.05})) == pytest.approx(legs * 1.05)
        assert "legs show" not in caplog.text
        assert estimate_height(replace(walk, meta={**walk.meta, "height_m": 0.8 * legs})) == pytest.approx(0.8 * legs)
    assert f"is -20 % from the {legs:.2f} m its legs show" in caplog.text


def test_a_walk_too_short_for_a_gait_cycle_is_warned_about(tmp_path, caplog):
    """Three frames of a 60 Hz marker file make a 1-frame session: rendered, but said to hold no gait cycle."""
    import logging

    lines = (FIXTURES / "subject01_walk1.trc").read_text().splitlines()
    header = lines[2].split("\t")
    header[2] = header[7] = "3"
    short = tmp_path / "short.trc"
    shutil.copy(FIXTURES / "subject01_static.trc", tmp_path / "subject01_static.trc")
    short.write_text("\n".join(lines[:2] + ["\t".join(header)] + lines[3:6] + lines[6:9]) + "\n")
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        res = synthesize(short, tmp_path / "out", SynthOptions(size=(160, 120), codec="ffv1"), progress=False)
    assert res.n_frames == 1
    assert "short.trc: the walk lasts 0.00 s, 1 frame at 25 fps: too short for a gait cycle" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        from gaitcap.synth.session import _warn_short
        from gaitcap.markers.motion import read_motion

        walk = read_motion(FIXTURES / "subject01_walk1.trc").resample(25.0)
        assert walk.n_frames >= 25
        _warn_short(walk, "walk.trc", 25.0)
    assert "too short" not in caplog.text
