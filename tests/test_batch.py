from __future__ import annotations

import json
import logging
import os
from dataclasses import replace
from functools import partial
from pathlib import Path

import pytest
from batch_tasks import N_FRAMES, fake_track

from gaitcap.batch import any_failed, find_sessions, format_summary, run_batch
from gaitcap.track_summary import run_options
from gaitcap.errors import ConfigError, InputError, OutputError
from gaitcap.track_summary import TRACK_JSON, is_finished


def make_sessions(root: Path, names: list[str], fail: tuple[str, ...] = (), crash: tuple[str, ...] = ()) -> list[Path]:
    out = []
    for name in names:
        s = root / name
        s.mkdir(parents=True)
        (s / "calibration.toml").write_text("# not read by the fake task\n")
        if name in fail:
            (s / "FAIL").touch()
        if name in crash:
            (s / "CRASH").touch()
        out.append(s)
    return out


def test_find_sessions_sub_folders_sorted_or_the_folder_itself(tmp_path):
    make_sessions(tmp_path / "all", ["walk02", "walk01"])
    (tmp_path / "all" / "notes").mkdir()
    assert [p.name for p in find_sessions(tmp_path / "all")] == ["walk01", "walk02"]
    assert find_sessions(tmp_path / "all" / "walk02") == [tmp_path / "all" / "walk02"]


def test_find_sessions_errors_name_the_folder(tmp_path):
    with pytest.raises(InputError, match="nope: folder not found"):
        find_sessions(tmp_path / "nope")
    (tmp_path / "empty" / "sub").mkdir(parents=True)
    with pytest.raises(InputError, match=r"empty: no session found .*calibration.toml"):
        find_sessions(tmp_path / "empty")


def test_a_failed_session_does_not_stop_the_others(tmp_path):
    sessions = make_sessions(tmp_path / "in", ["a", "b", "c", "d"], fail=("b",), crash=("c",))
    res = run_batch(sessions, tmp_path / "out", task=fake_track)
    assert [s.status for s in res] == ["ok", "failed", "failed", "ok"]
    assert "never in view" in res[1].message
    assert res[2].message == "ZeroDivisionError: division by zero"
    assert any_failed(res)
    for name in "ad":
        assert is_finished(tmp_path / "out" / name)
        assert res["abcd".index(name)].n_frames == N_FRAMES
    for name in "bc":
        assert not (tmp_path / "out" / name / TRACK_JSON).exists()
    # one log per session; a failure's log has the message and the traceback
    log_b = (tmp_path / "out" / "b" / "track.log").read_text()
    assert "fake tracking of b" in log_b and "never in view" in log_b and "Traceback" in log_b
    log_a = (tmp_path / "out" / "a" / "track.log").read_text()
    assert "fake tracking of a" in log_a and "of b" not in log_a


def test_finished_sessions_are_skipped_unless_force(tmp_path):
    sessions = make_sessions(tmp_path / "in", ["a", "b"], fail=("b",))
    run_batch(sessions, tmp_path / "out", task=fake_track)
    (sessions[1] / "FAIL").unlink()
    again = run_batch(sessions, tmp_path / "out", task=fake_track)
    assert [s.status for s in again] == ["skipped", "ok"]  # the failed one is redone
    assert "use --force" in again[0].message
    forced = run_batch(sessions, tmp_path / "out", task=fake_track, force=True)
    assert [s.status for s in forced] == ["ok", "ok"]
    assert not any_failed(forced)
    judged_failed = [replace(forced[0], verdict="failed"), forced[1]]  # tracked, but not to be used
    assert any_failed(judged_failed) and any_failed([replace(again[0], verdict="failed")])  # a skipped one too


def test_a_session_finished_with_other_options_is_neither_skipped_nor_redone(tmp_path, caplog):
    """A batch run again with another tracker, configuration, --max-frames, --height or --body: a session
    finished with other options (track.json's ``options``) is counted failed, naming them, and not tracked
    (--force redoes it); one finished with the same options is skipped; one recorded before options were
    recorded is skipped as before. Decided from the records: no session is tracked here."""
    sessions = make_sessions(tmp_path / "in", ["a", "b", "c"])
    recorded = {"a": run_options(max_frames=30), "b": run_options(tracker="ipf", max_frames=30), "c": None}
    for name, options in recorded.items():
        out = tmp_path / "out" / name
        out.mkdir(parents=True)
        doc = {"status": "ok", "n_frames": 30, "n_flagged": 0, "verdict": "ok", **({"options": options} if options else {})}
        (out / "track.json").write_text(json.dumps(doc))
    res = run_batch(sessions, tmp_path / "out", max_frames=30)  # the default task: run_track
    assert [s.status for s in res] == ["skipped", "failed", "skipped"]
    assert res[1].message == ("finished before with other options (the tracker factored-ipf (was ipf)): use --force "
                              "to redo it with these")  # fmt: skip
    assert any_failed(res) and "b: finished before with other options" in caplog.text
    res = run_batch(sessions[:1], tmp_path / "out", max_frames=20, height_m=1.7)
    assert res[0].status == "failed"
    assert "--max-frames 20 (was 30); --height 1.7 (was not given)" in res[0].message


def test_a_tracker_or_seed_the_configuration_refuses_is_a_config_error(tmp_path):
    """``tracker`` and ``seed`` are set on the configuration after it is read: a value its schema refuses
    is a ConfigError naming the key (as one in the file is), not pydantic's ValidationError, which escaped
    run_batch itself when a finished session's options were compared (_changed_options catches
    GaitcapError only)."""
    with pytest.raises(ConfigError, match=r"the options given: tracker: Input should be 'condensation', 'ipf' or "
                                          r"'factored-ipf'"):  # fmt: skip
        run_options(tracker="factored_ipf")
    with pytest.raises(ConfigError, match="the options given: seed: Input should be greater than or equal to 0"):
        run_options(seed=-1)
    sessions = make_sessions(tmp_path / "in", ["a"])
    out = tmp_path / "out" / "a"
    out.mkdir(parents=True)
    doc = {"status": "ok", "n_frames": 30, "n_flagged": 0, "verdict": "ok", "options": run_options(max_frames=30)}
    (out / "track.json").write_text(json.dumps(doc))
    with pytest.raises(ConfigError, match="the options given: tracker"):  # refused before any session
        run_batch(sessions, tmp_path / "out", tracker="factored_ipf")


def test_a_configuration_that_cannot_be_read_is_refused_though_every_session_finished(tmp_path):
    """A batch whose sessions had all finished skipped them all, exit 0, with a -c file the schema refuses
    ('tracker: nope'): it was only read to compare the options, and its error taken for 'cannot compare'.
    It is refused before any session now, as it is when a session is still to be tracked."""
    from click.testing import CliRunner

    from gaitcap.cli.main import cli

    sessions = make_sessions(tmp_path / "in", ["a"])
    out = tmp_path / "out" / "a"
    out.mkdir(parents=True)
    doc = {"status": "ok", "n_frames": 30, "n_flagged": 0, "verdict": "ok", "options": run_options(max_frames=30)}
    (out / "track.json").write_text(json.dumps(doc))
    bad = tmp_path / "bad.yaml"
    bad.write_text("tracker: nope\n")
    with pytest.raises(ConfigError, match=r"bad\.yaml: tracker: Input should be"):
        run_batch(sessions, tmp_path / "out", config=bad, max_frames=30)
    res = CliRunner().invoke(cli, ["track", str(tmp_path / "in"), "-o", str(tmp_path / "out"), "-c", str(bad),
                                   "--max-frames", "30"])  # fmt: skip
    assert res.exit_code == 1 and "bad.yaml: tracker" in res.output, res.output


def test_unreadable_track_json_means_not_finished(tmp_path, caplog):
    sessions = make_sessions(tmp_path / "in", ["a"])
    out = tmp_path / "out" / "a"
    out.mkdir(parents=True)
    (out / TRACK_JSON).write_text("{ half written")
    res = run_batch(sessions, tmp_path / "out", task=fake_track)
    assert res[0].status == "ok"
    assert "track.json: unreadable" in caplog.text


def test_task_options_reach_the_task_and_progress_is_off_in_parallel(tmp_path):
    sessions = make_sessions(tmp_path / "in", ["a"])
    run_batch(sessions, tmp_path / "out", task=fake_track, tracker="factored_ipf")
    log_a = (tmp_path / "out" / "a" / "track.log").read_text()
    assert "tracker=factored_ipf, progress=True" in log_a


def test_quiet_cli_batch_shows_no_progress(tmp_path, monkeypatch):
    """``gaitcap -q track FOLDER`` in one process: no progress bars (warnings only); without -q, shown."""
    from click.testing import CliRunner

    import gaitcap.cli.track as track_cli
    from gaitcap.cli.main import cli

    monkeypatch.setattr(track_cli, "run_batch", partial(run_batch, task=fake_track))
    make_sessions(tmp_path / "in", ["a"])
    log_a = tmp_path / "out" / "a" / "track.log"
    for flags, shown in ((["-q"], False), ([], True)):
        result = CliRunner().invoke(cli, [*flags, "track", str(tmp_path / "in"), "-o", str(tmp_path / "out"), "--force"])
        assert result.exit_code == 0, result.output
        runs = [line for line in log_a.read_text().splitlines() if "fake tracking of a" in line]
        assert runs[-1].endswith(f"progress={shown})")


def test_cli_batch_writes_a_machine_readable_summary(tmp_path, monkeypatch):
    """``gaitcap track FOLDER -o OUT`` writes OUT/batch.json: every session's summary (a failed one's
    message too) and whether the batch failed, as its exit code says (for a CI job)."""
    from click.testing import CliRunner

    import gaitcap.cli.track as track_cli
    from gaitcap.cli.main import cli

    monkeypatch.setattr(track_cli, "run_batch", partial(run_batch, task=fake_track))
    make_sessions(tmp_path / "in", ["a", "b"], fail=("b",))
    result = CliRunner().invoke(cli, ["-q", "track", str(tmp_path / "in"), "-o", str(tmp_path / "out")])
    assert result.exit_code == 1
    doc = json.loads((tmp_path / "out" / "batch.json").read_text())
    assert doc["failed"] is True and [s["status"] for s in doc["sessions"]] == ["ok", "failed"]
    assert doc["sessions"][0]["verdict"] == "doubtful" and doc["sessions"][0]["out"] == str(tmp_path / "out" / "a")
    assert "never in view" in doc["sessions"][1]["message"]


def test_parallel_processes(tmp_path):
    sessions = make_sessions(tmp_path / "in", ["a", "b", "c"], fail=("c",))
    res = run_batch(sessions, tmp_path / "out", task=fake_track, jobs=2)
    assert [s.status for s in res] == ["ok", "ok", "failed"]
    pids = {s.message for s in res[:2]}
    assert all(p.startswith("pid ") and p != f"pid {os.getpid()}" for p in pids)  # ran in workers
    assert "progress=False" in (tmp_path / "out" / "a" / "track.log").read_text()
    assert "never in view" in (tmp_path / "out" / "c" / "track.log").read_text()


def test_dask_scheduler_address(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    sessions = make_sessions(tmp_path / "in", ["a", "b"], fail=("b",))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        res = run_batch(sessions, tmp_path / "out", task=fake_track, scheduler=cluster.scheduler_address)
    assert [s.status for s in res] == ["ok", "failed"]
    assert is_finished(tmp_path / "out" / "a")
    assert "never in view" in (tmp_path / "out" / "b" / "track.log").read_text()


def test_bad_batch_arguments(tmp_path):
    sessions = make_sessions(tmp_path / "x", ["a"]) + make_sessions(tmp_path / "y", ["a"])
    with pytest.raises(InputError, match="several sessions are named a"):
        run_batch(sessions, tmp_path / "out", task=fake_track)
    with pytest.raises(ConfigError, match="--jobs must be at least 1"):
        run_batch(sessions[:1], tmp_path / "out", task=fake_track, jobs=0)
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(OutputError, match="file/out: cannot create the output folder"):
        run_batch(sessions[:1], blocker / "out", task=fake_track)


def test_read_only_output_root_fails_each_session_clearly(tmp_path, read_only_dir):
    sessions = make_sessions(tmp_path / "in", ["a"])
    res = run_batch(sessions, read_only_dir, task=fake_track)
    assert res[0].status == "failed"
    assert "ro/a/track.log: cannot write the session log (Permission denied)" in res[0].message


def test_console_stays_quiet_when_logger_is_at_warning(tmp_path):
    logger = logging.getLogger("gaitcap")
    old = logger.level
    logger.setLevel(logging.WARNING)
    try:
        sessions = make_sessions(tmp_path / "in", ["a"])
        run_batch(sessions, tmp_path / "out", task=fake_track)
        assert logger.level == logging.WARNING
    finally:
        logger.setLevel(old)
    assert "fake tracking of a" in (tmp_path / "out" / "a" / "track.log").read_text()


def test_format_summary_table(tmp_path):
    sessions = make_sessions(tmp_path / "in", ["walk01", "walk02"], fail=("walk02",))
    text = format_summary(run_batch(sessions, tmp_path / "out", task=fake_track))
    lines = text.splitlines()
    assert lines[0].split() == ["session", "status", "verdict", "frames", "flagged", "seconds", "message"]
    assert lines[1].split()[:5] == ["walk01", "ok", "doubtful", str(N_FRAMES), "1"]
    assert lines[1].endswith("a poor fit for 1 of 12 frames")  # the verdict's reasons replace the message
    assert lines[2].split()[:3] == ["walk02", "failed", "-"] and "never in view" in lines[2]
    assert lines[-1] == "2 sessions: 1 ok, 1 failed, 0 skipped; verdicts: 0 ok, 1 doubtful, 0 failed"
    doc = json.loads((tmp_path / "out" / "walk01" / TRACK_JSON).read_text())
    assert doc["status"] == "ok" and doc["verdict"] == "doubtful" and doc["verdict_reasons"]
    again = format_summary(run_batch(sessions[:1], tmp_path / "out", task=fake_track)).splitlines()
    assert again[1].split()[:5] == ["walk01", "skipped", "doubtful", str(N_FRAMES), "1"]  # the finished run's


def test_dask_local_cluster(tmp_path):
    pytest.importorskip("dask.distributed")
    sessions = make_sessions(tmp_path / "in", ["a", "b"])
    res = run_batch(sessions, tmp_path / "out", task=fake_track, scheduler="local", jobs=2)
    assert [s.status for s in res] == ["ok", "ok"]
    assert all(s.message != f"pid {os.getpid()}" for s in res)  # worker processes


def test_dask_missing_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "dask.distributed", None)
    sessions = make_sessions(tmp_path / "in", ["a"])
    with pytest.raises(ConfigError, match=r"dask.distributed is not installed \(pip install 'gaitcap\[distributed\]'\)"):
        run_batch(sessions, tmp_path / "out", task=fake_track, scheduler="local")


def test_session_output_blocked_by_a_file(tmp_path):
    sessions = make_sessions(tmp_path / "in", ["a", "b"])
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "a").write_text("not a folder")
    res = run_batch(sessions, tmp_path / "out", task=fake_track)
    assert [s.status for s in res] == ["failed", "ok"]
    assert "out/a/track.log: cannot write the session log" in res[0].message
