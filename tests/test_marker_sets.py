"""Marker sets labs use: Plug-in-Gait variants (SACR, no heels, subject prefix, the file's own
joint centres), CAST-like sets, user mappings, readers of real files, `gaitcap markers`."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from gaitcap.cli.main import cli
from gaitcap.errors import ConfigError, InputError
from gaitcap.gait.angles import joint_angles
from gaitcap.gait.events import detect_events
from gaitcap.io.c3d import _unprefixed, read_c3d_angles
from gaitcap.io.trc import read_trc, write_trc
from gaitcap.markers.jointcentres import apply_mapping, chord_point
from gaitcap.markers.mapping import MAPPINGS_DIR, load_mapping
from gaitcap.markers.motion import (
    choose_mapping,
    guess_up_axis,
    read_markers,
    read_motion,
    read_raw_markers,
    select_subject,
)
from gaitcap.trajectory import Trajectory

WALKING = Path(__file__).resolve().parent / "fixtures" / "walking"
PIG = WALKING / "gait-pig.c3d"  # A22: prefix, SACR, no heels, PiG segment points, events
RAW = WALKING / "gait-raw.c3d"  # same trial, raw markers only
OPENSIM = WALKING / "subject01_walk1.trc"


def test_prefixed_pig_file_uses_its_own_joint_centres():
    raw = read_raw_markers(PIG)
    assert raw.meta["subject"] == "A22" and "LFEO" in raw.names and not any(":" in n for n in raw.names)
    joints = read_motion(PIG)
    assert joints.meta["mapping"] == "plugin_gait"
    pig = np.isfinite(raw.point("LFEO")).all(axis=1)  # PiG's points end with the ASIS, 28 frames early
    assert 0.75 < pig.mean() < 0.85
    np.testing.assert_allclose(joints.point("knee_l")[pig], raw.point("LFEO")[pig])
    np.testing.assert_allclose(joints.point("ankle_r")[pig], raw.point("RTIO")[pig])
    np.testing.assert_allclose(joints.point("pelvis")[pig], raw.point("PELO")[pig], atol=1e-4)  # INT C3D: 0.05 mm
    # after them: the ASIS carried by SACR (segment fill), the centres from the markers' rules
    assert np.isfinite(joints.point("pelvis")).all()
    knee = np.isfinite(joints.point("knee_l")).all(axis=1)
    assert np.array_equal(knee[~pig], np.isfinite(raw.point("LKNE")[~pig]).all(axis=1))
    heel = np.isfinite(joints.point("heel_l")).all(axis=1)  # estimated without HEE
    foot = np.isfinite(raw.point("LANK")).all(axis=1) & np.isfinite(raw.point("LTOE")).all(axis=1)
    assert np.array_equal(heel, foot)


def test_pig_file_events_found_within_two_samples():
    joints = read_motion(PIG)
    assert len(joints.events) == 9
    found, _ = detect_events(joints)
    matched = []
    for ref in joints.events:
        same = [e.time_s for e in found if (e.side, e.event) == (ref.side, ref.event)]
        err = min((abs(t - ref.time_s) for t in same), default=np.inf)
        if err < 0.1:
            matched.append(err)
    # the last right foot off (2.60 s) too: RTOE ends at 2.50 s in heel rise, held on the floor
    # until RANK is out of the foot's reach (gaitcap.markers.jointcentres.hold_on_floor)
    assert len(matched) == 9
    assert max(matched) <= 2.0 / joints.rate_hz
    assert list(joints.meta["toe_releases"]) == ["right"]


def test_knee_flexion_from_pig_joint_centres_matches_the_files_angles():
    joints = read_motion(PIG)
    pig = read_c3d_angles(PIG)
    assert "LKneeAngles" in pig.names  # prefix removed
    _, direction = detect_events(joints)
    ang, _ = joint_angles(joints, direction)
    for side, label in (("l", "LKneeAngles"), ("r", "RKneeAngles")):
        a, b = ang[f"knee_flexion_{side}"], pig.get(label)[:, 0]
        ok = np.isfinite(a) & np.isfinite(b)
        assert np.sqrt(np.mean((a[ok] - b[ok]) ** 2)) < 1.0


def test_raw_sacr_file_joint_centres_from_markers_near_plug_in_gaits():
    raw_joints = read_motion(RAW)
    pig = read_raw_markers(PIG)
    assert "SACR" in read_raw_markers(RAW).names
    for point, pig_name, limit_mm in (("knee_l", "LFEO", 25), ("knee_r", "RFEO", 25), ("ankle_l", "LTIO", 25)):
        d = np.linalg.norm(raw_joints.point(point) - pig.point(pig_name), axis=1)
        assert np.nanmedian(d) * 1000 < limit_mm


def test_chord_point_is_at_distance_and_right_angle():
    hip = np.array([[0.0, 0.1, 0.9]])
    knee_marker = np.array([[0.0, 0.15, 0.5]])
    wand = np.array([[0.0, 0.2, 0.7]])
    j = chord_point(hip, wand, knee_marker, 0.05)
    assert np.linalg.norm(j - knee_marker) == pytest.approx(0.05)
    assert np.dot((j - knee_marker)[0], (hip - j)[0]) == pytest.approx(0.0, abs=1e-12)
    assert j[0, 1] < knee_marker[0, 1]  # away from the (lateral) wand


def _pig_joints_as_cast(joints: Trajectory) -> Trajectory:
    """CAST-like landmarks placed around known joint centres (epicondyles/malleoli +- 5 cm in y)."""
    side = np.array([0.0, 0.05, 0.0])
    pts, names = [], []
    for s, pre in (("l", "L_"), ("r", "R_")):
        for a, b, centre in (("FLE", "FME", "knee"), ("FAL", "TAM", "ankle")):
            c = joints.point(f"{centre}_{s}")
            pts += [c + side, c - side]
            names += [pre + a, pre + b]
        pts += [joints.point(f"heel_{s}") + [0, 0, 0.03], joints.point(f"toe_{s}") + [0, 0, 0.03]]
        names += [pre + "FCC", pre + "FM2"]
    pelvis = joints.point("pelvis")
    for n, off in (("L_IAS", [0.05, 0.12, 0.08]), ("R_IAS", [0.05, -0.12, 0.08]),
                   ("L_IPS", [-0.12, 0.04, 0.1]), ("R_IPS", [-0.12, -0.04, 0.1])):  # fmt: skip
        pts.append(pelvis + off)
        names.append(n)
    return Trajectory(tuple(names), np.stack(pts, axis=1), joints.rate_hz, meta={"source": "cast"})


def test_cast_set_is_chosen_and_gives_mid_landmarks():
    joints = read_motion(PIG)
    cast = _pig_joints_as_cast(joints)
    mapping = choose_mapping(cast.names)
    assert mapping.name == "cast"
    out = apply_mapping(mapping, cast)
    np.testing.assert_allclose(out.point("knee_l"), joints.point("knee_l"), atol=1e-9)
    np.testing.assert_allclose(out.point("ankle_r"), joints.point("ankle_r"), atol=1e-9)


def test_optional_points_and_lpsi_rpsi_variant_of_plugin_gait():
    m = load_mapping("plugin_gait")
    lower = ["LASI", "RASI", "LPSI", "RPSI", "LTHI", "RTHI", "LKNE", "RKNE", "LTIB", "RTIB", "LANK", "RANK",
             "LHEE", "RHEE", "LTOE", "RTOE"]  # fmt: skip
    res = m.resolve(lower)
    assert res.fits and "shoulder_l" not in res.output_points()
    assert res.describe("hjc_l") == "harrington(LASI, RASI, LPSI, RPSI)"
    full = m.resolve(lower + ["LSHO", "RSHO", "LELB", "RELB", "LWRA", "LWRB", "RWRA", "RWRB"])
    assert {"shoulder_l", "elbow_r", "wrist_l", "thorax"} <= set(full.output_points())
    assert not m.resolve(lower[2:]).fits  # no ASIS


def test_unknown_set_error_names_closest_mapping_and_command():
    with pytest.raises(InputError) as e:
        choose_mapping(["LASI", "RASI", "SACR", "LKNE"], "x.c3d")
    msg = str(e.value)
    assert "closest: plugin_gait" in msg and "LTHI" in msg and "gaitcap markers" in msg and "--mapping" in msg


def test_several_subjects_pick_most_or_named():
    pts = np.ones((3, 5, 3))
    traj = Trajectory(("Bob:LASI", "Bob:RASI", "Ann:LASI", "Ann:RASI", "Ann:SACR"), pts, 100.0, meta={"source": "s"})
    assert select_subject(traj).names == ("LASI", "RASI", "SACR")
    bob = select_subject(traj, "Bob")
    assert bob.names == ("LASI", "RASI") and bob.meta["subject"] == "Bob"
    with pytest.raises(InputError, match="no subject 'Eve'"):
        select_subject(traj, "Eve")


def test_event_labels_with_subject_prefix():
    assert _unprefixed("A22:Foot Strike") == "Foot Strike" and _unprefixed("Left") == "Left"


def _opensim_style(path: Path, dst: Path) -> Path:
    """The walk's TRC with the header of OpenSim's own examples: the values line has empty fields
    between values (``60.00<TAB><TAB>60.00<TAB><TAB>151...``), the keys line has not."""
    lines = path.read_text().splitlines()
    lines[2] = "\t\t".join(lines[2].split("\t")) + "\t"
    dst.write_text("\n".join(lines) + "\n")
    return dst


def test_trc_header_with_empty_fields_reads_like_the_original(tmp_path):
    odd = _opensim_style(OPENSIM, tmp_path / "walk.trc")
    assert "\t\t" in odd.read_text().splitlines()[2]
    a, b = read_trc(OPENSIM), read_trc(odd)
    assert a.names == b.names and a.rate_hz == b.rate_hz
    np.testing.assert_array_equal(a.points, b.points)


def test_trc_z_up_metres_gaps_and_late_start(tmp_path):
    joints = read_motion(PIG)
    late = Trajectory(joints.names, joints.points.copy(), joints.rate_hz, t0_s=3.5)
    late.points[10:14, 2] = 0.0  # a gap written as zeros
    path = write_trc(tmp_path / "z.trc", late, units="m", up_axis="z")
    back = read_markers(path)  # no up axis stated: the markers' spread says z
    assert back.meta["file_up_axis"] == "z" and back.t0_s == pytest.approx(3.5)
    assert np.isnan(back.points[10:14, 2]).all()
    np.testing.assert_allclose(back.points[20], joints.points[20], atol=1e-8)
    assert guess_up_axis(read_trc(OPENSIM).points) == "y"


def test_user_mapping_yaml_validated_and_used(tmp_path):
    good = tmp_path / "my_lab.yaml"
    good.write_text("name: my_lab\npoints:\n  knee_l: {marker: LFEO}\n  ankle_l: {marker: LTIO}\n")
    joints = read_motion(PIG, mapping=good)
    assert joints.names == ("knee_l", "ankle_l") and joints.meta["mapping"] == "my_lab"
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\npoints:\n  knee_l: {markr: LFEO}\n")
    with pytest.raises(ConfigError, match="bad.yaml"):
        read_motion(PIG, mapping=bad)
    res = CliRunner().invoke(cli, ["markers", str(PIG), "--mapping", str(good)])
    assert res.exit_code == 1 and "mapping my_lab: does NOT fit: defines no hip_l, hip_r, knee_r, ankle_r" in res.output


def test_markers_command_shows_sources_and_missing():
    res = CliRunner().invoke(cli, ["markers", str(RAW)])
    assert res.exit_code == 0, res.output
    assert "mapping plugin_gait: fits" in res.output
    assert "harrington(LASI, RASI, SACR)" in res.output and "chord(hjc_l, LTHI, LKNE)" in res.output
    assert "other mapping opensim_gait2354: missing" in res.output
    # the file's 14 labels that never hold a sample are named, not silently left out of its 13 markers
    assert "13 markers" in res.output and "14 more labels without any sample: LKD1" in res.output
    res = CliRunner().invoke(cli, ["markers", str(OPENSIM), "--mapping", "plugin_gait"])
    assert res.exit_code == 1 and "does NOT fit" in res.output


def test_markers_command_on_a_gaitcap_export_reads_its_joint_centres(tmp_path):
    """gaitcap report's trajectories.c3d holds gaitcap's own joint centres: read as they are (as report and
    read_motion do), not judged against the marker mappings (it was 'plugin_gait: does NOT fit', exit 1)."""
    from gaitcap.io.c3d_export import write_c3d

    joints = read_motion(RAW)
    write_c3d(tmp_path / "trajectories.c3d", joints)
    res = CliRunner().invoke(cli, ["markers", str(tmp_path / "trajectories.c3d")])
    assert res.exit_code == 0, res.output
    assert f"joint centres of gaitcap's body model ({len(joints.names)} of 20 points" in res.output
    assert "does NOT fit" not in res.output


def test_a_static_trial_given_as_the_walk_is_named_as_such():
    res = CliRunner().invoke(cli, ["report", str(WALKING / "subject01_static.trc")])
    assert res.exit_code == 1
    assert "subject01_static.trc: this is a static trial (*_static.trc), which the mapping reads beside" in res.output


def test_report_on_raw_c3d_with_mapping_option(tmp_path):
    res = CliRunner().invoke(cli, ["report", str(RAW), "-o", str(tmp_path / "g"), "--mapping", "plugin_gait"])
    assert res.exit_code == 0, res.output
    assert "complete cycles" in res.output and (tmp_path / "g" / "events.csv").is_file()


def test_report_on_trc_with_opensim_style_header(tmp_path):
    odd = _opensim_style(OPENSIM, tmp_path / "subject01_walk1.trc")
    (tmp_path / "subject01_static.trc").write_bytes((WALKING / "subject01_static.trc").read_bytes())
    res = CliRunner().invoke(cli, ["report", str(odd), "-o", str(tmp_path / "g")])
    assert res.exit_code == 0, res.output
    assert "2 complete cycles" in res.output


def test_synth_on_prefixed_sacr_pig_file(tmp_path):
    from gaitcap.synth.session import SynthOptions, synthesize

    opts = SynthOptions(cameras=2, size=(96, 72), fps=10.0, codec="ffv1")
    result = synthesize(PIG, tmp_path / "s", opts, progress=False, mapping="plugin_gait", subject="A22")
    assert result.n_frames == 29  # 2.84 s at 10 fps
    assert max(result.fit.residual_m.values()) < 0.05


def test_force_plate_events_of_a_c3d_without_event_group():
    raw = read_motion(RAW)  # no EVENT group: events from its two force plates
    assert raw.events and {e.source for e in raw.events} == {"forceplate"}
    recorded = read_motion(PIG).events  # the same trial, events set by the lab
    for e in raw.events:
        same = [r.time_s for r in recorded if (r.side, r.event) == (e.side, e.event)]
        assert min(abs(t - e.time_s) for t in same) <= 1.0 / raw.rate_hz
    assert len(raw.events) == 4  # two plates: one strike and one foot off of each foot


def test_sacral_marker_gives_the_anatomical_pelvis_frame():
    from gaitcap.report.pipeline import with_pelvis_markers

    joints = with_pelvis_markers(read_motion(PIG), read_markers(PIG))
    np.testing.assert_allclose(joints.point("SACR"), read_markers(PIG).point("SACR"))
    assert not joints.has("LPSI") and not joints.has("RPSI")  # the file has none: not named as if it had
    _, direction = detect_events(joints)
    ang, _ = joint_angles(joints, direction)
    hip = read_c3d_angles(PIG).get("LHipAngles")[:, 0]
    ok = np.isfinite(ang["hip_flexion_l"]) & np.isfinite(hip)
    assert np.sqrt(np.mean((ang["hip_flexion_l"][ok] - hip[ok]) ** 2)) < 1.0  # 5.0 deg with the hip centres only


def test_opensim_pelvis_markers_give_the_anatomical_pelvis_frame():
    """The OpenSim walk spells its pelvis markers L.ASIS, R.ASIS, V.Sacral: they were not looked for, so its
    report took the pelvis from the hip centres and the thorax and said it had no ASIS/PSIS markers."""
    from gaitcap.gait.angles import pelvis_frame
    from gaitcap.report.pipeline import with_pelvis_markers

    markers = read_markers(OPENSIM)
    joints = with_pelvis_markers(read_motion(OPENSIM), markers)
    assert joints.names[-3:] == ("L.ASIS", "R.ASIS", "V.Sacral")  # the file's own names, the sacrum once
    np.testing.assert_allclose(joints.point("V.Sacral"), markers.point("V.Sacral"))
    assert pelvis_frame(joints)[1] == "ASIS/PSIS markers"
    assert pelvis_frame(read_motion(OPENSIM))[1] != "ASIS/PSIS markers"


def test_report_with_the_files_recorded_events(tmp_path):
    """--recorded-events: the parameters, cycles and events.csv come from the file's EVENT group; a file that
    records none is refused by name."""
    import csv

    res = CliRunner().invoke(cli, ["report", str(PIG), "-o", str(tmp_path / "rec"), "--recorded-events"])
    assert res.exit_code == 0, res.output
    recorded = read_motion(PIG).events
    with open(tmp_path / "rec" / "events.csv") as f:
        rows = [(r["side"], r["event"], round(float(r["time_s"]), 3)) for r in csv.DictReader(f)]
    assert sorted(rows) == sorted((e.side, e.event, round(e.time_s, 3)) for e in recorded) and len(rows) == 9
    lonely = tmp_path / "walk.trc"
    shutil.copyfile(OPENSIM, lonely)  # no force-plate file beside it: no events
    res = CliRunner().invoke(cli, ["report", str(lonely), "-o", str(tmp_path / "x"), "--recorded-events",
                                   "--static", str(OPENSIM.with_name("subject01_static.trc"))])  # fmt: skip
    assert res.exit_code == 1 and "walk.trc: --recorded-events: the file records no gait event" in res.output


def test_exported_c3d_names_only_the_pelvis_markers_the_file_has(tmp_path):
    """gait-pig.c3d has a sacral marker and no PSIS: report's trajectories.c3d held LPSI and RPSI, both the
    SACR samples (a lab's software would take them for two PSIS markers at the same place)."""
    import ezc3d

    res = CliRunner().invoke(cli, ["report", str(PIG), "-o", str(tmp_path / "gait")])
    assert res.exit_code == 0, res.output
    c3d = ezc3d.c3d(str(tmp_path / "gait" / "trajectories.c3d"))
    labels = list(c3d["parameters"]["POINT"]["LABELS"]["value"])
    assert "LPSI" not in labels and "RPSI" not in labels
    assert {"LASI", "RASI", "SACR"} <= set(labels)
    sacr = c3d["data"]["points"][:3, labels.index("SACR")].T / 1000.0
    np.testing.assert_allclose(sacr, read_markers(PIG).point("SACR"), atol=1e-5, equal_nan=True)
    assert "ASIS/PSIS" in (tmp_path / "gait" / "report.html").read_text()  # still the anatomical pelvis frame


def test_mapping_marker_typo_named_with_file_definition_and_closest_name(tmp_path):
    """A lab mapping with a typo in a marker name ('LKNEE' for LKNE) or in a helper point's name
    ('kjc_1' for kjc_l): report/synth said only "mapping 'my_lab' needs markers missing from the
    file: LKNEE", and `gaitcap markers` only "missing LKNEE" (found writing a lab's own mapping)."""
    mine = tmp_path / "my_lab.yaml"
    mine.write_text(
        "name: my_lab\nvirtual:\n"
        "  hjc_l: {harrington: {side: left, lasi: LASI, rasi: RASI, sacral: SACR}}\n"
        "  kjc_l: {chord: {proximal: hjc_l, wand: LTHI, marker: LKNEE, distance_m: 0.057}}\n"
        "points:\n  hip_l: {marker: hjc_l}\n  knee_l: {marker: kjc_l}\n  ankle_l: {marker: kjc_1}\n"
    )
    with pytest.raises(InputError) as err:
        read_motion(RAW, mapping=mine)
    text = str(err.value)
    assert "my_lab.yaml" in text
    assert "LKNEE (named by kjc_l; needed for knee_l; did you mean 'LKNE'?)" in text
    assert "kjc_1 (named by ankle_l; did you mean 'kjc_l'?)" in text
    res = CliRunner().invoke(cli, ["markers", str(RAW), "--mapping", str(mine)])
    assert res.exit_code == 1 and "did you mean 'LKNE'?" in res.output


@pytest.mark.parametrize(("rule", "key", "said"), [
    ("{shift: {point: LKNE, direction: [LKNE, RKNE], distance_m: 40}}", "shift.distance_m", "40 mm is 0.04 m"),
    ("{shift: {point: LKNE, direction: [LKNE, RKNE], fraction: 17, fraction_of: [LKNE, RKNE]}}", "shift.fraction",
     "17 % is 0.17"),
    ("{lerp: {start: LKNE, end: RKNE, fraction: 50}}", "lerp.fraction", "50 % is 0.5"),
    ("{chord: {proximal: LASI, wand: LTHI, marker: LKNE, distance_m: 57}}", "chord.distance_m", "57 mm is 0.057 m"),
    ("{sole: {point: LTOE, heel: LANK, toe: LTOE, height_m: 20}}", "sole.height_m", "20 mm is 0.02 m"),
])  # fmt: skip
def test_mapping_offsets_in_millimetres_or_percent_refused_naming_the_unit(tmp_path, rule, key, said):
    """A shift of 40 (mm meant) or a fraction of 17 (% meant) put a lab's elbow or heel tens of
    metres away with no word (found writing a lab's own mapping); a chord distance of 57 was
    refused only as 'less than or equal to 0.2'."""
    mine = tmp_path / "my_lab.yaml"
    mine.write_text(f"name: my_lab\npoints:\n  knee_l: {rule}\n")
    with pytest.raises(ConfigError) as err:
        load_mapping(mine)
    assert "my_lab.yaml" in str(err.value) and f"points.knee_l.{key}" in str(err.value) and said in str(err.value)


def test_mapping_leaving_out_a_joint_refused_by_markers_report_and_synth_naming_it(tmp_path):
    """A lab mapping that leaves out knee_r: `gaitcap markers` said 'fits' (exit 0), then report
    stopped on "trajectory has no point 'knee_r'" and synth, after fitting the body model, on
    'joint centres missing for the fit: knee_r', neither naming the mapping (found writing a lab's
    own mapping for a renamed walk.c3d)."""
    shipped = (MAPPINGS_DIR / "plugin_gait.yaml").read_text()
    mine = tmp_path / "my_lab.yaml"
    mine.write_text(shipped.replace("  knee_r: {marker: kjc_r}\n", ""))
    res = CliRunner().invoke(cli, ["markers", str(RAW), "--mapping", str(mine)])
    assert res.exit_code == 1 and "does NOT fit: defines no knee_r under points" in res.output
    for command in (["report", str(RAW), "-o", str(tmp_path / "r")], ["synth", str(RAW), "-o", str(tmp_path / "s")]):
        res = CliRunner().invoke(cli, [*command, "--mapping", str(mine)])
        assert res.exit_code == 1, res.output
        assert "mapping 'plugin_gait' (" in res.output and "my_lab.yaml) defines no knee_r under points" in res.output
        assert not (tmp_path / command[-1][-1]).exists()
    assert read_motion(RAW, mapping=mine).names.count("knee_r") == 0  # the library reads what it defines


def _edited_mapping(folder, old: str, new: str):
    """A lab's mapping: the shipped Plug-in-Gait one with ``old`` (which it holds) replaced by ``new``."""
    shipped = (MAPPINGS_DIR / "plugin_gait.yaml").read_text()
    assert old in shipped
    mine = folder / "my_lab.yaml"
    mine.write_text(shipped.replace(old, new))
    return mine


@pytest.mark.parametrize(("old", "new", "pair"), [
    ("harrington: {side: left, lasi: LASI, rasi: RASI, sacral: SACR}",
     "harrington: {side: right, lasi: LASI, rasi: RASI, sacral: SACR}", "hip_l and hip_r"),
    ("  knee_l: {marker: kjc_l}", "  knee_l: {marker: kjc_r}", "knee_l and knee_r"),
])  # fmt: skip
def test_mapping_giving_one_point_for_left_and_right_refused(tmp_path, old, new, pair):
    """A lab mapping with the wrong side ('side: right' in the left hip's Harrington rule, or
    knee_l reading kjc_r) gave a report and a synthetic session with both hips (knees) at one
    point and exit 0 (found writing a lab's own mapping for a renamed walk.c3d)."""
    mine = _edited_mapping(tmp_path, old, new)
    with pytest.raises(InputError) as err:
        read_motion(RAW, mapping=mine)
    assert "my_lab.yaml" in str(err.value) and f"{pair} are the same point (0.0 mm apart" in str(err.value)
    res = CliRunner().invoke(cli, ["report", str(RAW), "--mapping", str(mine), "-o", str(tmp_path / "r")])
    assert res.exit_code == 1 and "the same point" in res.output and not (tmp_path / "r").exists()


@pytest.mark.parametrize(("old", "new", "said"), [
    ("chord: {proximal: hjc_l, wand: LTHI, marker: LKNE", "chord: {proximal: hjc_l, wand: LTHI, marker: RKNE",
     "kjc_l: its chord's wand LTHI and marker RKNE are not on one segment: their distance changes by 67 mm"),
    ("chord: {proximal: hjc_l, wand: LTHI, marker: LKNE", "chord: {proximal: hjc_l, wand: RTHI, marker: LKNE",
     "kjc_l: its chord's wand RTHI and marker LKNE are not on one segment"),
    ("chord: {proximal: kjc_l, wand: LTIB, marker: LANK", "chord: {proximal: kjc_l, wand: LTIB, marker: RANK",
     "ajc_l: its chord's wand LTIB and marker RANK are not on one segment"),
    ("chord: {proximal: hjc_l, wand: LTHI, marker: LKNE", "chord: {proximal: hjc_l, wand: RTHI, marker: RKNE",
     "the left shank, knee_l to ankle_l, changes length by 294 mm over the frames (333 to 627 mm"),
])  # fmt: skip
def test_mapping_naming_the_other_sides_marker_in_a_chord_refused(tmp_path, old, new, said):
    """A lab mapping whose left knee (ankle) chord names a right marker ('marker: RKNE' in kjc_l's
    rule) was accepted: 'gaitcap markers' said 'fits' (exit 0) and the left knee lay 37 mm from the
    right one, the left shank 526 mm long (its length changing by 242 mm over walk.c3d), with exit 0.
    The chord's wand and marker must stay on one segment, and each thigh and shank keep its length."""
    mine = _edited_mapping(tmp_path, old, new)
    with pytest.raises(InputError) as err:
        read_motion(RAW, mapping=mine)
    assert f"{RAW}: mapping 'plugin_gait' ({mine}): {said}" in str(err.value)
    assert "names the other side's marker or point" in str(err.value)
    res = CliRunner().invoke(cli, ["markers", str(RAW), "--mapping", str(mine)])
    assert res.exit_code == 1 and "mapping plugin_gait: does NOT fit: " in res.output and said in res.output
    res = CliRunner().invoke(cli, ["report", str(RAW), "--mapping", str(mine), "-o", str(tmp_path / "r")])
    assert res.exit_code == 1 and said in res.output and not (tmp_path / "r").exists()


def test_shipped_files_keep_their_limbs_and_chords_on_one_segment():
    """The checks above refuse none of the real walks with their shipped mappings (and `gaitcap markers`
    computing the joint centres prints no log of the reading)."""
    for path in (RAW, PIG, OPENSIM, WALKING / "rajagopal_walk.trc"):
        read_motion(path)
    res = CliRunner().invoke(cli, ["markers", str(RAW)])
    assert res.exit_code == 0 and "mapping plugin_gait: fits" in res.output
    assert "typical chord distance" not in res.output  # the reading's information log


def test_recorded_events_are_not_called_detected(tmp_path):
    """With --recorded-events the parameters come from the file's EVENT group, yet parameters.json's
    info.event_method said 'Zeni et al. 2008 ...' and report.html 'Events: 9 detected (Zeni et al. 2008 ...),
    9 recorded in the file': a clinician took the table for the detector's (found comparing walk.c3d's report
    with and without the flag). Now both name the recorded events; without the flag, as before."""
    import json
    import re

    from gaitcap.gait.analysis import RECORDED_EVENT_METHOD

    for flag, out in (("--recorded-events", "rec"), (None, "det")):
        res = CliRunner().invoke(cli, ["report", str(PIG), "-o", str(tmp_path / out)] + ([flag] if flag else []))
        assert res.exit_code == 0, res.output
    rec = json.loads((tmp_path / "rec" / "parameters.json").read_text())["info"]["event_method"]
    det = json.loads((tmp_path / "det" / "parameters.json").read_text())["info"]["event_method"]
    assert rec == RECORDED_EVENT_METHOD and det.startswith("Zeni")
    text = (tmp_path / "rec" / "report.html").read_text()
    assert "detected (Zeni" not in text
    assert re.search(r"Events: the 9 recorded in the file \(--recorded-events\), used for the parameters", text)
    assert re.search(r"Events: 12 detected \(Zeni.*\), 9 recorded in the file", (tmp_path / "det" / "report.html").read_text())


def test_pelvic_rotation_differs_from_plug_in_gait_by_the_walking_direction():
    """README ('angles.csv'): the pelvis angles are relative to the estimated walking direction, Plug-in-Gait's
    to the lab's axis, so pelvic rotation differs from the file's own by the angle between them (2.8 deg on
    gait-pig.c3d); a clinician comparing the two saw a constant offset the README did not explain."""
    from gaitcap.gait.analysis import analyse
    from gaitcap.report.pipeline import with_pelvis_markers

    a = analyse(with_pelvis_markers(read_motion(PIG), read_markers(PIG)))
    heading = float(np.degrees(np.arctan2(a.direction.forward[1], a.direction.forward[0])))
    pig = read_c3d_angles(PIG)
    for side, sign in (("l", 1.0), ("r", -1.0)):
        ours, theirs = a.angles[f"pelvis_rotation_{side}"], pig.get(f"{side.upper()}PelvisAngles")[:, 2]
        ok = np.isfinite(ours) & np.isfinite(theirs)
        offset = float(np.mean(ours[ok] - theirs[ok]))
        assert offset == pytest.approx(sign * heading, abs=0.1) and abs(heading) == pytest.approx(2.8, abs=0.1)
        assert float(np.std(ours[ok] - theirs[ok])) < 0.2
