"""`gaitcap report` end to end: outputs, not-enough-steps exit code, real embedded walk."""

from __future__ import annotations

import csv
import json
import re
from dataclasses import replace

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from gait_walker import Walker

from gaitcap.cli.main import cli
from gaitcap.data import embedded_walk
from gaitcap.gait.analysis import analyse
from gaitcap.io.c3d import read_c3d_angles
from gaitcap.io.trajectories_h5 import write_trajectory
from gaitcap.markers.motion import read_markers, read_motion
from gaitcap.report.pipeline import with_pelvis_markers

FILES = ("events.csv", "parameters.json", "parameters.csv", "strides.csv", "angles.csv", "cycles.h5", "trajectories.c3d", "report.html")


def test_report_on_a_tracking_folder_writes_every_output(tmp_path) -> None:
    w = Walker(duration=4.0, rate_hz=25.0)
    out = tmp_path / "OUT"
    write_trajectory(out / "trajectories.h5", w.trajectory())
    res = CliRunner().invoke(cli, ["report", str(out)])
    assert res.exit_code == 0, res.output
    gait = out / "gait"
    assert all((gait / f).is_file() for f in FILES)
    rows = list(csv.DictReader((gait / "events.csv").open()))
    assert {r["side"] for r in rows} == {"left", "right"} and {r["event"] for r in rows} == {"foot_strike", "foot_off"}
    # the nearest frame (time_s is written to 0.1 ms, so a time within 0.05 ms of a half frame may round either way)
    assert all(abs(int(r["frame"]) - float(r["time_s"]) * 25.0) <= 0.5 + 25.0 * 5e-5 for r in rows)
    p = json.loads((gait / "parameters.json").read_text())
    assert p["status"] == "ok"
    assert p["overall"]["cadence_steps_per_min"] == pytest.approx(120 / w.stride_time, rel=0.02)
    for side in ("left", "right"):
        for key in ("stride_length_m", "step_length_m", "stride_time_s", "step_time_s", "stance_pct", "swing_pct", "n_strides"):
            assert p[side][key] is not None
    with h5py.File(gait / "cycles.h5") as f:
        assert f["left/knee_flexion"].shape[1] == 101 and f["left/knee_flexion"].shape[0] == p["left"]["n_strides"]
    html = (gait / "report.html").read_text()
    assert html.count("data:image/png;base64,") == 4 and "http" not in html.replace("http-equiv", "")
    assert re.search(r"Walking direction -?\d+° from the calibration's x axis \(nearest to [+-][xy]\)", html), html[:2000]
    assert "A dash (–): not measured" in html and "A blank cell: not defined" in html
    assert "tracking_verdict" not in p  # no track.json: not a tracking run's verdict to carry
    (out / "track.json").write_text(json.dumps({"status": "ok", "verdict": "failed",
                                                "verdict_reasons": ["none of the 100 frames fits the silhouettes"]}))
    res = CliRunner().invoke(cli, ["report", str(out), "-o", str(tmp_path / "gait2")])
    assert res.exit_code == 0, res.output
    p = json.loads((tmp_path / "gait2" / "parameters.json").read_text())
    assert p["tracking_verdict"] == {"verdict": "failed", "reasons": ["none of the 100 frames fits the silhouettes"]}


def test_report_with_less_than_one_cycle_exits_3_and_says_why(tmp_path) -> None:
    out = tmp_path / "OUT"
    tr = Walker(duration=0.9).trajectory()
    pts = tr.points.copy()
    pts[40:45] = np.nan
    write_trajectory(out / "trajectories.h5", replace(tr, points=pts))
    res = CliRunner().invoke(cli, ["report", str(out)])
    assert res.exit_code == 3
    assert res.output.count("not enough steps") == 1  # said once (the analysis's warning), not echoed again
    p = json.loads((out / "gait" / "parameters.json").read_text())
    assert p["status"] == "not_enough_steps" and "not enough steps" in p["reason"]
    assert f"; 5 of the {tr.n_frames} frames have no position (flagged by the tracker or missing)" in p["reason"]
    assert p["left"]["n_strides"] == 0 and p["overall"]["speed_m_s"] is None
    html = (out / "gait" / "report.html").read_text()
    assert "Not enough steps" in html
    assert "<td>–</td>" in html and "A dash (–): not measured" in html  # the table's dashes, explained


def test_report_errors_are_one_line_exit_1(tmp_path) -> None:
    res = CliRunner().invoke(cli, ["report", str(tmp_path)])
    assert res.exit_code == 1 and "trajectories.h5" in res.output
    (tmp_path / "gait.yaml").write_text("lowpas_hz: 3\n")
    write_trajectory(tmp_path / "trajectories.h5", Walker(duration=2.0).trajectory())
    res = CliRunner().invoke(cli, ["report", str(tmp_path), "--config", str(tmp_path / "gait.yaml")])
    assert res.exit_code == 1 and "lowpass_hz" in res.output


def test_embedded_vicon_walk_events_and_angles_match_the_recording() -> None:
    """Regression guard on real data (figures of scripts/validate_gait.py on the full file)."""
    path = embedded_walk()
    joints = read_motion(path)
    a = analyse(with_pelvis_markers(joints, read_markers(path)))
    errs = []
    for ref in joints.events:
        same = [e.time_s for e in a.events if (e.side, e.event) == (ref.side, ref.event)]
        errs.append(min(abs(t - ref.time_s) for t in same))
    errs = np.array(errs)
    assert len(errs) == 8 and np.mean(errs <= 0.020) >= 0.85 and errs.max() <= 0.03
    pig = read_c3d_angles(path)
    for ours, theirs, limit in (("knee_flexion", "KneeAngles", 5.0), ("hip_flexion", "HipAngles", 5.0)):
        for s, p in (("l", "L"), ("r", "R")):
            d = a.angles[f"{ours}_{s}"] - pig.get(f"{p}{theirs}")[:, 0]
            assert np.sqrt(np.nanmean(d**2)) < limit
            assert np.nanstd(d) < 2.0  # same shape; the offset is the frame definitions'
    assert a.parameters.ok and a.parameters.overall["n_strides"] == 2
    assert a.parameters.overall["speed_m_s"] == pytest.approx(0.9, abs=0.1)  # the data README: about 0.9 m/s


def test_angle_note_says_hip_flexion_lacks_the_pelvis_tilt_without_pelvis_markers(tmp_path) -> None:
    """Without ASIS/PSIS markers (every tracking run) the note named only pelvic tilt, while hip flexion is measured
    from the same pelvis and reads 5-11 degrees below Plug-in-Gait's (scripts/validate_gait.py, joint centres only):
    a clinician read hip hyperextension that is not there."""
    out = tmp_path / "OUT"
    write_trajectory(out / "trajectories.h5", Walker(duration=4.0, rate_hz=25.0).trajectory())
    res = CliRunner().invoke(cli, ["report", str(out)])
    assert res.exit_code == 0, res.output
    text = re.sub(r"\s+", " ", (out / "gait" / "report.html").read_text())
    assert "Without ASIS/PSIS markers" in text
    note = text[text.index("Without ASIS/PSIS markers"):]
    note = note[: note.index("</p>")]
    assert "hip flexion" in note and "Plug-in-Gait" in note and "see the docs" not in note
    res = CliRunner().invoke(cli, ["report", str(embedded_walk()), "-o", str(tmp_path / "walk")])
    assert res.exit_code == 0, res.output
    assert "Without ASIS/PSIS markers" not in (tmp_path / "walk" / "report.html").read_text()  # its own pelvis markers


def test_readme_lists_every_file_report_writes() -> None:
    """The README documented track's and silhouettes' outputs but none of report's: where angles.csv's unit
    (degrees), events.csv's frame or the C3D's axes are said was nowhere a user reads."""
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    assert "## Outputs of `gaitcap report`" in readme
    section = readme.split("## Outputs of `gaitcap report`", 1)[1].split("\n## ", 1)[0]
    for name in FILES:
        assert f"`{name}`" in section, name
    assert "degrees" in section and "Y_SCREEN" in section


def test_a_report_stopped_half_way_leaves_no_earlier_report_beside_its_files(tmp_path, monkeypatch) -> None:
    """Found by interrupting 'gaitcap report OUT' (Ctrl-C after 3 s) over an earlier report: events.csv,
    parameters.json ... were the new run's and report.html the earlier run's, a set that looked complete.
    Now the earlier files are removed first: the stopped run leaves only what it wrote, and no report.html."""
    import gaitcap.report.pipeline as report_pipeline

    out = tmp_path / "OUT"
    write_trajectory(out / "trajectories.h5", Walker(duration=4.0, rate_hz=25.0).trajectory())
    assert CliRunner().invoke(cli, ["report", str(out)]).exit_code == 0
    assert all((out / "gait" / f).is_file() for f in FILES)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(report_pipeline, "write_c3d", interrupted)
    res = CliRunner().invoke(cli, ["report", str(out)])
    assert res.exit_code == 1 and "Aborted!" in res.output
    assert sorted(p.name for p in (out / "gait").iterdir()) == sorted(FILES[:6])  # the new run's, before the C3D
    monkeypatch.undo()
    assert CliRunner().invoke(cli, ["report", str(out)]).exit_code == 0  # a re-run writes the whole set
    assert all((out / "gait" / f).is_file() for f in FILES)
