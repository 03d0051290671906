"""The report's view of the tracking fit: the verdict banner, the frames chosen for the contact
sheet, the angle bands, the drawn model and the self-contained HTML (no browser needed)."""

from __future__ import annotations

import base64
import json
import re
import shutil
from dataclasses import replace
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from gait_walker import Walker

from gaitcap.cli.main import cli
from gaitcap.gait.analysis import analyse
from gaitcap.io.track_h5 import QUALITY_POOR_FIT, TrackRecord
from gaitcap.io.truth_folder import read_events_csv
from gaitcap.io.trajectories_h5 import write_trajectory
from gaitcap.report.fit import (MAX_ATTENTION_FRAMES, UNCERTAIN_MM, FitRecord, angle_bands, attention_frames,
                                load_fit_record, select_frames)  # fmt: skip
import gaitcap.track_summary as track_summary
from gaitcap.track_summary import read_verdict
from gaitcap.report.sheet import draw_model, project_model, tracked_model
from gaitcap.session import Session
from gaitcap.trajectory import GaitEvent

IMG = re.compile(r"src='data:(image/(?:png|jpeg));base64,([^']+)'")


def _record(T: int = 60, fit: float = 0.8, sigma_m: float = 0.02) -> TrackRecord:
    P = 20
    return TrackRecord(tuple(f"p{k}" for k in range(14)) + ("hip_l", "hip_r", "knee_l", "knee_r", "ankle_l", "ankle_r"),
                       25.0, np.zeros((T, P, 3)), np.full((T, P), sigma_m), np.zeros((T, 31)), tuple("q" * 31),
                       np.full(T, fit), np.zeros(T, np.uint8))  # fmt: skip


def _events(times: list[float]) -> list[GaitEvent]:
    kinds = ("foot_strike", "foot_off")
    return [GaitEvent(t, "left" if k % 2 == 0 else "right", kinds[(k // 2) % 2]) for k, t in enumerate(times)]


def test_sheet_takes_the_events_and_the_worst_frame_of_each_flagged_run():
    rec = _record()
    rec.quality[30:36] = QUALITY_POOR_FIT
    rec.fit[30:36] = [0.5, 0.45, 0.3, 0.4, 0.5, 0.52]
    frames = select_frames(FitRecord(Path("."), rec), _events([0.4, 0.8, 1.2, 1.6]))
    by_index = {f.index: f for f in frames}
    assert {10, 20, 30, 40} <= set(by_index)  # the events, at 25 Hz
    assert by_index[32].attention and "poor fit" in by_index[32].reasons  # the run's lowest fit
    assert not by_index[10].attention and by_index[10].reasons == ("left foot strike",)
    assert all(f.attention == (30 <= f.index < 36) for f in frames)
    assert [f.index for f in frames] == sorted(by_index)


def test_sheet_shows_uncertain_frames_and_caps_the_attention_frames():
    rec = _record(T=200)
    rec.uncertainty[50:53] = (UNCERTAIN_MM + 10) / 1000
    rec.uncertainty[51, -6:] = (UNCERTAIN_MM + 30) / 1000
    rec.quality[100:200] = QUALITY_POOR_FIT
    rec.fit[100:200] = np.linspace(0.5, 0.1, 100)
    fit = FitRecord(Path("."), rec)
    frames = select_frames(fit, [])
    attention = [f for f in frames if f.attention]
    assert len(attention) == MAX_ATTENTION_FRAMES
    assert 199 in {f.index for f in attention}  # the lowest fit of the flagged run
    assert fit.uncertain[51] and not fit.uncertain[49]
    assert sum("evenly spaced" in f.reasons for f in frames) == 8  # without events, 8 frames over the run


def test_verdict_is_read_when_present_and_absent_otherwise():
    assert read_verdict({"status": "ok"}) is None and read_verdict(None) is None
    v = read_verdict({"verdict": "failed", "verdict_reasons": ["the subject was lost", "legs swapped"]})
    assert v is not None and v.line() == "verdict: failed (the subject was lost; legs swapped)"
    assert read_verdict({"verdict": "ok"}).line() == "verdict: ok"


def test_verdict_notes_reach_the_banner_as_notes():
    from gaitcap.report.html import verdict_banner

    v = read_verdict({"verdict": "ok", "verdict_reasons": [], "verdict_notes": ["no camera views the walk <obliquely>"]})
    assert v is not None and v.notes == ("no camera views the walk <obliquely>",) and v.line() == "verdict: ok"
    banner = verdict_banner(v)
    assert "Verdict: ok" in banner and "<i>note: no camera views the walk &lt;obliquely&gt;</i>" in banner
    assert "<li>" not in verdict_banner(read_verdict({"verdict": "ok"}))


def test_the_angle_note_warns_of_the_ankles_when_the_verdict_notes_feet_off_the_masks():
    """A clinician read the demo's left ankle at -59 to 31 degrees (Plug-in-Gait's -10 to 20) with the only
    warning in the verdict's banner: where the verdict notes feet off the masks, the angle note says the
    ankle curves follow the legs."""
    from gaitcap.report.html import FitView, render_report

    analysis = analyse(Walker(duration=4.0, rate_hz=25.0).trajectory())
    feet = "feet placed where a camera's silhouette has little of them (foot_l in 35 of 56 frames: ...)"
    warned = render_report(analysis, view=FitView(verdict=read_verdict({"verdict": "ok", "verdict_notes": [feet]})))
    assert "The ankle angles come from the tracked heel and toe points" in warned
    for notes in ([], ["no camera views the walk obliquely"]):
        quiet = render_report(analysis, view=FitView(verdict=read_verdict({"verdict": "ok", "verdict_notes": notes})))
        assert "The ankle angles come from" not in quiet
    assert "The ankle angles come from" not in render_report(analysis)  # a marker file: no verdict


def test_angle_bands_grow_with_the_uncertainty_and_are_seeded():
    traj = Walker(duration=2.0, rate_hz=50.0).trajectory()
    direction = analyse(traj).direction
    names = ("knee_flexion_l", "hip_flexion_r", "ankle_dorsiflexion_l")
    assert angle_bands(traj, direction, names) is None
    T, P = traj.points.shape[:2]
    small = angle_bands(replace(traj, meta={"uncertainty": np.full((T, P), 0.005)}), direction, names)
    large = angle_bands(replace(traj, meta={"uncertainty": np.full((T, P), 0.02)}), direction, names)
    again = angle_bands(replace(traj, meta={"uncertainty": np.full((T, P), 0.02)}), direction, names)
    zero = angle_bands(replace(traj, meta={"uncertainty": np.zeros((T, P))}), direction, names)
    for n in names:
        assert np.all(zero[n] < 1e-9)
        assert 0.1 < np.median(small[n]) < np.median(large[n]) < 30.0
        # first order: the band scales with sigma (x4 here), within the Monte Carlo noise of 32 draws
        assert 2.5 < np.median(large[n]) / np.median(small[n]) < 6.0
        np.testing.assert_array_equal(large[n], again[n])


def test_report_on_a_run_without_a_tracker_record_has_no_fit_section(tmp_path):
    out = tmp_path / "OUT"
    write_trajectory(out / "trajectories.h5", Walker(duration=3.0).trajectory())
    (out / "track.json").write_text(json.dumps({"status": "ok", "verdict": "ok", "verdict_reasons": []}))
    res = CliRunner().invoke(cli, ["report", str(out)])
    assert res.exit_code == 0, res.output
    assert "verdict: ok" in res.output.splitlines()
    html = (out / "gait" / "report.html").read_text()
    assert "Verdict: ok" in html and "Contact sheet" not in html
    assert "No band: this trajectory carries no per-point uncertainty" in html


# ----------------------------------------------------------------------- on a tracked run


def _decoded_images(html: str) -> list[tuple[str, np.ndarray]]:
    out = []
    for mime, data in IMG.findall(html):
        img = cv2.imdecode(np.frombuffer(base64.b64decode(data), np.uint8), cv2.IMREAD_COLOR)
        assert img is not None and img.size > 0, mime
        out.append((mime, img))
    return out


@pytest.fixture(scope="module")
def tracked_copy(tracked_session, tmp_path_factory):
    """The tracked run and its session copied (the tests change their files), track.json with a verdict."""
    synth, out, _ = tracked_session
    root = tmp_path_factory.mktemp("report_fit")
    shutil.copytree(out, root / "run")
    shutil.copytree(synth.session, root / "session")
    doc = json.loads((root / "run" / "track.json").read_text())
    doc.update(verdict="doubtful", verdict_reasons=["3 frames fit the silhouettes poorly"])
    (root / "run" / "track.json").write_text(json.dumps(doc))
    return synth, root


def test_tracked_model_is_the_model_the_run_tracked(tracked_copy):
    _, root = tracked_copy
    fit = load_fit_record(root / "run" / "trajectories.h5")
    model, note = tracked_model(fit)
    assert model is not None and note == ""
    ok = np.all(np.isfinite(fit.record.poses), axis=1)
    np.testing.assert_allclose(model.forward(fit.record.poses[ok]), fit.record.points[ok], atol=1e-9)


def test_drawn_model_covers_its_projection_and_nothing_far_from_it(tracked_copy):
    synth, root = tracked_copy
    fit = load_fit_record(root / "run" / "trajectories.h5")
    model, _ = tracked_model(fit)
    cam = Session.open(root / "session").rig[0]
    q = fit.record.poses[5]
    pc = project_model(cam, model, q)
    image = np.full((cam.height, cam.width, 3), 128, np.uint8)
    sides = ["centre"] * len(pc.ra)
    draw_model(image, pc, sides, 1)
    changed = np.any(image != 128, axis=2)
    pelvis = np.round((pc.a[0] + pc.b[0]) / 2).astype(int)
    assert changed[pelvis[1], pelvis[0]]
    # the pelvis joint projected through the calibration lies on the drawn body
    u, v = np.round(cam.project(fit.record.points[5, fit.record.names.index("pelvis")])).astype(int)
    assert changed[v, u]
    ys, xs = np.nonzero(changed)
    reach = np.max(np.r_[pc.ra, pc.rb]) + 3
    assert xs.min() >= np.min(np.r_[pc.a[:, 0], pc.b[:, 0]]) - reach and xs.max() <= np.max(np.r_[pc.a[:, 0], pc.b[:, 0]]) + reach


def test_report_of_a_tracked_run_embeds_the_contact_sheet_and_the_banner(tracked_copy):
    _, root = tracked_copy
    res = CliRunner().invoke(cli, ["report", str(root / "run"), "--session", str(root / "session"), "-o", str(root / "g1")])
    assert res.exit_code in (0, 3), res.output
    assert "verdict: doubtful (3 frames fit the silhouettes poorly)" in res.output.splitlines()
    html = (root / "g1" / "report.html").read_text()
    assert html.index("Verdict: doubtful") < html.index("How well the model fits")
    images = _decoded_images(html)
    jpegs = [img for mime, img in images if mime == "image/jpeg"]
    n_cells = html.count("<div class='cell")
    assert len(jpegs) == 2 * n_cells  # one thumbnail per camera and frame
    # one cell per frame the sheet chooses for the report's own events (and the frames needing a look)
    events = list(read_events_csv(root / "g1" / "events.csv"))
    fit = load_fit_record(root / "run" / "trajectories.h5")
    chosen = [f.index for f in select_frames(fit, events)]
    assert events and [int(t) for t in re.findall(r"<b>#(\d+)</b>", html)] == chosen
    assert n_cells == len(chosen) and {int(round(e.time_s * fit.record.rate_hz)) for e in events} <= set(chosen)
    assert all(img.shape[0] == 240 for img in jpegs)
    assert len(html) < 3_000_000 and "http" not in html.replace("http-equiv", "")
    assert "tracked body model (capsules)" in html
    session = Path(json.loads((root / "run" / "track.json").read_text())["session"]).name
    # the session, not trajectories.h5, and the verdict (printed in every page's header)
    assert f"<title>Gait report — {session} (run) — verdict: doubtful</title>" in html


def test_report_without_the_videos_omits_the_sheet_and_says_why(tracked_copy):
    _, root = tracked_copy
    gone = root / "session_gone"
    shutil.copytree(root / "session", gone)
    shutil.rmtree(gone / "videos")
    res = CliRunner().invoke(cli, ["report", str(root / "run"), "--session", str(gone), "-o", str(root / "g2")])
    assert res.exit_code in (0, 3), res.output
    html = (root / "g2" / "report.html").read_text()
    assert "The contact sheet is omitted: the session cannot be read" in html and "videos" in html
    assert not any(mime == "image/jpeg" for mime, _ in _decoded_images(html))
    assert "How well the model fits" in html  # the fit plot needs no video
    res = CliRunner().invoke(cli, ["report", str(root / "run"), "--session", str(root / "nowhere"), "-o", str(root / "g3")])
    html = (root / "g3" / "report.html").read_text()
    assert "the session folder given with --session is not found" in html and "give it with --session" not in html
    other = root / "other_walk"  # another session (by its name): said, and drawn as asked
    shutil.copytree(root / "session", other)
    res = CliRunner().invoke(cli, ["report", str(root / "run"), "--session", str(other), "-o", str(root / "g4")])
    assert f"--session {other}: this run tracked " in res.output
    assert "the model is drawn over another session's videos" in res.output


def test_report_of_a_batch_output_folder_names_its_runs(tmp_path):
    for name in ("walk01", "walk02"):
        write_trajectory(tmp_path / "OUT" / name / "trajectories.h5", Walker(duration=2.0).trajectory())
    res = CliRunner().invoke(cli, ["report", str(tmp_path / "OUT")])
    assert res.exit_code == 1
    assert (f"{tmp_path / 'OUT'}: holds the runs of 2 sessions (walk01, walk02): report each one, e.g. gaitcap "
            f"report {tmp_path / 'OUT' / 'walk01'}") in res.output


def test_a_run_that_lost_the_subject_still_gets_its_fit_report(tracked_copy):
    _, root = tracked_copy
    lost = root / "lost"
    shutil.copytree(root / "run", lost)
    with h5py.File(lost / "trajectories.h5", "r+") as f:
        f["points"][...] = np.nan
        f["quality"][...] = QUALITY_POOR_FIT
    res = CliRunner().invoke(cli, ["report", str(lost), "--session", str(root / "session")])
    assert res.exit_code == 1
    assert "verdict: doubtful" in res.output and "the tracking's fit is shown in" in res.output
    html = (lost / "gait" / "report.html").read_text()
    assert "No gait analysis." in html and "Verdict: doubtful" in html
    assert sum(mime == "image/jpeg" for mime, _ in _decoded_images(html)) >= 2
    assert not (lost / "gait" / "parameters.json").exists()
    assert "the tracking failed" not in html  # doubtful: the analysis's own reason alone
    doc = json.loads((lost / "track.json").read_text())
    (lost / "track.json").write_text(json.dumps({**doc, "verdict": "failed", "verdict_reasons": ["none fits"]}))
    CliRunner().invoke(cli, ["report", str(lost), "--session", str(root / "session")])
    assert "<b>No gait analysis.</b> The tracking failed (its verdict, above): " in (lost / "gait" / "report.html").read_text()


def test_every_flagged_run_gets_its_worst_frame_before_a_long_run_fills_the_sheet():
    rec = _record(T=300)
    rec.quality[20:220] = QUALITY_POOR_FIT
    rec.fit[20:220] = 0.1  # a long, very poor run
    rec.fit[120] = 0.05
    rec.quality[260:263] = QUALITY_POOR_FIT
    rec.fit[260:263] = [0.5, 0.4, 0.5]  # a short, milder one
    picked = attention_frames(FitRecord(Path("."), rec), spacing=10)
    assert {120, 261} <= set(picked) and len(picked) == MAX_ATTENTION_FRAMES


def test_a_run_without_its_track_json_is_reported_with_a_warning(tracked_session, tmp_path):
    """A re-run stopped before its end removes track.json and leaves the earlier run's files: report and eval
    say so instead of reading them as a finished run's."""
    synth, out, _ = tracked_session
    run = tmp_path / "run"
    shutil.copytree(out, run)
    (run / "track.json").unlink()
    res = CliRunner().invoke(cli, ["report", str(run), "-o", str(tmp_path / "gait")])
    assert f"{run}: no finished track.json beside trajectories.h5: a run there did not finish" in res.output
    res = CliRunner().invoke(cli, ["eval", str(run), "--truth", str(synth.session / "truth.h5")])
    assert res.exit_code == 0, res.output
    notes = json.loads((run / "eval.json").read_text())["notes"]
    assert any("no finished track.json" in n for n in notes)
    finished = CliRunner().invoke(cli, ["report", str(out), "-o", str(tmp_path / "gait2")])
    assert "no finished track.json" not in finished.output
    (run / "track.json").write_text("{broken")  # unreadable (edited by hand): named once by each command
    for args, code in ((["report", str(run), "-o", str(tmp_path / "gait3")], 3),  # 3: no complete gait cycle
                       (["eval", str(run), "--truth", str(synth.session / "truth.h5"), "--force"], 0)):  # fmt: skip
        track_summary._unreadable.clear()  # as in a new process
        res = CliRunner().invoke(cli, args)
        assert res.exit_code == code, res.output
        assert res.output.count("track.json: unreadable (") == 1, res.output
        assert "taken as no finished run" in res.output and "no finished track.json beside" in res.output


def test_uncertain_frames_use_the_runs_own_threshold(tracked_copy):
    """A run tracked with another ``verdict.uncertain_mm`` has its frames judged by it, as its verdict was."""
    _, root = tracked_copy
    shutil.copytree(root / "run", root / "run40")
    h5 = root / "run40" / "trajectories.h5"
    with h5py.File(h5, "r+") as f:
        config = yaml.safe_load(f.attrs["config"])
        config["verdict"]["uncertain_mm"] = 40.0
        f.attrs["config"] = yaml.safe_dump(config)
    default = load_fit_record(root / "run" / "trajectories.h5")
    fit = load_fit_record(h5)
    assert default.uncertain_mm == UNCERTAIN_MM and fit.uncertain_mm == 40.0
    mm = fit.lower_limb_uncertainty_mm()
    np.testing.assert_array_equal(fit.uncertain, np.nan_to_num(mm) > 40.0)
    res = CliRunner().invoke(cli, ["report", str(root / "run40"), "--session", str(root / "session"), "-o", str(root / "g40")])
    assert res.exit_code in (0, 3), res.output
    assert "mean lower-limb uncertainty above 40 mm" in (root / "g40" / "report.html").read_text()


def test_the_thumbnail_reaches_the_floor_beneath_a_model_drawn_too_small():
    """A run with a wrong --height drew a model too small, and the crop around it cut off the person's feet
    (at the thumbnail's edge or past it): the crop now reaches the floor under the pelvis, where they stand."""
    from gaitcap.camera import Camera
    from gaitcap.report.sheet import crop_box, floor_below

    R = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # looking along +y, z up
    cam = Camera("c", (640, 480), np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]), np.zeros(5),
                 cv2.Rodrigues(R)[0].ravel(), -R @ np.array([0.0, -5.0, 1.0]))  # fmt: skip
    names = ("pelvis", "knee_l", "ankle_l", "head")
    small = np.array([[0.0, 0.0, 0.9], [0.05, 0.0, 0.7], [0.05, 0.0, 0.5], [0.0, 0.0, 1.3]])  # floats 0.5 m up
    floor_px = cam.project(floor_below(small, names))[0]
    np.testing.assert_allclose(floor_below(small, names), [[0.0, 0.0, 0.0]])
    x0, y0, x1, y1 = crop_box(cam.project(small), (640, 480))
    assert floor_px[1] > y1  # around the model alone: the floor is cut off
    x0, y0, x1, y1 = crop_box(np.concatenate([cam.project(small), floor_px[None]]), (640, 480))
    assert y0 < floor_px[1] < y1 and x0 < floor_px[0] < x1
    assert np.isnan(floor_below(small[1:], names[1:])).all()  # no pelvis: nothing added
