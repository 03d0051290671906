from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from gaitcap.cli.main import cli
from gaitcap.data import embedded_walk
from gaitcap.errors import InputError
from gaitcap.evaluation import Thresholds, check_thresholds, evaluate
from gaitcap.evaluation.metrics import angle_bias_deg, angle_rmse_deg, match_events, runs, swap_mask
from gaitcap.io.trajectories_h5 import write_trajectory
from gaitcap.synth.session import SynthOptions, synthesize
from gaitcap.synth.truth import read_truth
from gaitcap.trajectory import GaitEvent, Trajectory

LEGS = ("hip", "knee", "ankle", "heel", "toe")


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    out = tmp_path_factory.mktemp("eval") / "walk"
    synthesize(embedded_walk(), out, SynthOptions(size=(320, 240)), progress=False)
    return out


@pytest.fixture(scope="module")
def truth(session) -> Trajectory:
    return read_truth(session / "truth.h5").trajectory


def tracked(truth: Trajectory, points: np.ndarray) -> Trajectory:
    """What a tracker writes: the points, no recorded events."""
    return replace(truth, points=points, events=(), meta={})


def swap_legs(points: np.ndarray, names: tuple[str, ...], frames: slice) -> np.ndarray:
    p = points.copy()
    for leg in LEGS:
        i, j = names.index(f"{leg}_l"), names.index(f"{leg}_r")
        p[frames, i], p[frames, j] = points[frames, j], points[frames, i]
    return p


def test_truth_has_recorded_events(truth):
    assert truth.n_frames > 40 and len(truth.events) >= 4


def test_constant_offset_gives_its_size_as_mpjpe(truth):
    ev = evaluate(tracked(truth, truth.points + [0.006, -0.008, 0.0]), truth)
    for group in ("all", "lower_limb", "heel_toe"):
        assert ev.positions[group]["mpjpe_mm"] == pytest.approx(10.0, abs=1e-6)
    assert ev.positions["lower_limb"]["n_points"] == 6 and ev.positions["heel_toe"]["n_points"] == 4
    assert all(v == pytest.approx(10.0, abs=1e-6) for v in ev.per_point_mm.values())
    assert ev.swaps["n_frames"] == 0
    # a rigid translation changes no joint angle and no event
    assert max(ev.angles_rmse_deg.values()) < 1e-6
    assert [m["error_ms"] for m in ev.events["matches"]] == pytest.approx(
        [m["error_ms"] for m in ev.events_baseline["matches"]]
    )
    assert ev.events["reference_events"] == "recorded in the reference"


def test_gaussian_noise_mpjpe_matches_the_chi_mean(truth):
    sigma = 0.004
    rng = np.random.default_rng(7)
    ev = evaluate(tracked(truth, truth.points + rng.normal(0, sigma, truth.points.shape)), truth)
    expected = 1000 * sigma * 2 * math.sqrt(2 / math.pi)  # mean of a 3-D isotropic Gaussian's norm
    assert ev.mpjpe_mm == pytest.approx(expected, rel=0.05)
    assert ev.positions["all"]["frame_max_mm"] > ev.positions["all"]["frame_median_mm"]
    assert ev.swaps["n_frames"] == 0


def test_left_right_swap_is_counted(truth):
    pts = swap_legs(truth.points, truth.names, slice(20, 30))
    ev = evaluate(tracked(truth, pts), truth)
    assert ev.swaps["n_frames"] == 10
    assert ev.swaps["runs"] == [[20, 30]]
    assert ev.positions["lower_limb"]["mpjpe_mm"] > 20
    assert ev.per_point_mm["pelvis"] == pytest.approx(0.0)


def test_nan_frames_are_flagged_and_excluded(truth):
    pts = truth.points + [0.0, 0.0, 0.01]
    pts[5:12] = np.nan
    ev = evaluate(tracked(truth, pts), truth)
    assert ev.n_flagged == 7
    assert ev.mpjpe_mm == pytest.approx(10.0, abs=1e-6)
    assert ev.to_dict()["frames"] == {"compared": truth.n_frames - 7, "total": truth.n_frames, "out_total": truth.n_frames,
                                      "outside_reference": 0, "flagged": 7, "reference_missing": 0,
                                      "reference_total": truth.n_frames, "reference_outside_out": 0}  # fmt: skip
    json.dumps(ev.to_dict(), allow_nan=False)  # strict JSON: NaN became null


def test_nothing_tracked(truth, session, tmp_path):
    """A run lost throughout (every frame NaN, verdict failed) was an error, exit 1 and no eval.json, where its
    check_thresholds says a value not available fails: a CI took a lost run for a broken job (found with a copy of a
    run whose points were all NaN). Now nothing is compared, a note says why, and each threshold fails (exit 3)."""
    ev = evaluate(tracked(truth, np.full_like(truth.points, np.nan)), truth)
    assert ev.n_compared == 0 and ev.n_flagged == truth.n_frames
    assert "OUT has no tracked frame at all (every frame is NaN): nothing compared" in ev.notes
    json.dumps(ev.to_dict(), allow_nan=False)
    out = write_out(tmp_path / "OUT", tracked(truth, np.full_like(truth.points, np.nan)))
    (out / "track.json").write_text(json.dumps({"status": "ok", "verdict": "failed", "verdict_reasons": ["lost"]}))
    res = CliRunner().invoke(cli, ["eval", str(out), "--truth", str(session), "--max-lower-limb-mpjpe-mm", "40",
                                   "--max-event-error-frames", "2", "--require-verdict", "ok"])  # fmt: skip
    assert res.exit_code == 3, res.output
    doc = json.loads((out / "eval.json").read_text())
    assert doc["passed"] is False and doc["thresholds_failed"] == [
        "lower-limb MPJPE not available (no frame compared)",
        "event timing not available (no detected event matched a reference event)",
        "the run's verdict is failed, not ok"]


def test_untracked_point_is_dropped_with_a_note(truth):
    pts = truth.points.copy()
    pts[:, truth.names.index("wrist_l")] = np.nan
    ev = evaluate(tracked(truth, pts), truth)
    assert ev.n_flagged == 0 and "wrist_l" not in ev.points
    assert "point never tracked in OUT, not compared: wrist_l" in ev.notes


def test_shorter_output_is_aligned_by_time(truth):
    start = 10
    out = Trajectory(truth.names, truth.points[start:] + [0.01, 0, 0], truth.rate_hz, t0_s=start / truth.rate_hz)
    ev = evaluate(out, truth)
    assert ev.n_frames == truth.n_frames - start
    assert ev.mpjpe_mm == pytest.approx(10.0, abs=1e-6)
    assert all(m["reference_s"] >= start / truth.rate_hz - 1e-9 for m in ev.events["matches"])


def test_no_common_frame_or_point(truth):
    late = Trajectory(truth.names, truth.points, truth.rate_hz, t0_s=100.0)
    with pytest.raises(InputError, match="no frame in common"):
        evaluate(late, truth)
    other = Trajectory(("a", "b"), truth.points[:, :2], truth.rate_hz)
    with pytest.raises(InputError, match="no point in common"):
        evaluate(other, truth)


def test_thresholds(truth):
    ev = evaluate(tracked(truth, truth.points + [0.01, 0, 0]), truth)
    assert check_thresholds(ev, Thresholds(max_mpjpe_mm=11, max_angle_rmse_deg=1, max_event_error_frames=5)) == []
    fails = check_thresholds(ev, Thresholds(max_mpjpe_mm=9.5, max_event_error_frames=0.01))
    assert fails[0].startswith("MPJPE (all points) 10.0 mm > 9.5 mm (worst point ")
    assert fails[1].startswith("event timing error") and "> 0.01 frames (worst: " in fails[1]
    assert ev.thresholds == {"max_mpjpe_mm": 9.5, "max_event_error_frames": 0.01}  # recorded in eval.json
    lower = check_thresholds(ev, Thresholds(max_lower_limb_mpjpe_mm=9.5))
    assert len(lower) == 1 and lower[0].startswith("lower-limb MPJPE 10.0 mm > 9.5 mm (worst point ")


def test_event_threshold_in_milliseconds_is_the_same_at_every_frame_rate(truth):
    """--max-event-error-frames counts frames of OUT's rate: a lab's 1-frame limit is 40 ms at 25 fps
    but 20 ms at 50 fps, so the same 30 ms error passes at 25 fps and fails at 50 fps. The limit in
    milliseconds (--max-event-error-ms) judges both alike (found tracking the same walk at 25 and 50 fps)."""
    ev = evaluate(tracked(truth, truth.points + [0.01, 0, 0]), truth)
    ev.events.update(matches=[])  # the worst event is named apart (test_a_failed_threshold_names_what_drifted)
    assert ev.events["n_matched"] and not ev.events["n_missed"]
    for rate in (25.0, 50.0):
        ev.events.update(max_abs_ms=30.0, max_abs_frames=0.030 * rate)
        assert check_thresholds(ev, Thresholds(max_event_error_ms=40)) == []
        assert ev.thresholds == {"max_event_error_ms": 40}  # recorded in eval.json
        assert check_thresholds(ev, Thresholds(max_event_error_ms=25)) == ["event timing error 30 ms > 25 ms"]
    assert check_thresholds(ev, Thresholds(max_event_error_frames=1)) == ["event timing error 1.50 frames > 1 frames"]
    both = check_thresholds(ev, Thresholds(max_event_error_frames=1, max_event_error_ms=25))
    assert both == ["event timing error 1.50 frames > 1 frames", "event timing error 30 ms > 25 ms"]
    ev.events.update(n_matched=0)
    assert check_thresholds(ev, Thresholds(max_event_error_ms=40)) == [
        "event timing not available (no detected event matched a reference event)"]


def test_a_tracking_runs_events_are_scored_as_its_report_finds_them(truth):
    """At 50 Hz and above a tracking run's events keep their anchors (GaitOptions.refine_tracked): eval
    scores OUT's events as the report detects them, not refined as a marker file's would be."""
    from gaitcap.evaluation.compare import align
    from gaitcap.gait.options import GaitOptions
    from gaitcap.trajectory import TRACKED_FORMAT

    fast = truth.resample(50.0)
    out = replace(tracked(fast, fast.points + [0.01, 0, 0]), meta={"format": TRACKED_FORMAT})
    assert align(out, fast).trajectory("est").meta == {"format": TRACKED_FORMAT}
    anchors = evaluate(out, fast, options=GaitOptions(refine=False)).events
    assert evaluate(out, fast).events == anchors
    as_markers = evaluate(replace(out, meta={}), fast).events  # read from elsewhere: refined
    assert as_markers["n_matched"] and as_markers != anchors


def test_cli_event_threshold_in_milliseconds(tmp_path, truth):
    a = write_out(tmp_path / "A", tracked(truth, truth.points))
    b = write_out(tmp_path / "B", tracked(truth, truth.points))
    res = CliRunner().invoke(cli, ["eval", str(b), "--reference", str(a), "--max-event-error-ms", "0"])
    assert res.exit_code == 0, res.output
    doc = json.loads((b / "eval.json").read_text())
    assert doc["thresholds"] == {"max_event_error_ms": 0.0} and doc["passed"]
    assert "--max-event-error-ms" in CliRunner().invoke(cli, ["eval", "--help"]).output


def test_thresholds_on_what_was_not_compared_and_the_runs_verdict(truth):
    """CI thresholds fail a run that passes its error limits on what little was compared: frames flagged or
    not covered by the reference (--min-compared-fraction), reference events not detected
    (--max-event-error-frames), a verdict worse than required or none (--require-verdict)."""
    pts = truth.points + [0.01, 0, 0]
    pts[truth.n_frames // 2:] = np.nan  # half the run flagged
    ev = evaluate(tracked(truth, pts), truth)
    assert ev.n_out_frames == truth.n_frames and ev.n_compared == truth.n_frames // 2
    half = f"{truth.n_frames // 2} of OUT's {truth.n_frames} frames compared (50%) < 90%"
    assert check_thresholds(ev, Thresholds(min_compared_fraction=0.9)) == [half + " (flagged, or without a reference frame)"]
    assert check_thresholds(ev, Thresholds(min_compared_fraction=0.5)) == []
    missed = check_thresholds(ev, Thresholds(max_event_error_frames=5))
    assert missed and "events not detected in OUT (" in missed[-1] and ev.events["n_missed"] > 0
    short = Trajectory(truth.names, truth.points[:20], truth.rate_hz)  # a reference covering 20 frames
    cut = evaluate(tracked(truth, truth.points), short)
    assert f"{truth.n_frames - 20} of OUT's {truth.n_frames} frames have no reference frame: not compared" in cut.notes
    assert check_thresholds(cut, Thresholds(min_compared_fraction=0.9))
    for verdict, required, fails in ((None, "ok", True), ("failed", "doubtful", True), ("doubtful", "ok", True),
                                     ("doubtful", "doubtful", False), ("ok", "ok", False)):  # fmt: skip
        ev.verdict = verdict
        assert bool(check_thresholds(ev, Thresholds(require_verdict=required))) is fails, (verdict, required)


def test_angle_error_is_measured(truth):
    # move both knees 3 cm forward along the walk: the knee flexion changes, the hips do not move
    fwd = truth.point("pelvis")[-1] - truth.point("pelvis")[0]
    fwd[2] = 0
    fwd /= np.linalg.norm(fwd)
    pts = truth.points.copy()
    for name in ("knee_l", "knee_r"):
        pts[:, truth.names.index(name)] += 0.03 * fwd
    ev = evaluate(tracked(truth, pts), truth)
    assert ev.angles_rmse_deg["knee_flexion_l"] > 3 and ev.angles_rmse_deg["knee_flexion_r"] > 3
    assert ev.angles_rmse_deg["pelvis_tilt_l"] < 1e-6
    name, worst = ev.max_checked_angle_rmse()
    assert worst == max(ev.angles_rmse_deg[f"{n}_{s}"] for n in ("hip_flexion", "knee_flexion", "ankle_dorsiflexion") for s in "lr")
    assert check_thresholds(ev, Thresholds(max_angle_rmse_deg=2))[0].startswith(f"{name} RMSE")


def test_metric_helpers():
    assert angle_rmse_deg(np.array([359.0, 10.0, np.nan]), np.array([1.0, 10.0, 5.0])) == (pytest.approx(math.sqrt(2)), 2)
    assert runs(np.array([0, 1, 1, 0, 1], bool)) == [(1, 3), (4, 5)]
    # the bias is the mean wrapped difference, and RMSE^2 = bias^2 + variance of the difference
    assert angle_bias_deg(np.array([359.0, 10.0, np.nan]), np.array([1.0, 10.0, 5.0])) == (pytest.approx(-1.0), 2)
    rng = np.random.default_rng(3)
    ref_angle = rng.uniform(-10, 70, 200)
    est_angle = ref_angle + 4.0 + rng.normal(0, 2, 200)
    bias, n = angle_bias_deg(est_angle, ref_angle)
    assert n == 200 and bias == pytest.approx(np.mean(est_angle - ref_angle))
    assert angle_rmse_deg(est_angle, ref_angle)[0] ** 2 == pytest.approx(bias**2 + np.var(est_angle - ref_angle))
    ref = [GaitEvent(1.0, "left", "foot_strike"), GaitEvent(2.0, "left", "foot_strike"), GaitEvent(1.5, "right", "foot_off")]
    det = [GaitEvent(1.04, "left", "foot_strike"), GaitEvent(1.5, "left", "foot_off"), GaitEvent(1.9, "left", "foot_strike")]
    matches, missed, extra = match_events(det, ref, 0.25)
    assert [(m.reference_s, round(m.error_s, 6)) for m in matches] == [(1.0, 0.04), (2.0, -0.1)]
    assert missed == [ref[2]] and extra == [det[1]]
    est = np.zeros((2, 2, 3))
    est[:, 0, 0], est[:, 1, 0] = 1.0, -1.0
    ref_pts = est.copy()
    ref_pts[1] = est[1, ::-1]
    assert swap_mask(est, ref_pts, ["hip_l", "hip_r"]).tolist() == [False, True]


# ------------------------------------------------------------------------------- the CLI
def write_out(folder, traj: Trajectory):
    folder.mkdir(parents=True, exist_ok=True)
    write_trajectory(folder / "trajectories.h5", traj)
    return folder


def test_cli_thresholds_flip_the_exit_code(tmp_path, session, truth):
    out = write_out(tmp_path / "OUT", tracked(truth, truth.points + [0.01, 0, 0]))
    runner = CliRunner()
    ok = runner.invoke(cli, ["eval", str(out), "--truth", str(session / "truth.h5"), "--max-mpjpe-mm", "15"])
    assert ok.exit_code == 0, ok.output
    assert "all points (20)" in ok.output and "10.0" in ok.output
    doc = json.loads((out / "eval.json").read_text())
    assert doc["positions_mm"]["all"]["mpjpe_mm"] == pytest.approx(10.0)
    assert doc["passed"] is True and doc["left_right_swaps"]["n_frames"] == 0
    bad = runner.invoke(cli, ["eval", str(out), "--truth", str(session), "--max-mpjpe-mm", "5", "--force"])
    assert bad.exit_code == 3  # a threshold: not an error (1) nor a usage error (2)
    assert "threshold exceeded: MPJPE (all points) 10.0 mm > 5 mm (worst point " in bad.output
    doc = json.loads((out / "eval.json").read_text())
    assert doc["thresholds_failed"][0].startswith("MPJPE (all points) 10.0 mm > 5 mm") and doc["passed"] is False
    assert doc["thresholds"] == {"max_mpjpe_mm": 5.0} and doc["gaitcap_version"]
    folder = runner.invoke(cli, ["eval", str(out), "--truth", str(session), "-o", str(tmp_path), "--force"])
    assert folder.exit_code == 1 and f"{tmp_path}: is a folder; -o names the JSON file" in folder.output
    # an evaluation that fails with --force leaves no earlier eval.json to be read as its result
    (out / "trajectories.h5").write_bytes(b"not hdf5")
    broken = runner.invoke(cli, ["eval", str(out), "--truth", str(session), "--force"])
    assert broken.exit_code == 1 and not (out / "eval.json").exists()


def test_cli_shows_the_runs_verdict(tmp_path, session, truth):
    out = write_out(tmp_path / "OUT", tracked(truth, truth.points))
    runner = CliRunner()
    res = runner.invoke(cli, ["eval", str(out), "--truth", str(session / "truth.h5")])
    assert res.exit_code == 0 and "verdict of the run: not judged" in res.output
    assert json.loads((out / "eval.json").read_text())["verdict"] is None
    reasons = ["the ankles cross in 12 of 40 frames: a suspected leg swap"]
    (out / "track.json").write_text(json.dumps({"status": "ok", "verdict": "doubtful", "verdict_reasons": reasons}))
    res = runner.invoke(cli, ["eval", str(out / "trajectories.h5"), "--truth", str(session / "truth.h5"), "--force"])
    assert res.exit_code == 0, res.output
    assert f"verdict of the run: doubtful: {reasons[0]}" in res.output
    doc = json.loads((out / "eval.json").read_text())
    assert doc["verdict"] == "doubtful" and doc["verdict_reasons"] == reasons


def test_cli_reference_mode_and_output_option(tmp_path, truth):
    a = write_out(tmp_path / "A", tracked(truth, truth.points))
    b = write_out(tmp_path / "B", tracked(truth, truth.points + [0, 0.02, 0]))
    res = CliRunner().invoke(cli, ["eval", str(b), "--reference", str(a), "-o", str(tmp_path / "cmp.json"),
                                   "--max-event-error-frames", "0.5"])  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "cmp.json").read_text())
    assert doc["positions_mm"]["all"]["mpjpe_mm"] == pytest.approx(20.0)
    assert doc["events"]["reference_events"] == "detected on the reference"
    assert doc["events"]["n_missed"] == 0 and doc["events"]["max_abs_frames"] == pytest.approx(0.0, abs=1e-6)
    assert doc["events_method_baseline"] is None


def test_cli_usage_and_input_errors(tmp_path, session, truth, monkeypatch):
    runner = CliRunner()
    out = write_out(tmp_path / "OUT", tracked(truth, truth.points))
    neither = runner.invoke(cli, ["eval", str(out)])
    assert neither.exit_code == 2 and "give exactly one of --truth and --reference" in neither.output
    both = runner.invoke(cli, ["eval", str(out), "--truth", str(session), "--reference", str(out)])
    assert both.exit_code == 2
    missing = runner.invoke(cli, ["eval", str(tmp_path / "nothing"), "--truth", str(session)])
    assert missing.exit_code == 1 and "nothing: file not found" in missing.output
    no_truth = runner.invoke(cli, ["eval", str(out), "--truth", str(tmp_path / "t.h5")])
    assert no_truth.exit_code == 1 and "t.h5: truth file not found" in no_truth.output
    first = runner.invoke(cli, ["eval", str(out), "--truth", str(session)])
    assert first.exit_code == 0 and "MPJPE" in first.output
    import gaitcap.evaluation.run

    calls = []
    monkeypatch.setattr(gaitcap.evaluation.run, "evaluate_output", lambda *a, **k: calls.append(a))
    again = runner.invoke(cli, ["eval", str(out), "--truth", str(session)])
    assert again.exit_code == 1 and "eval.json: exists already (use --force to overwrite)" in again.output
    assert calls == []  # refused before the evaluation, not after it


def test_cli_names_a_truth_from_another_session(tmp_path, session, truth):
    """The run's track.json names the session it tracked: a truth from elsewhere is pointed out, not refused
    (a session may have moved); the truth of its own session, as a file or as the folder, is not."""
    runner = CliRunner()
    out = write_out(tmp_path / "OUT", tracked(truth, truth.points))
    for tracked_session, named in ((tmp_path / "elsewhere", True), (session, False)):
        (out / "track.json").write_text(json.dumps({"status": "ok", "session": str(tracked_session)}))
        for given in (session, session / "truth.h5"):
            res = runner.invoke(cli, ["eval", str(out), "--truth", str(given), "--force"])
            assert res.exit_code == 0, res.output
            doc = json.loads((out / "eval.json").read_text())
            assert ("is it the right truth?" in res.output) is named
            assert any("elsewhere, track.json): is it the right truth?" in n for n in doc["notes"]) is named


def test_a_truth_outside_any_session_and_a_reference_of_another_session(tmp_path, session, truth):
    """A lab's own truth export kept outside the session folder is not doubted (nothing tells its session);
    a reference run that tracked another session than OUT is (by their track.json)."""
    from gaitcap.evaluation.report import other_run_session, other_session

    export = tmp_path / "lab_export" / "truth"
    export.mkdir(parents=True)
    assert other_session(export, str(session)) is None
    assert "is it the right truth?" in other_session(session, str(tmp_path / "elsewhere"))
    runner = CliRunner()
    out = write_out(tmp_path / "OUT", tracked(truth, truth.points))
    ref = write_out(tmp_path / "REF", tracked(truth, truth.points))
    (out / "track.json").write_text(json.dumps({"status": "ok", "session": str(session)}))
    (ref / "track.json").write_text(json.dumps({"status": "ok", "session": str(tmp_path / "walk02")}))
    res = runner.invoke(cli, ["eval", str(out), "--reference", str(ref)])
    assert res.exit_code == 0, res.output
    assert f"the reference run tracked another session ({tmp_path / 'walk02'}) than this run" in res.output
    assert other_run_session(ref / "trajectories.h5", str(tmp_path / "walk02")) is None


def _turned(points: np.ndarray, angle: float) -> np.ndarray:
    """points (F, P, 3) turned by ``angle`` radians about the vertical axis through the origin."""
    c, s = math.cos(angle), math.sin(angle)
    return points @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T


@pytest.mark.parametrize("heading", [0.0, 2.0, -2.8])
def test_systematic_part_of_an_offset_in_the_walking_frame(truth, heading):
    """A constant offset (forward, to the subject's left, up) comes back as each point's mean signed
    error in the walking frame, whichever way the subject walks: outward is +left for the left
    points and the midline, -left for the right ones; the whole error is systematic (share 1)."""
    ref = replace(truth, points=_turned(truth.points, heading))
    pelvis = ref.point("pelvis")[:, :2]
    forward = (pelvis[-1] - pelvis[0]) / np.linalg.norm(pelvis[-1] - pelvis[0])  # the embedded walk is straight
    left = np.array([-forward[1], forward[0]])
    offset = np.array([*(0.010 * forward + 0.006 * left), -0.004])
    ev = evaluate(tracked(ref, ref.points + offset), ref)
    assert set(ev.bias_mm) == set(truth.names)
    for name, b in ev.bias_mm.items():
        outward = -6.0 if name.endswith("_r") else 6.0
        assert (b["forward"], b["outward"], b["up"]) == pytest.approx((10.0, outward, -4.0), abs=0.3), name
        assert b["share"] == pytest.approx(1.0, abs=1e-9)
    assert ev.to_dict()["bias_mm"]["knee_l"]["up"] == pytest.approx(-4.0, abs=1e-9)
    for group in ("all", "lower_limb", "heel_toe"):  # nothing is left once each point's offset is removed
        assert ev.positions[group]["mpjpe_mm"] == pytest.approx(math.hypot(10.0, 6.0, 4.0), abs=1e-6)
        assert ev.positions[group]["offset_free_mpjpe_mm"] == pytest.approx(0.0, abs=1e-6)


def test_systematic_part_of_zero_mean_noise_is_small(truth):
    """Noise with no offset: every mean signed error within 4 standard errors of zero, and a small share."""
    sigma = 0.010
    noisy = truth.points + np.random.default_rng(11).normal(0, sigma, truth.points.shape)
    ev = evaluate(tracked(truth, noisy), truth)
    bound = 4 * 1000 * sigma / math.sqrt(truth.n_frames)
    for b in ev.bias_mm.values():
        assert max(abs(b["forward"]), abs(b["outward"]), abs(b["up"])) < bound
        assert b["share"] < 0.3
    lower = ev.positions["lower_limb"]  # noise has no offset to remove: about the whole error is left
    assert lower["offset_free_mpjpe_mm"] == pytest.approx(lower["mpjpe_mm"], rel=0.05)


def test_walking_frame_on_the_spot_and_unknown():
    """Walking on the spot the direction has the left hip on its left, whichever way the pelvis sways;
    without hips or pelvis: None."""
    from gaitcap.evaluation.compare import walking_frame

    names = ("pelvis", "hip_l", "hip_r")
    frames = 20
    pts = np.zeros((frames, 3, 3))
    pts[:, 1] = [0.0, -0.1, 0.9]  # facing -x: the left hip is at -y
    pts[:, 2] = [0.0, 0.1, 0.9]
    for sway in (0.01, -0.01):  # a centimetre, ending ahead or behind: no travel to speak of
        pts[:, 0, 0] = sway * np.linspace(0, 1, frames)
        assert walking_frame(pts, names) == pytest.approx([-1.0, 0.0], abs=1e-9)
    assert walking_frame(np.full((frames, 1, 3), np.nan), ("knee_l",)) is None


def test_the_gait_analyses_messages_say_which_trajectory(truth, caplog):
    """eval analyses OUT and the reference alike: each of the gait analysis's messages names which it is about,
    and the labels are gone afterwards."""
    import logging

    caplog.set_level(logging.INFO, logger="gaitcap")
    evaluate(tracked(truth, truth.points), truth)
    gait = [r.getMessage() for r in caplog.records if r.name.startswith("gaitcap.gait")]
    assert any(m.startswith("OUT: detected") for m in gait) and any(m.startswith("the reference: detected") for m in gait)
    assert all(m.startswith(("OUT: ", "the reference: ")) for m in gait)
    assert not any(logging.getLogger(name).filters for name in logging.Logger.manager.loggerDict
                   if name.startswith("gaitcap.gait"))  # fmt: skip


def test_points_in_millimetres_are_named_as_the_likely_cause(truth, caplog):
    """A run (or a lab's export) in millimetres gave a lower-limb MPJPE of hundreds of metres and implausible
    gait values, with no word on units: the evaluation notes it, and the gait analysis says it."""
    import logging

    from gaitcap.gait.analysis import analyse

    ev = evaluate(tracked(truth, truth.points * 1000.0), truth)
    assert any("1000 times as far apart as the reference's" in n and "millimetres" in n for n in ev.notes), ev.notes
    ev = evaluate(tracked(truth, truth.points), replace(truth, points=truth.points * 1000.0))
    assert any("1000 times closer together than the reference's" in n for n in ev.notes), ev.notes
    assert not any("millimetres" in n for n in evaluate(tracked(truth, truth.points + 0.01), truth).notes)
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        params = analyse(replace(truth, points=truth.points * 1000.0)).parameters
    assert "the points are likely in millimetres, and gaitcap reads metres" in params.reason
    assert "millimetres" in caplog.text and "millimetres" not in analyse(truth).parameters.reason


@pytest.mark.parametrize("record", [None, {"status": "ok", "verdict": "failed",
                                           "verdict_reasons": ["fewer than 10 % of the frames fit"]}])
def test_a_reference_run_that_failed_or_did_not_finish_is_named(tmp_path, truth, record):
    """A CI's saved reference that is itself a failed run (verdict failed) or not a finished run (no track.json)
    was compared with silently (exit 0, no note): now a note says so and eval.json holds its verdict."""
    out = write_out(tmp_path / "OUT", tracked(truth, truth.points))
    (out / "track.json").write_text(json.dumps({"status": "ok", "verdict": "ok"}))
    ref = write_out(tmp_path / "REF", tracked(truth, truth.points))
    if record is not None:
        (ref / "track.json").write_text(json.dumps(record))
    res = CliRunner().invoke(cli, ["eval", str(out), "--reference", str(ref), "--require-verdict", "ok"])
    assert res.exit_code == 0, res.output  # OUT's own verdict is what --require-verdict checks
    doc = json.loads((out / "eval.json").read_text())
    if record is None:
        assert doc["reference_verdict"] is None
        assert any(n.startswith(f"the reference {ref}: no finished track.json") for n in doc["notes"]), doc["notes"]
    else:
        assert doc["reference_verdict"] == "failed"
        assert any("the reference run's own verdict is failed: fewer than 10 % of the frames fit" in n
                   for n in doc["notes"]), doc["notes"]
    assert "the reference" in res.output
    (ref / "track.json").write_text(json.dumps({"status": "ok", "verdict": "ok"}))
    res = CliRunner().invoke(cli, ["eval", str(out), "--reference", str(ref), "--force"])
    doc = json.loads((out / "eval.json").read_text())
    assert doc["reference_verdict"] == "ok" and not any(n.startswith("the reference") for n in doc["notes"])


def test_a_run_shorter_than_its_reference_run_fails_the_compared_fraction(tmp_path, truth):
    """A run that lost its last frames, compared with a saved reference run, passed --min-compared-fraction 1 (exit 0,
    no note: the fraction counted only OUT's frames). Now the reference run's frames OUT lacks are named in a note and
    count as not compared; against a truth (a run of --max-frames) only OUT's frames count, as before."""
    n = truth.n_frames
    ref = write_out(tmp_path / "REF", tracked(truth, truth.points))
    short = write_out(tmp_path / "SHORT", tracked(truth, truth.points[: n - 10]))
    runner = CliRunner()
    res = runner.invoke(cli, ["eval", str(short), "--reference", str(ref), "--min-compared-fraction", "1"])
    assert res.exit_code == 3, res.output
    doc = json.loads((short / "eval.json").read_text())
    assert f"10 of the reference's {n} frames have no frame in OUT: not compared" in doc["notes"]
    assert doc["thresholds_failed"] == [f"{n - 10} of {n} frames compared ({(n - 10) / n:.0%}) < 100% (OUT's {n - 10} "
                                        "and the reference run's 10 that OUT lacks; flagged, or without a reference frame)"]
    assert doc["frames"]["reference_total"] == n and doc["frames"]["reference_outside_out"] == 10
    same = runner.invoke(cli, ["eval", str(ref), "--reference", str(ref), "--min-compared-fraction", "1"])
    assert same.exit_code == 0, same.output
    ev = evaluate(tracked(truth, truth.points[: n - 10]), truth)
    assert ev.n_reference_outside == 10 and not ev.reference_is_run
    assert check_thresholds(ev, Thresholds(min_compared_fraction=1.0)) == []  # a truth longer than the run: not failed


def test_a_run_tracked_from_another_working_folder_is_not_doubted(tmp_path, session, truth, monkeypatch):
    """track.json records the session as the command line gave it (``gaitcap track walk -o OUT`` gives "walk"), so
    eval run from another folder resolved it there and asked 'is it the right truth?' of the session's own truth
    (found running a CI's eval from inside the run's folder). The run's trajectories.h5 records the absolute path,
    which eval now takes; a truth of another session is still named."""
    import h5py

    out = write_out(tmp_path / "OUT", tracked(truth, truth.points))
    with h5py.File(out / "trajectories.h5", "a") as f:
        f.attrs["session"] = str(session.resolve())
    (out / "track.json").write_text(json.dumps({"status": "ok", "session": session.name}))
    monkeypatch.chdir(out)
    runner = CliRunner()
    res = runner.invoke(cli, ["eval", ".", "--truth", str(session / "truth.h5")])
    assert res.exit_code == 0, res.output
    assert "is it the right truth?" not in res.output
    other = tmp_path / "walk02"
    other.mkdir()
    (other / "calibration.toml").write_text("")
    (other / "truth.h5").write_bytes((session / "truth.h5").read_bytes())
    res = runner.invoke(cli, ["eval", ".", "--truth", str(other), "--force"])
    assert res.exit_code == 0, res.output
    assert f"is not from the session this run tracked ({session.resolve()}" in res.output


def test_a_failed_threshold_names_what_drifted(truth):
    """A CI log showed 'lower-limb MPJPE 27.4 mm > 5 mm' or 'event timing error 1.16 frames > 0.1 frames' with no
    word on which joint or which event: each failure now names its worst point, its worst event (side, kind,
    the reference's time, the signed error) and the reference events not detected."""
    names = truth.names
    pts = truth.points + [0.01, 0, 0]
    pts[:, names.index("ankle_r")] += [0.03, 0, 0]  # 40 mm there
    pts[:, names.index("wrist_l")] += [0.09, 0, 0]  # 100 mm there: the worst of all points, not of the lower limb
    ev = evaluate(tracked(truth, pts), truth)
    fails = check_thresholds(ev, Thresholds(max_mpjpe_mm=5, max_lower_limb_mpjpe_mm=5))
    assert fails[0].endswith("> 5 mm (worst point wrist_l 100.0 mm)"), fails
    assert fails[1].endswith("> 5 mm (worst point ankle_r 40.0 mm)"), fails
    late = replace(truth, events=tuple(replace(e, time_s=e.time_s - 0.2) if i == 1 else e
                                       for i, e in enumerate(truth.events)))  # one reference event 5 frames earlier
    ev = evaluate(tracked(truth, truth.points), late)
    fails = check_thresholds(ev, Thresholds(max_event_error_frames=1))
    e = replace(truth.events[1], time_s=truth.events[1].time_s - 0.2)
    assert fails == [f"event timing error {ev.events['max_abs_frames']:.2f} frames > 1 frames (worst: {e.side} "
                     f"{e.event} at {e.time_s:.3f} s, +{ev.events['max_abs_frames']:.2f} frames)"], fails



def test_the_readmes_ci_recipe(tmp_path, session, truth, monkeypatch):
    """The README's CI recipe, its eval lines run as written: a run like its reference passes both checks (exit 0),
    a drifted one fails the reference's with exit 3 and one line naming the drift, a missing reference is an error
    (exit 1). Its synth and track lines are stood in for by this module's session and runs written from its truth
    (tracking is for tests/test_regression.py)."""
    import re
    import shlex
    import shutil
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    block = re.search(r"## A regression check in CI\n.*?```bash\n(.*?)```", readme, re.S).group(1)
    lines = [shlex.split(line) for line in block.splitlines() if line.startswith("gaitcap ")]
    assert [a[2] for a in lines] == ["synth", "track", "track", "eval", "eval"]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ci").mkdir()
    (tmp_path / "ci" / "walk").symlink_to(session)
    run_points = truth.points + [0.01, 0, 0]
    printed: list[str] = []

    def run(args: list[str], points: np.ndarray) -> int:
        if args[2] == "synth":
            return 0  # the module's session is ci/walk
        if args[2] == "track":
            out = write_out(tmp_path / args[args.index("-o") + 1], tracked(truth, points))
            (out / "track.json").write_text(json.dumps({"status": "ok", "verdict": "ok", "session": str(session)}))
            return 0
        res = CliRunner().invoke(cli, args[1:])
        printed.append(res.output)
        return res.exit_code

    assert [run(a, run_points) for a in lines] == [0, 0, 0, 0, 0], printed
    assert json.loads((tmp_path / "run" / "eval_reference.json").read_text())["passed"] is True
    drifted = run_points.copy()
    drifted[:, truth.names.index("knee_l")] += [0.0, 0.0, 0.02]
    assert [run(a, drifted) for a in lines[2:]] == [0, 0, 3]  # within the truth's 40 mm, not the reference's 0
    assert "threshold exceeded: MPJPE (all points) 1.0 mm > 0 mm (worst point knee_l 20.0 mm)" in printed[-1]
    doc = json.loads((tmp_path / "run" / "eval_reference.json").read_text())
    assert doc["passed"] is False and doc["thresholds"]["max_mpjpe_mm"] == 0.0
    assert doc["thresholds_failed"] == ["MPJPE (all points) 1.0 mm > 0 mm (worst point knee_l 20.0 mm)"]
    shutil.rmtree(tmp_path / "ci" / "reference")
    assert run(lines[4], run_points) == 1 and "file not found" in printed[-1]


def test_eval_help_names_the_eval_json_keys_a_ci_reads(tmp_path, truth):
    """eval --help named 'passed' but not the keys of the thresholds checked and failed ('thresholds',
    'thresholds_failed'): each key the help names is in eval.json."""
    import re

    help_text = CliRunner().invoke(cli, ["eval", "--help"]).output
    paragraph = help_text.split("eval.json also records", 1)[1].split("Exit codes", 1)[0]
    keys = set(re.findall(r'\("(\w+)"', paragraph))
    assert keys == {"thresholds", "thresholds_failed", "passed"}, keys
    out = write_out(tmp_path / "OUT", tracked(truth, truth.points))
    assert CliRunner().invoke(cli, ["eval", str(out), "--reference", str(out), "--max-mpjpe-mm", "1"]).exit_code == 0
    doc = json.loads((out / "eval.json").read_text())
    assert keys <= set(doc) and doc["thresholds"] == {"max_mpjpe_mm": 1.0} and doc["thresholds_failed"] == []


def test_a_passing_check_says_so_in_one_line(tmp_path, session, truth):
    """A passing eval printed its table and 'wrote eval.json', nothing in the CI log saying which thresholds were
    checked and met: one line now does (and none without thresholds)."""
    out = write_out(tmp_path / "OUT", tracked(truth, truth.points + [0.01, 0, 0]))
    res = CliRunner().invoke(cli, ["eval", str(out), "--truth", str(session), "--max-mpjpe-mm", "15",
                                   "--min-compared-fraction", "0.5"])  # fmt: skip
    assert res.exit_code == 0, res.output
    assert res.output.rstrip().splitlines()[-1] == "thresholds met: --max-mpjpe-mm 15, --min-compared-fraction 0.5"
    res = CliRunner().invoke(cli, ["eval", str(out), "--truth", str(session), "--force"])
    assert res.exit_code == 0 and "thresholds met" not in res.output


def test_a_batch_output_folder_is_named_as_one(tmp_path, session, truth):
    """eval of a 'gaitcap track FOLDER -o OUTS' output said only 'OUTS/trajectories.h5: file not found': it now says
    the folder is a batch's output and names its runs to evaluate one by one (as OUT and as --reference)."""
    outs = tmp_path / "OUTS"
    for name in ("walk01", "walk02"):
        write_out(outs / name, tracked(truth, truth.points))
    (outs / "batch.json").write_text("[]")
    runner = CliRunner()
    for args in (["eval", str(outs), "--truth", str(session)],
                 ["eval", str(outs / "walk01"), "--reference", str(outs)]):  # fmt: skip
        res = runner.invoke(cli, args)
        assert res.exit_code == 1, res.output
        assert (f"{outs}: a batch's output (batch.json), one run per session: evaluate each run's folder "
                f"({outs / '<session>'}: walk01, walk02)") in res.output
    assert runner.invoke(cli, ["eval", str(outs / "walk01"), "--truth", str(session)]).exit_code == 0
