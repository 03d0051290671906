"""scripts/bench_first_run.py: its work folder is cleared of an earlier call's outputs only, and a new
one is fine."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "bench_first_run.py"


def _script():
    spec = importlib.util.spec_from_file_location("bench_first_run", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_new_work_folder_is_made(tmp_path):
    # 'python scripts/bench_first_run.py --work NEW' stopped on FileNotFoundError: NEW/venv (unlinked
    # because it was not a folder) before building anything: the script failed on every first use
    work = tmp_path / "new"
    res = subprocess.run([sys.executable, str(SCRIPT), "--work", str(work), "--python", "false"],
                         check=False, capture_output=True, text=True, timeout=60)  # fmt: skip
    assert "FileNotFoundError" not in res.stderr
    assert "CalledProcessError" in res.stderr  # it went on to build the venv ('false' fails at once)
    assert work.is_dir() and not any(work.iterdir())


def test_an_earlier_calls_outputs_go_and_nothing_else(tmp_path):
    (tmp_path / "venv" / "bin").mkdir(parents=True)
    (tmp_path / "demo-1" / "track").mkdir(parents=True)
    (tmp_path / "demo-1.log").write_text("run 1")
    (tmp_path / "install.log").write_text("kept: rewritten by the next install")
    (tmp_path / "notes.txt").write_text("mine")
    _script().clear_outputs(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["install.log", "notes.txt"]
