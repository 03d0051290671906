"""``gaitcap track --body``: another clip of the same subject tracked with an earlier run's body."""

from __future__ import annotations

import json
import re
import shutil

import h5py
import pytest
from click.testing import CliRunner
from quick_config import quick_tracking

import gaitcap.pipeline as pipeline_module
from gaitcap.cli.main import cli
from gaitcap.errors import ConfigError, InputError
from gaitcap.pipeline import read_body, run_track


def _attrs(path):
    with h5py.File(path) as f:
        return {k: f.attrs[k] for k in ("height_m", "body_scales", "body_shifts", "shape")}


def test_track_with_an_earlier_runs_body(tracked_session, tmp_path, monkeypatch):
    """The earlier run's model is tracked as it is: same height and proportions, bit for bit, and
    no stage of the shape calibration runs."""
    embedded, first, _ = tracked_session

    def no_calibration(*args, **kwargs):
        raise AssertionError("the shape calibration ran although the body was given")

    monkeypatch.setattr(pipeline_module, "_calibrate_shape", no_calibration)
    summary = run_track(embedded.session, tmp_path / "out", body=first, progress=False, max_frames=12)
    assert summary.status == "ok" and summary.n_frames == 12
    before, after = _attrs(first / "trajectories.h5"), _attrs(tmp_path / "out" / "trajectories.h5")
    assert before["shape"].startswith(("thigh", "pelvis")) and "mean fit" in before["shape"]  # a calibrated body
    for key in ("height_m", "body_scales", "body_shifts"):
        assert after[key] == before[key]
    body = json.loads((tmp_path / "out" / "track.json").read_text())["body"]
    earlier = json.loads((first / "track.json").read_text())["body"]
    assert body["height_source"] == "--body"
    assert body["shape"] == f"reused from {first / 'trajectories.h5'} (its shape: {before['shape']})"
    assert body["segment_lengths_m"] == earlier["segment_lengths_m"]
    stages = json.loads((tmp_path / "out" / "track.json").read_text())["stages_s"]
    assert "initialisation" in stages and not {"shape", "shape_window", "shape_settle"} & set(stages)
    # the initialisation, here inside the per-frame loop, is not counted as the frames' tracking
    ms, searched = map(int, re.search(r"(\d+) ms/frame tracking \((\d+) frames searched", summary.message).groups())
    assert searched > 0 and ms * searched / 1000 <= stages["tracking"] + 0.02 * searched, (summary.message, stages)


def test_body_file_and_folder_give_the_same_model(tracked_session):
    _, first, _ = tracked_session
    a, b = read_body(first), read_body(first / "trajectories.h5")
    assert a.path == b.path == first / "trajectories.h5"
    assert a.model.proportions() == b.model.proportions() and a.model.height_m == b.model.height_m


def test_body_with_height_is_refused_and_creates_nothing(tracked_session, tmp_path):
    embedded, first, _ = tracked_session
    with pytest.raises(ConfigError, match="--height.*--body"):
        run_track(embedded.session, tmp_path / "out", body=first, height_m=1.7, progress=False, max_frames=2)
    assert not (tmp_path / "out").exists()


def test_body_that_cannot_be_reused_is_named(tracked_session, tmp_path):
    _, first, _ = tracked_session
    with pytest.raises(InputError, match="nothing-here"):
        read_body(tmp_path / "nothing-here")
    empty = tmp_path / "empty.h5"
    with h5py.File(empty, "w"):
        pass
    with pytest.raises(InputError, match=r"empty\.h5: not a gaitcap track output"):
        read_body(empty)
    no_height = tmp_path / "no_height" / "trajectories.h5"
    no_height.parent.mkdir()
    shutil.copy(first / "trajectories.h5", no_height)
    with h5py.File(no_height, "a") as f:
        del f.attrs["height_m"]
    with pytest.raises(InputError, match=r"no_height/trajectories\.h5: its body cannot be reused: .*height"):
        read_body(no_height.parent)


def test_cli_body_with_height_is_a_usage_error(tracked_session, tmp_path):
    """--body with --height is a usage error (exit 2, as other commands' conflicting options), not a failed run."""
    embedded, first, _ = tracked_session
    result = CliRunner().invoke(cli, ["track", str(embedded.session), "-o", str(tmp_path / "out"), "--body", str(first),
                                      "--height", "1.7"])  # fmt: skip
    assert result.exit_code == 2
    assert "--body" in result.output and "not both" in result.output
    assert not (tmp_path / "out").exists()


def test_an_uncalibrated_body_is_reused_with_a_warning(tracked_session, tmp_path, caplog):
    """A run whose calibration was skipped or rejected tracked body.yaml's proportions: reusing them
    is allowed, and said."""
    _, first, _ = tracked_session
    copy = tmp_path / "skipped" / "trajectories.h5"
    copy.parent.mkdir()
    shutil.copy(first / "trajectories.h5", copy)
    with h5py.File(copy, "a") as f:
        f.attrs["shape"] = "skipped: subject not in view in the first frames"
    caplog.set_level("WARNING")
    read_body(copy.parent)
    assert "its body was not calibrated (shape: skipped" in caplog.text
    caplog.clear()
    read_body(first)
    assert "not calibrated" not in caplog.text


def test_a_given_height_far_from_the_silhouettes_is_warned_about(tracked_session, tmp_path):
    """A slip in --height or session.yaml scales every result: a height a sixth or more off the silhouettes'
    estimate is warned about and noted in track.json; the session's own height is not."""
    from gaitcap.pipeline import _height_mismatch

    assert _height_mismatch(1.70, "--height", 1.62) is None  # the estimate runs a few % low
    assert "+21 %" in _height_mismatch(1.96, "--height", 1.62)
    assert _height_mismatch(1.2, "--height", None) is None
    embedded, first, _ = tracked_session
    config = quick_tracking(tmp_path)
    wrong = run_track(embedded.session, tmp_path / "wrong", config=config, height_m=1.2, progress=False, max_frames=3)
    assert any("height 1.20 m (--height) is" in n and "the silhouettes show" in n for n in wrong.verdict_notes)
    assert not any("the silhouettes show" in n for n in json.loads((first / "track.json").read_text())["verdict_notes"])
