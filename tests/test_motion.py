"""Motion files -> joint centres: C3D time axis and events, mapping rules, GRF events, bone lengths."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gaitcap.data import embedded_walk
from gaitcap.errors import ConfigError, InputError
from gaitcap.io.c3d import read_c3d_angles
from gaitcap.io.trc import read_trc, write_trc
from gaitcap.markers.events import events_from_grf
from gaitcap.markers.jointcentres import harrington_hjc, rigid_cluster_point, sole_point
from gaitcap.markers.mapping import Mapping, load_mapping
from gaitcap.markers.motion import read_markers, read_motion
from gaitcap.trajectory import FOOT, LOWER_LIMB, POINT_NAMES

WALKING = Path(__file__).resolve().parent / "fixtures" / "walking"
OPENSIM_WALK = WALKING / "subject01_walk1.trc"
OPENSIM_STATIC = WALKING / "subject01_static.trc"
OPENSIM_GRF = WALKING / "subject01_walk1_grf.mot"


@pytest.fixture(scope="module")
def pig():
    return read_motion(embedded_walk())


@pytest.fixture(scope="module")
def opensim():
    return read_motion(OPENSIM_WALK)


# --- C3D ------------------------------------------------------------------------------------


def test_c3d_time_axis_and_meta(pig):
    assert pig.rate_hz == 100.0
    assert pig.n_frames == 221
    assert pig.t0_s == pytest.approx(1.52)  # header first frame 153 (1-based)
    assert pig.meta["height_m"] == pytest.approx(1.639)
    assert pig.meta["mapping"] == "plugin_gait"


def test_c3d_events(pig):
    got = {(e.side, e.event): [] for e in pig.events}
    for e in pig.events:
        got[(e.side, e.event)].append(round(e.time_s, 3))
        assert e.source == "c3d"
    assert got == {
        ("right", "foot_strike"): [1.661, 2.74],
        ("left", "foot_off"): [1.81, 2.892],
        ("left", "foot_strike"): [2.224, 3.33],
        ("right", "foot_off"): [2.364, 3.5],
    }
    # 0-based array index = round(t * 100) - 152
    assert pig.frame_of(2.74) == 274 - 152


def test_c3d_markers_leave_model_outputs_out():
    markers = read_markers(embedded_walk())
    assert "LASI" in markers.names and "LKJC" in markers.names
    assert not any(n.endswith("Angles") for n in markers.names)
    angles = read_c3d_angles(embedded_walk())
    assert "LKneeAngles" in angles.names and angles.values.shape == (221, 8, 3)
    assert 40.0 < np.nanmax(angles.get("LKneeAngles")[:, 0]) < 80.0  # swing knee flexion, degrees


def test_pig_points_and_upright_geometry(pig):
    assert pig.names == ("pelvis", *LOWER_LIMB, *FOOT)  # lower body only: no upper-body points
    z = {n: np.nanmedian(pig.point(n)[:, 2]) for n in pig.names}
    assert z["hip_l"] > z["knee_l"] > z["ankle_l"] > z["heel_l"] >= -0.01
    # heel and toe reach the floor (z = 0) in stance
    for n in ("heel_l", "heel_r", "toe_l", "toe_r"):
        assert abs(np.nanmin(pig.point(n)[:, 2])) < 0.01


# --- rules ----------------------------------------------------------------------------------


def test_harrington_hand_computed():
    # pelvis facing +x, left +y, up +z; PW = 240 mm, PD = 150 mm
    lasi, rasi, sacral = np.array([[0, 0.12, 1.0]]), np.array([[0, -0.12, 1.0]]), np.array([[-0.15, 0, 1.0]])
    # x = -0.24*150 - 9.9 = -45.9; up = -0.30*240 - 10.9 = -82.9; right = 0.33*240 + 7.3 = 86.5 (mm)
    np.testing.assert_allclose(harrington_hjc(lasi, rasi, sacral, "right"), [[-0.0459, -0.0865, 0.9171]], atol=1e-12)
    np.testing.assert_allclose(harrington_hjc(lasi, rasi, sacral, "left"), [[-0.0459, 0.0865, 0.9171]], atol=1e-12)


def test_harrington_moves_with_the_pelvis(rng):
    lasi, rasi, sacral = np.array([0, 0.12, 1.0]), np.array([0, -0.12, 1.0]), np.array([-0.15, 0, 1.0])
    rot = Rotation.random(random_state=3)
    t = np.array([0.4, -1.0, 0.2])
    moved = [rot.apply(p)[None] + t for p in (lasi, rasi, sacral)]
    hjc = harrington_hjc(lasi[None], rasi[None], sacral[None], "left")
    np.testing.assert_allclose(harrington_hjc(*moved, "left"), rot.apply(hjc) + t, atol=1e-12)


def test_cluster_reconstruction_exact_on_rigid_motion(rng):
    static_cluster = rng.normal(scale=0.05, size=(4, 3))
    static_point = np.array([0.02, -0.01, -0.2])
    rots = Rotation.random(30, random_state=7)
    trans = rng.normal(size=(30, 3))
    cluster = np.stack([rots[i].apply(static_cluster) + trans[i] for i in range(30)])
    truth = np.stack([rots[i].apply(static_point) + trans[i] for i in range(30)])
    cluster[5, 2] = np.nan  # three markers left: still exact
    cluster[9, 1:3] = np.nan  # two markers left: undefined
    got = rigid_cluster_point(static_cluster, static_point, cluster)
    ok = np.arange(30) != 9
    np.testing.assert_allclose(got[ok], truth[ok], atol=1e-9)
    assert np.isnan(got[9]).all()


@pytest.mark.parametrize("pitch_deg", [0.0, 25.0, -40.0])
def test_sole_point_follows_the_foot_pitch(pitch_deg):
    # foot along +x, marker 0.04 m above the sole point; the foot pitched about the y axis
    h = 0.04
    rot = Rotation.from_euler("y", -pitch_deg, degrees=True)
    heel, toe = rot.apply([0.0, 0.0, h]), rot.apply([0.2, 0.0, h])
    sole = rot.apply([0.0, 0.0, 0.0])
    got = sole_point(heel[None], heel[None], toe[None], h)
    np.testing.assert_allclose(got[0], sole, atol=1e-12)


# --- OpenSim trial --------------------------------------------------------------------------


def test_grf_events():
    events = events_from_grf(OPENSIM_GRF, threshold_n=20)
    got: dict[tuple[str, str], list[float]] = {}
    for e in events:
        got.setdefault((e.side, e.event), []).append(e.time_s)
        assert e.source == "grf"
    expected = {
        ("right", "foot_strike"): [0.618, 1.853],
        ("right", "foot_off"): [0.165, 1.410],
        ("left", "foot_strike"): [1.247, 2.460],
        ("left", "foot_off"): [0.788, 2.018],
    }
    assert set(got) == set(expected)
    for key, times in expected.items():
        np.testing.assert_allclose(got[key], times, atol=2.5 / 600)  # within 2.5 samples at 600 Hz


def test_opensim_joint_centres(opensim):
    assert opensim.names == POINT_NAMES
    assert opensim.meta["mapping"] == "opensim_gait2354"
    assert opensim.meta["static"].endswith("subject01_static.trc")
    assert len(opensim.events) == 8 and all(e.source == "grf" for e in opensim.events)
    z = {n: np.nanmedian(opensim.point(n)[:, 2]) for n in opensim.names}
    assert z["head"] > z["neck"] > z["thorax"] > z["pelvis"] > z["knee_r"] > z["ankle_r"] > z["toe_r"]
    assert z["shoulder_l"] > z["elbow_l"] > z["wrist_l"]
    # right is -y in the z-up frame of a y-up OpenSim file (x forward, y left)
    assert np.nanmedian(opensim.point("hip_r")[:, 1] - opensim.point("hip_l")[:, 1]) < -0.1


def test_markers_counts_the_events_the_force_table_gives():
    """gaitcap markers said '0 events in the file' for the OpenSim walk, whose report takes 8 from the
    force-plate table beside it: the account now says so."""
    from click.testing import CliRunner

    from gaitcap.cli.main import cli

    res = CliRunner().invoke(cli, ["markers", str(OPENSIM_WALK)])
    assert res.exit_code == 0, res.output
    assert "0 events in the file (8 found from the force-plate table beside it)" in res.output.splitlines()[0]


def test_static_trial_passed_explicitly_or_missing(tmp_path):
    walk = tmp_path / "trial.trc"
    shutil.copyfile(OPENSIM_WALK, walk)
    with pytest.raises(InputError, match=r"\*_static.trc"):
        read_motion(walk)
    joints = read_motion(walk, static=OPENSIM_STATIC)
    assert joints.has("knee_l") and not joints.events  # no force-plate file beside it


def test_static_trial_given_on_the_command_line(tmp_path):
    """A walk copied without its static trial: markers and report say to give it with --static, and take it."""
    from click.testing import CliRunner

    from gaitcap.cli.main import cli

    walk = tmp_path / "trial.trc"
    shutil.copyfile(OPENSIM_WALK, walk)
    runner = CliRunner()
    missing = runner.invoke(cli, ["markers", str(walk)])
    assert missing.exit_code == 1 and "needs a static trial" in missing.output and "--static FILE" in missing.output
    given = runner.invoke(cli, ["markers", str(walk), "--static", str(OPENSIM_STATIC)])
    assert given.exit_code == 0 and f"static trial: {OPENSIM_STATIC}" in given.output
    beside = runner.invoke(cli, ["markers", str(OPENSIM_WALK)])
    assert beside.exit_code == 0 and "static trial: " in beside.output and "subject01_static.trc" in beside.output
    refused = runner.invoke(cli, ["report", str(walk), "-o", str(tmp_path / "r")])
    assert refused.exit_code == 1 and "give it with --static FILE" in refused.output
    report = runner.invoke(cli, ["report", str(walk), "-o", str(tmp_path / "r"), "--static", str(OPENSIM_STATIC)])
    assert report.exit_code == 0, report.output
    assert (tmp_path / "r" / "report.html").is_file()


def _cv(traj, a, b):
    length = np.linalg.norm(traj.point(a) - traj.point(b), axis=1)
    return np.nanstd(length) / np.nanmean(length)


@pytest.mark.parametrize("trial", ["pig", "opensim"])
@pytest.mark.parametrize("segment", [("hip", "knee"), ("knee", "ankle")])
@pytest.mark.parametrize("side", ["_l", "_r"])
def test_bone_lengths_are_nearly_constant(request, trial, segment, side):
    traj = request.getfixturevalue(trial)
    assert _cv(traj, segment[0] + side, segment[1] + side) < 0.03


# --- mapping validation ---------------------------------------------------------------------


def _write_mapping(tmp_path, text):
    path = tmp_path / "m.yaml"
    path.write_text(text)
    return path


def test_unknown_rule_key_suggests(tmp_path):
    path = _write_mapping(tmp_path, "name: x\npoints:\n  hip_l:\n    harington: {side: left, lasi: A, rasi: B, sacral: C}\n")
    with pytest.raises(ConfigError, match="did you mean 'harrington'"):
        load_mapping(path)


def test_unknown_nested_key_suggests(tmp_path):
    path = _write_mapping(tmp_path, "name: x\npoints:\n  hip_l:\n    harrington: {sid: left, lasi: A, rasi: B, sacral: C}\n")
    with pytest.raises(ConfigError, match="did you mean 'side'"):
        load_mapping(path)


def test_unknown_output_point_and_forward_reference(tmp_path):
    with pytest.raises(ConfigError, match="knee_left"):
        load_mapping(_write_mapping(tmp_path, "name: x\npoints:\n  knee_left: {marker: K}\n"))
    with pytest.raises(ConfigError, match="defined later"):
        load_mapping(_write_mapping(tmp_path, "name: x\npoints:\n  pelvis: {mean: [hip_l, hip_r]}\n  hip_l: {marker: A}\n  hip_r: {marker: B}\n"))


def test_exactly_one_rule(tmp_path):
    with pytest.raises(ConfigError, match="exactly one rule"):
        load_mapping(_write_mapping(tmp_path, "name: x\npoints:\n  hip_l: {marker: A, mean: [B]}\n"))


def test_shipped_mappings_load():
    for name in ("plugin_gait", "opensim_gait2354"):
        assert isinstance(load_mapping(name), Mapping)
    with pytest.raises(ConfigError, match="plugin_gait"):
        load_mapping("plugin_gate")


def test_missing_markers_are_named(tmp_path):
    markers = read_trc(OPENSIM_WALK)
    keep = [n for n in markers.names if n not in ("V.Sacral", "L.Heel")]
    path = write_trc(tmp_path / "few.trc", read_markers(OPENSIM_WALK).subset(keep))
    with pytest.raises(InputError) as err:
        read_motion(path)
    msg = str(err.value)
    assert "closest: opensim_gait2354 (missing V.Sacral, L.Heel)" in msg
    assert "gaitcap markers" in msg


def test_gaitcap_points_file_reads_back_as_joint_centres(tmp_path, pig):
    # the tracker writes joints.trc with gaitcap point names; read_motion returns them as they are
    path = write_trc(tmp_path / "joints.trc", pig.subset(reversed(pig.names)))
    back = read_motion(path)
    assert back.names == pig.names
    np.testing.assert_allclose(back.points, pig.points, atol=1e-6)
    assert back.t0_s == pytest.approx(pig.t0_s)
