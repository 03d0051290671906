"""scripts/bench_suite.py: a run into a WORK folder never silently replaces an earlier run's results
that it does not redo (refused before any work; ``--replace`` replaces them)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "bench_suite.py"
FULL = ["s00_vicon", "s01_opensim", "s02_c3dorg", "s03_vicon", "s04_opensim", "s05_c3dorg"]  # --sessions 6


def _suite(args: list[str]) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), "--sessions", "6", "--no-external", *args],
                          capture_output=True, text=True, timeout=120)  # fmt: skip


def _rows(work: Path, names: list[str], **extra) -> str:
    rows = [{"name": n, "status": "ok", "lower_mm": 30.0, **extra} for n in names]
    text = json.dumps(rows)
    (work / "suite.json").write_text(text)
    return text


def test_only_or_true_masks_into_an_earlier_runs_work_is_refused(tmp_path):
    """--only into a full run's WORK replaced its suite.json by the rows of the few sessions redone, and
    --true-masks into a WORK of runs on the sessions' own videos replaced their runs and rows (or, with
    --reuse, took the own videos' rows as the true masks'): refused, naming the file and what it holds."""
    work = tmp_path / "work"
    work.mkdir()
    (work / "sessions").write_text("")  # if a run were not refused, its first synth fails at once
    full = _rows(work, FULL)
    res = _suite(["--work", str(work), "--only", "s03_vicon"])
    assert res.returncode == 2, res.stderr
    assert f"{work / 'suite.json'}: holds the rows of 6 sessions, 5 of which this run leaves out" in res.stderr
    assert "--replace" in res.stderr
    assert (work / "suite.json").read_text() == full

    one = _rows(work, ["s03_vicon"])  # an earlier --only run of the same session on its own videos
    res = _suite(["--work", str(work), "--only", "s03_vicon", "--true-masks"])
    assert res.returncode == 2, res.stderr
    assert "holds a run on the sessions' own videos: this run, on the sessions' true masks (--true-masks)" in res.stderr
    assert (work / "suite.json").read_text() == one

    (work / "suite.json").unlink()  # a run stopped before its table: its runs' rows tell
    run = work / "runs" / "s03_vicon"
    run.mkdir(parents=True)
    (run / "suite_row.json").write_text(json.dumps({"name": "s03_vicon", "status": "ok", "true_masks": True}))
    res = _suite(["--work", str(work), "--only", "s03_vicon", "--reuse"])
    assert res.returncode == 2, res.stderr
    assert f"{work / 'runs'}: holds the runs of 1 of these sessions (s03_vicon) on the sessions' true masks" in res.stderr


def test_the_check_lets_the_same_run_be_redone():
    """The same sessions on the same videos again (a rerun, another --config) are not refused."""
    sys.path.insert(0, str(SCRIPT.parent))
    try:
        import bench_suite
    finally:
        sys.path.remove(str(SCRIPT.parent))
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        work = Path(d)
        assert bench_suite.replaces_other_run(work, "suite", FULL, False, False) is None  # nothing there
        _rows(work, ["s03_vicon"])
        assert bench_suite.replaces_other_run(work, "suite", ["s03_vicon"], False, False) is None
        assert bench_suite.replaces_other_run(work, "suite", FULL, False, False) is None  # a full run after --only
        _rows(work, FULL, true_masks=True)
        assert bench_suite.replaces_other_run(work, "suite", FULL, True, False) is None
        assert bench_suite.replaces_other_run(work, "suite", FULL, False, False) is not None
        # --silhouettes-only writes its own table and folder: the tracked runs' kind does not matter
        assert bench_suite.replaces_other_run(work, "suite_silhouettes", FULL, False, True) is None
