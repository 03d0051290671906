"""The frame sync's check (gaitcap.sync_check): cameras whose videos start a few frames apart are found
from the rise and fall of the silhouettes' tops, named with the offset and how to trim them;
synchronised or rhythmless series say nothing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gaitcap.sync_check import PairOffset, SyncFinding, head_top, out_of_step, pair_offset, pair_offsets, start_delays, sync_note

FPS = 25.0


def walk_tops(n: int, start: int = 0, rng: np.random.Generator | None = None, noise: float = 0.15) -> np.ndarray:
    """A head-top series of a walk (rows, up positive: the head rises and falls once a step, a step every
    13.5 frames, and climbs in the image as the subject nears the camera) seen from frame ``start`` of
    the walk on."""
    t = np.arange(start, start + n, dtype=float)
    x = 1.2 * np.cos(2 * np.pi * t / 13.5) + 0.3 * t - 0.002 * t**2
    return x + (0.0 if rng is None else rng.normal(0.0, noise, n))


def test_head_top_is_the_first_row_to_a_fraction():
    sil = np.zeros((100, 80), np.float32)
    sil[20:90, 30:40] = 1.0
    sil[19, 30:35] = 1.0  # half a row above the head
    sil[5, 0] = 1.0  # a stray pixel is not the top
    assert head_top(sil) == pytest.approx(-19.5)
    assert np.isnan(head_top(np.zeros((10, 10), np.float32)))


@pytest.mark.parametrize("delay", [1, 2, 4, -1, -2, -4])
def test_a_camera_started_later_is_found_with_its_offset(rng, delay):
    n = 60
    a = walk_tops(n, max(0, -delay), rng)  # -delay: the first camera started later
    b = walk_tops(n, max(0, delay), rng)
    pair = pair_offset(a, b, FPS, "cam1", "cam2")
    assert pair.judged and pair.correlation > 0.8
    assert pair.lag == pytest.approx(delay, abs=0.35)
    assert out_of_step([pair], FPS) == [pair]
    note = sync_note([pair], ["cam1", "cam2"], FPS)
    assert note is not None and "out of step" in note
    later, earlier = ("cam2", "cam1") if delay > 0 else ("cam1", "cam2")
    assert "cam2's video starts" in note
    assert ("after cam1's" if delay > 0 else "before cam1's") in note
    frames = f"{abs(delay)} frame{'s' if abs(delay) > 1 else ''}"
    assert f"trim the first {frames} of {earlier}" in note
    assert f"ffmpeg -i videos/{earlier}.mp4" in note and f"trim=start_frame={abs(delay)}" in note
    assert f"set skip_frames: {{{earlier}: {abs(delay)}}} in session.yaml" in note
    assert f"of {later}" not in note and f"{later}:" not in note


def test_synchronised_videos_say_nothing(rng):
    a, b = walk_tops(60, 0, rng), walk_tops(60, 0, rng)
    pair = pair_offset(a, b, FPS)
    assert pair.judged and abs(pair.lag) < 0.3
    assert sync_note([pair], ["a", "b"], FPS) is None


def test_a_pair_without_the_rhythm_is_not_judged(rng):
    """A camera in line with the walkway: its series is noise, the pair says nothing either way."""
    a = walk_tops(60, 0, rng)
    b = rng.normal(0.0, 1.0, 60)
    pair = pair_offset(a, b, FPS)
    assert not pair.judged
    assert sync_note([pair], ["a", "b"], FPS) is None


def test_a_clip_too_short_is_not_judged(rng):
    pair = pair_offset(walk_tops(20, 2, rng), walk_tops(20, 0, rng), FPS)
    assert not pair.judged


def test_three_cameras_one_late_is_trimmed_in_the_others(rng):
    n = 60
    spread = np.stack([walk_tops(n, 2, rng), walk_tops(n, 0, rng), walk_tops(n, 2, rng)], axis=1)
    pairs = pair_offsets(spread, ["c1", "c2", "c3"], FPS)
    assert start_delays(pairs, ["c1", "c2", "c3"]) == {"c1": 2, "c2": 0, "c3": 2}
    note = sync_note(pairs, ["c1", "c2", "c3"], FPS)
    assert note is not None and "trim the first 2 frames of c2" in note and "of c1" not in note


def test_the_skip_frames_advised_add_to_the_sessions_own():
    """The offsets are measured on the videos as the session reads them (after its skip_frames): the
    setting advised is the session's plus the frames to trim, less what every camera would skip alike."""
    from gaitcap.sync_check import corrected_skips

    cams = ["cam1", "cam2", "cam3"]
    assert corrected_skips({"cam1": 2}, {}, cams) == {"cam1": 2}
    assert corrected_skips({"cam1": 1}, {"cam1": 1}, cams) == {"cam1": 2}  # one frame was not enough
    assert corrected_skips({"cam1": 1}, {"cam2": 1}, cams[:2]) == {}  # the wrong camera was skipped: undo it
    assert corrected_skips({"cam1": 1, "cam3": 1}, {"cam2": 3}, cams) == {"cam2": 2}  # cam2's skip went too far


def test_start_delays_leave_out_cameras_no_judged_pair_reaches():
    pairs = [PairOffset("a", "b", 2.1, 0.9, True), PairOffset("a", "c", 0.0, 0.1, False)]
    assert start_delays(pairs, ["a", "b", "c"]) == {"a": 0, "b": 2}


@pytest.fixture(scope="module")
def late_session(embedded_session, tmp_path_factory):
    """A copy of the embedded session whose second camera's video starts 2 frames late (its first 2
    frames dropped), and the frames of the first camera's video."""
    import shutil

    from gaitcap.io.video_write import AtomicVideoWriter
    from gaitcap.video import VideoReader

    src = embedded_session.session
    ses = tmp_path_factory.mktemp("late") / "late"
    shutil.copytree(src, ses, ignore=shutil.ignore_patterns("videos"))
    (ses / "videos").mkdir()
    n = {}
    for video in sorted((src / "videos").iterdir()):
        drop = 2 if video.stem == "cam2" else 0
        with VideoReader(video) as reader:
            frames = [f for _, f in reader]
            fps, size = reader.info.fps, reader.info.size
        with AtomicVideoWriter(ses / "videos" / video.name, fps, size) as writer:
            for frame in frames[drop:]:
                writer.write(frame)
        n[video.stem] = len(frames)
    return ses, n["cam1"]


def _copy(ses, folder, skip_frames=None):
    """``ses`` copied into ``folder``, with session.yaml's ``skip_frames`` when given."""
    import shutil

    import yaml

    out = folder / ses.name
    shutil.copytree(ses, out)
    if skip_frames is not None:
        info = yaml.safe_load((out / "session.yaml").read_text()) if (out / "session.yaml").exists() else {}
        (out / "session.yaml").write_text(yaml.safe_dump({**(info or {}), "skip_frames": skip_frames}))
    return out


def test_a_camera_started_two_frames_late_is_noted_with_the_skip_frames_that_bring_it_into_step(late_session, tmp_path):
    """With frame_sync.retrack off, a session whose second camera's video starts 2 frames late is tracked
    with a warning, a note in track.json naming the cameras, the offset, the skip_frames to set and the
    trim, and a doubtful verdict (before: nothing said it); with the skip_frames the note advises, in
    session.yaml, the same videos are tracked in step: no note, no such reason (before: no way short of
    re-encoding)."""
    import json
    import re

    import yaml
    from quick_config import quick_tracking

    from gaitcap.pipeline import run_track

    ses, n_frames = late_session
    config = quick_tracking(tmp_path, backward={"enabled": False}, frame_sync={"retrack": False})
    summary = run_track(ses, tmp_path / "out", config=config, progress=False, seed=0)
    notes = json.loads((tmp_path / "out" / "track.json").read_text())["verdict_notes"]
    assert notes == summary.verdict_notes
    sync = [n for n in notes if "out of step" in n]
    assert len(sync) == 1, notes
    assert "cam2's video starts 2." in sync[0] and "after cam1's" in sync[0]
    assert "trim the first 2 frames of cam1" in sync[0] and "ffmpeg -i videos/cam1.mp4" in sync[0]
    assert summary.verdict == "doubtful"  # a run whose views are a frame or more apart is not to be trusted as is
    assert any(r.startswith("the cameras' videos look out of step (cam2's video starts 2.") for r in summary.verdict_reasons)

    advised = re.search(r"set skip_frames: (\{[^}]*\}) in session\.yaml", sync[0])
    assert advised is not None and yaml.safe_load(advised.group(1)) == {"cam1": 2}
    synced = run_track(_copy(ses, tmp_path, yaml.safe_load(advised.group(1))), tmp_path / "synced", config=config,
                       progress=False, seed=0)  # fmt: skip
    assert not [n for n in synced.verdict_notes if "out of step" in n], synced.verdict_notes
    assert not [r for r in synced.verdict_reasons if "out of step" in r]
    assert synced.n_frames == summary.n_frames == n_frames - 2  # cam1's frames 2.. with cam2's 0..


def test_a_session_out_of_step_is_tracked_again_in_step(late_session, tmp_path):
    """frame_sync.retrack (the default): the same session is tracked again with the skip_frames found,
    once, and that run is written, its note saying so and nothing out of step; its masks (--save-masks)
    are the second run's; the session folder is not changed. The same as the run of a session.yaml with
    those skip_frames, but for the note."""
    import json

    import h5py
    from quick_config import quick_tracking

    from gaitcap.pipeline import run_track

    ses, n_frames = late_session
    config = quick_tracking(tmp_path, backward={"enabled": False})
    before = (ses / "session.yaml").read_bytes() if (ses / "session.yaml").exists() else None
    summary = run_track(ses, tmp_path / "out", config=config, progress=False, seed=0, save_masks=True)
    assert ((ses / "session.yaml").read_bytes() if (ses / "session.yaml").exists() else None) == before
    assert summary.verdict != "doubtful" or not [r for r in summary.verdict_reasons if "out of step" in r]
    first = summary.verdict_notes[0]
    assert first.startswith("tracked twice: the cameras' videos looked out of step (cam2's video starts 2.")
    assert "skip_frames: {cam1: 2}" in first
    assert not [n for n in summary.verdict_notes if n.startswith("the cameras' videos look out of step")]
    assert json.loads((tmp_path / "out" / "track.json").read_text())["verdict_notes"] == summary.verdict_notes
    assert summary.n_frames == n_frames - 2
    assert sorted(p.name for p in (tmp_path / "out").iterdir() if p.name.startswith(".")) == []  # no temporary left
    with h5py.File(tmp_path / "out" / "silhouettes.h5") as f:
        assert {len(f["masks"][c]) for c in f["masks"]} == {n_frames - 2}

    from gaitcap.report.fit import load_fit_record
    from gaitcap.report.sheet import open_session

    # the report draws the model over the frames the run tracked (cam1's from its frame 2), though the
    # session folder's session.yaml has no skip_frames (before: cam1's frame k under the run's frame k)
    tracked_session, why = open_session(load_fit_record(tmp_path / "out" / "trajectories.h5"))
    assert tracked_session is not None, why
    assert tracked_session.offsets == {"cam1": 2, "cam2": 0}

    # gaitcap eval says the run's frames start two frames into cam1's video (the truth is timed by its frames)
    from gaitcap.evaluation.report import read_truth_reference
    from gaitcap.evaluation.run import evaluate_output

    ev = evaluate_output(tmp_path / "out", read_truth_reference(ses / "truth.h5"), ses / "truth.h5")
    assert [n for n in ev.notes if n.startswith("OUT skipped the first frames of some cameras' videos (skip_frames: "
                                                 "{cam1: 2})")]  # fmt: skip

    given = run_track(_copy(ses, tmp_path, {"cam1": 2}), tmp_path / "given", config=config, progress=False, seed=0)
    with h5py.File(tmp_path / "out" / "trajectories.h5") as a, h5py.File(tmp_path / "given" / "trajectories.h5") as b:
        assert a["points"].shape == b["points"].shape
        assert float(abs(a["points"][()] - b["points"][()]).max()) < 1e-9
    assert given.verdict_notes == summary.verdict_notes[1:]


def test_the_first_run_is_kept_when_tracking_in_step_fails(late_session, tmp_path, monkeypatch):
    """Tracking again with the skip_frames found fails (here its videos are refused): the first run is
    written, its verdict doubtful, its notes kept and one more saying what failed, its own masks saved."""
    import h5py
    from quick_config import quick_tracking

    import gaitcap.pipeline as pipeline_module
    from gaitcap.errors import InputError
    from gaitcap.pipeline import run_track

    real = pipeline_module.check_session_videos

    def refusing_skips(session, *args, **kwargs):
        if any(session.offsets.values()):
            raise InputError("refused for the test")
        return real(session, *args, **kwargs)

    monkeypatch.setattr(pipeline_module, "check_session_videos", refusing_skips)
    ses, n_frames = late_session
    config = quick_tracking(tmp_path, backward={"enabled": False})
    kept = run_track(ses, tmp_path / "out", config=config, progress=False, seed=0, save_masks=True)
    assert kept.verdict == "doubtful"
    assert any(n.startswith("the cameras' videos look out of step (cam2's video starts 2.") for n in kept.verdict_notes)
    assert kept.verdict_notes[-1] == "tracking again with skip_frames: {cam1: 2} failed (refused for the test): this is the first run"
    assert kept.n_frames == n_frames - 2  # the first run: cam1's frames 0.. with cam2's (which began 2 later)
    with h5py.File(tmp_path / "out" / "silhouettes.h5") as f:
        assert {len(f["masks"][c]) for c in f["masks"]} == {n_frames - 2}
    assert sorted(p.name for p in (tmp_path / "out").iterdir() if p.name.startswith(".")) == []


def _misread_once(monkeypatch, skips, lag):
    """The frame sync check of the session's first run reads ``skips`` and ``lag`` (a misread, as the
    check may make); the runs after it are checked for real."""
    import gaitcap.pipeline as pipeline_module

    real, calls = pipeline_module._sync_note, []

    def first_misread(tops, videos, skipped):
        calls.append(dict(skipped))
        if len(calls) == 1:
            return SyncFinding("cam2's video starts 1.0 frames after cam1's (misread)", "the cameras' videos look out of step",
                               skips, lag)  # fmt: skip
        return real(tops, videos, skipped)

    monkeypatch.setattr(pipeline_module, "_sync_note", first_misread)
    return calls


def test_a_skip_that_leaves_the_videos_as_far_out_of_step_keeps_the_first_run(embedded_session, tmp_path, monkeypatch):
    """Cameras in step whose check misread an offset: tracked again with the skip it advised, the videos
    are out of step by as much or more (the skip made them so), so the first run is written, with a note
    saying why (before: the worse run, two frames out of step, was kept)."""
    import h5py
    from quick_config import quick_tracking

    from gaitcap.pipeline import run_track

    calls = _misread_once(monkeypatch, {"cam1": 2}, 1.0)
    config = quick_tracking(tmp_path, backward={"enabled": False})
    kept = run_track(embedded_session.session, tmp_path / "out", config=config, progress=False, seed=0, save_masks=True)
    assert calls == [{"cam1": 0, "cam2": 0}, {"cam1": 2, "cam2": 0}]  # the second run checked, after its skip
    assert kept.verdict_notes[-1].startswith("tracking again with skip_frames: {cam1: 2} left the videos as far out "
                                             "of step (cam2's video starts 2.")  # fmt: skip
    assert "before cam1's" in kept.verdict_notes[-1]  # the skip took cam1 two frames past cam2
    assert kept.n_frames == 56  # the first run, no frame skipped
    with h5py.File(tmp_path / "out" / "trajectories.h5") as f:
        assert f.attrs["skip_frames"] == "{cam1: 0, cam2: 0}"
    with h5py.File(tmp_path / "out" / "silhouettes.h5") as f:
        assert {len(f["masks"][c]) for c in f["masks"]} == {56}
    assert sorted(p.name for p in (tmp_path / "out").iterdir() if p.name.startswith(".")) == []


def test_a_skip_that_leaves_the_videos_less_out_of_step_is_kept(late_session, tmp_path, monkeypatch):
    """An offset read short (one frame of two): the run tracked with that skip is still out of step, by
    less, and is kept, its notes saying it was tracked twice and how far its videos still are apart."""
    from quick_config import quick_tracking

    from gaitcap.pipeline import run_track

    ses, n_frames = late_session
    _misread_once(monkeypatch, {"cam1": 1}, 2.0)
    config = quick_tracking(tmp_path, backward={"enabled": False})
    kept = run_track(ses, tmp_path / "out", config=config, progress=False, seed=0)
    twice = [n for n in kept.verdict_notes if n.startswith("tracked twice: the cameras' videos looked out of step")]
    assert len(twice) == 1 and "skip_frames: {cam1: 1}" in twice[0]
    rest = [n for n in kept.verdict_notes if n.startswith("the cameras' videos look out of step (cam2's video starts 1.")]
    assert len(rest) == 1 and "set skip_frames: {cam1: 2} in session.yaml" in rest[0]  # the session's skip added in
    assert kept.verdict == "doubtful"
    with h5py_file(tmp_path / "out" / "trajectories.h5") as f:
        assert f.attrs["skip_frames"] == "{cam1: 1, cam2: 0}"


def h5py_file(path):
    import h5py

    return h5py.File(path)


def test_gaitcap_silhouettes_says_when_the_cameras_look_out_of_step(late_session, tmp_path):
    """``gaitcap silhouettes SESSION`` runs the same check on its masks, taken to the silhouettes the
    tracker sees: a warning naming the cameras and the skip_frames to set (before: nothing until a
    whole tracking run); with those skip_frames in session.yaml, none."""
    import os
    import subprocess
    import sys

    ses, _ = late_session
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parents[1] / "src"), os.environ.get("PYTHONPATH", "")])}

    def silhouettes(session, out):
        return subprocess.run([sys.executable, "-m", "gaitcap", "silhouettes", str(session), "-o", str(out)],
                              capture_output=True, text=True, env=env, timeout=600)  # fmt: skip

    late = silhouettes(ses, tmp_path / "masks_late")
    assert late.returncode == 0, late.stderr
    said = [line for line in late.stderr.splitlines() if "out of step" in line]
    assert len(said) == 1 and "cam2's video starts 2." in said[0] and "set skip_frames: {cam1: 2}" in said[0], late.stderr
    synced = silhouettes(_copy(ses, tmp_path, {"cam1": 2}), tmp_path / "masks_synced")
    assert synced.returncode == 0, synced.stderr
    assert "out of step" not in synced.stderr


def test_a_run_keeps_enough_frames_for_the_check_at_every_common_rate():
    """The pipeline keeps the first MAX_FRAMES frames' tops (memory flat in the clip's length): that
    covers the window the check reads at up to 120 fps."""
    from gaitcap.sync_check import MAX_FRAMES, WINDOW_S

    for fps in (25, 30, 50, 60, 100, 120):
        assert MAX_FRAMES >= round(WINDOW_S * fps)


def test_frames_without_a_silhouette_give_no_warning_and_no_judgement():
    """A camera that never sees the subject (NaN tops): not judged, and nothing printed to the user."""
    import warnings

    from gaitcap.sync_check import pair_offset

    seen = np.sin(np.arange(60) * 0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        p = pair_offset(np.full(60, np.nan), seen, 25.0)
    assert not p.judged
