from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from gaitcap import __version__
from gaitcap.cli.main import COMMAND_MODULES, cli


@pytest.fixture
def runner() -> CliRunner:
    return CliRunner()


def test_version(runner):
    result = runner.invoke(cli, ["--version"])
    assert result.exit_code == 0
    assert __version__ in result.output


def test_every_command_help_has_an_example(runner):
    ctx = click.Context(cli)
    names = cli.list_commands(ctx)
    assert set(names) == set(COMMAND_MODULES)
    for name in names:
        result = runner.invoke(cli, [name, "--help"])
        assert result.exit_code == 0, name
        assert "Example" in result.output, name
        sub = getattr(cli.get_command(ctx, name), "commands", {})
        for subname in sub:
            r = runner.invoke(cli, [name, subname, "--help"])
            assert r.exit_code == 0 and "Example" in r.output, f"{name} {subname}"


def test_every_measurement_option_states_its_unit():
    """Every option taking a measurement (a float, or a size or length given as text) says its unit in
    its help: synth's --fps and --size and calibrate's --marker did not."""
    ctx = click.Context(cli)
    unit = re.compile(r"(?<![A-Za-z])(px|mm|cm|m|metres|deg|degrees|s|Hz|frames|pixels|fraction|frames per second)\b")
    missing = []

    def walk(command, path):
        if isinstance(command, click.Group):
            for name in command.list_commands(ctx):
                walk(command.get_command(ctx, name), [*path, name])
            return
        for p in command.params:
            measured = isinstance(p.type, click.types.FloatParamType) or p.name in ("size", "square", "marker")
            if isinstance(p, click.Option) and measured and not unit.search(f"{p.opts[-1]} {p.help or ''}"):
                missing.append(f"{' '.join(path)} {p.opts[-1]}")

    walk(cli, [])
    assert not missing, f"options whose help gives no unit: {', '.join(missing)}"


def test_a_height_at_the_ends_of_its_range_is_a_usage_error(runner, tmp_path):
    """--height 2.6 (or 0.5) passed the option's [0.5, 2.6] and failed after the backgrounds were fitted with
    'subject height 2.6 m is outside 0.5-2.6 m' (the body model's range is open), leaving an empty output
    folder; now the option's range is the model's."""
    session = tmp_path / "session"
    session.mkdir()
    for command in (["track", str(session), "-o", str(tmp_path / "out")], ["synth", "-o", str(tmp_path / "out")]):
        for height in ("0.5", "2.6"):
            result = runner.invoke(cli, [*command, "--height", height])
            assert result.exit_code == 2 and "Invalid value for '--height'" in result.output, result.output
            assert "0.5<x<2.6" in result.output
    assert not (tmp_path / "out").exists()


def test_synth_bad_size_is_a_usage_error(runner, tmp_path):
    result = runner.invoke(cli, ["synth", "-o", str(tmp_path / "s"), "--size", "big"])
    assert result.exit_code == 2
    assert "expected WIDTHxHEIGHT" in result.output


def test_synth_missing_motion_file_names_it(runner, tmp_path):
    result = runner.invoke(cli, ["synth", str(tmp_path / "nope.c3d"), "-o", str(tmp_path / "s")])
    assert result.exit_code == 1
    assert re.search(r"nope\.c3d: file not found", result.output)


def test_synth_refuses_existing_output(runner, tmp_path):
    out = tmp_path / "s"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    result = runner.invoke(cli, ["-q", "synth", "-o", str(out)])
    assert result.exit_code == 1
    assert "already exists (use --force" in result.output
    assert (out / "keep.txt").read_text() == "mine"


def test_synth_never_deletes_what_is_not_a_session_and_refuses_what_it_cannot_write(runner, tmp_path):
    """--force replaces an earlier synthetic session, never a folder of other files (it deleted a thesis);
    an output that cannot be written, or an odd frame size the codecs would crop, is refused before any
    work, in one line."""
    out = tmp_path / "s"
    out.mkdir()
    (out / "thesis.tex").write_text("mine")
    (out / "videos").mkdir()
    result = runner.invoke(cli, ["-q", "synth", "-o", str(out), "--force"])
    assert result.exit_code == 1
    assert "holds files that are not a synthetic session's (thesis.tex): not replaced" in result.output
    assert (out / "thesis.tex").read_text() == "mine"
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    for target, said in ((blocker, "is a file"), (blocker / "sess", f"{blocker}: is a file, not a folder: cannot write {blocker / 'sess'} under it")):
        result = runner.invoke(cli, ["-q", "synth", "-o", str(target)])
        assert result.exit_code == 1 and said in result.output and "Traceback" not in result.output, result.output
    result = runner.invoke(cli, ["-q", "synth", "-o", str(tmp_path / "odd"), "--size", "641x479"])
    assert result.exit_code == 2 and "width and height must be even" in result.output
    assert not (tmp_path / "odd").exists()


def test_demo_runs_end_to_end(runner, tmp_path):
    # two frames keep the test short (the initialisation search dominates); the README runs all 56
    result = runner.invoke(cli, ["demo", "-o", str(tmp_path), "--max-frames", "2"])
    assert result.exit_code == 0, result.output
    assert "100.0 %" in result.output  # every truth point inside the rendered silhouettes
    assert (tmp_path / "session" / "truth.h5").is_file()
    out = tmp_path / "track"
    for line, path in [("session", tmp_path / "session"), ("tracking", out), ("evaluation", out / "eval.json"),
                       ("report", out / "gait" / "report.html")]:  # fmt: skip
        assert f"{line}: {path}" in result.output
        assert path.exists(), path
    track = json.loads((out / "track.json").read_text())
    assert track["n_frames"] == 2 and f"verdict: {track['verdict']}" in result.output
    doc = json.loads((out / "eval.json").read_text())
    assert doc["frames"]["total"] == 2
    assert doc["verdict"] == track["verdict"] and doc["segment_lengths"]  # what gaitcap eval writes
    mpjpe = re.search(r"lower-limb MPJPE ([0-9.]+) mm", result.output)
    assert mpjpe and float(mpjpe.group(1)) == pytest.approx(doc["positions_mm"]["lower_limb"]["mpjpe_mm"], abs=0.05)
    assert "knee flexion RMSE left" in result.output


def test_demo_fails_when_its_tracking_verdict_is_failed(runner, tmp_path, monkeypatch):
    """As a smoke test (CI), a demo whose tracking verdict is failed exits 1 (its outputs still written)."""
    import gaitcap.demo

    real = gaitcap.demo.run_demo

    def judged_failed(*args, **kwargs):
        result = real(*args, **kwargs)
        result.track.verdict = "failed"
        return result

    monkeypatch.setattr(gaitcap.demo, "run_demo", judged_failed)
    result = runner.invoke(cli, ["demo", "-o", str(tmp_path), "--max-frames", "2"])
    assert result.exit_code == 1 and "the demo's tracking verdict is failed" in result.output
    assert (tmp_path / "track" / "track.json").is_file()


def test_track_starts_without_the_scipy_modules_imported_late():
    """scipy.signal and scipy.spatial.transform (about half a second of imports) are imported while
    the prefetch thread fits the backgrounds (gaitcap.pipeline._import_late), not when `gaitcap
    track` starts: importing the CLI and the pipeline leaves them out."""
    late = ("scipy.signal", "scipy.spatial.transform")
    code = f"import sys, gaitcap.cli.main, gaitcap.pipeline; print([m for m in {late!r} if m in sys.modules])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def _child(code: str, tmp_path) -> subprocess.CompletedProcess:
    """``code`` run in a fresh interpreter (the package importable as in this one), in tmp_path."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=env,
                          timeout=120)  # fmt: skip


def test_the_program_ends_with_its_status_output_and_exit_handlers(tmp_path):
    """gaitcap.cli.main.main ends the process itself (no module teardown): the command's output,
    its error message and status, and the exit handlers registered during the run all still come
    out as a normal exit gives them."""
    handler = "import atexit, pathlib; atexit.register(pathlib.Path('handled').write_text, 'yes'); "
    ok = _child(handler + "from gaitcap.cli.main import main; main(['--version'])", tmp_path)
    assert ok.returncode == 0 and __version__ in ok.stdout
    assert (tmp_path / "handled").read_text() == "yes"
    bad = _child("from gaitcap.cli.main import main; main(['-q', 'track', '.', '-o', 'out', '-c', 'none.yaml'])",
                 tmp_path)  # fmt: skip
    assert bad.returncode == 2 and "none.yaml" in bad.stderr and not (tmp_path / "out").exists()
    text = _child("from gaitcap.cli.main import _exit_now; _exit_now('stopped: reason')", tmp_path)
    assert text.returncode == 1 and text.stderr.strip() == "stopped: reason"


def test_a_console_whose_reader_has_gone_does_not_stop_the_command(tmp_path):
    """stderr a pipe whose reader has gone (``gaitcap ... 2>&1 | head -1``): the log lines are dropped and
    the command goes on to write its outputs and exit 0 (it stopped at its first log line, exit 1, nothing
    written)."""
    import gaitcap.data

    walk = Path(gaitcap.data.__file__).parent / "walk_pig.c3d"
    read, write = os.pipe()
    os.close(read)  # the reader is gone: every write to the pipe fails (EPIPE)
    try:
        run = subprocess.run([sys.executable, "-m", "gaitcap", "report", str(walk), "-o", str(tmp_path / "gait")],
                             stdout=subprocess.DEVNULL, stderr=write, cwd=tmp_path, timeout=300,
                             env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})  # fmt: skip
    finally:
        os.close(write)
    assert run.returncode == 0
    assert (tmp_path / "gait" / "report.html").is_file() and (tmp_path / "gait" / "parameters.json").is_file()


def test_the_program_waits_for_a_thread_still_running(tmp_path):
    """A non-daemon thread still running when the command returns is waited for (the normal exit),
    not cut short by the fast one."""
    code = ("import threading, time, pathlib\n"
            "threading.Thread(target=lambda: (time.sleep(0.5), pathlib.Path('done').write_text('x'))).start()\n"
            "from gaitcap.cli.main import main; main(['--version'])")  # fmt: skip
    run = _child(code, tmp_path)
    assert run.returncode == 0 and __version__ in run.stdout
    assert (tmp_path / "done").exists()


def test_track_says_its_verdict_and_notes_once(runner, embedded_session, tmp_path):
    """The run logs its verdict and notes; the command adds only where the results are."""
    import yaml

    from gaitcap.config import default_config_path

    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["shape"]["enabled"] = False
    data["factored_ipf"].update(particles=40, root_particles=80)
    config = tmp_path / "tracking.yaml"
    config.write_text(yaml.safe_dump(data))
    out = tmp_path / "out"
    result = runner.invoke(cli, ["track", str(embedded_session.session), "-o", str(out), "--max-frames", "3",
                                 "-c", str(config)])  # fmt: skip
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    track = json.loads((out / "track.json").read_text())
    assert [line for line in lines if line.startswith("verdict: ")] == [f"verdict: {track['verdict']}"]
    for note in track["verdict_notes"]:
        assert sum(note in line for line in lines) == 1
    assert lines[-1] == f"results: {out}"
    data["quality"]["min_fit"] = 0.999  # no frame fits that well: the verdict is failed
    data["lost_legs"] = {"retrack": False}
    config.write_text(yaml.safe_dump(data))
    result = runner.invoke(cli, ["track", str(embedded_session.session), "-o", str(out), "--max-frames", "3",
                                 "-c", str(config), "--force"])  # fmt: skip
    assert json.loads((out / "track.json").read_text())["verdict"] == "failed"  # written, for a look
    assert result.exit_code == 1, result.output
    assert f"the run's verdict is failed: the results in {out} must not be used" in result.output


def test_ctrl_c_inside_a_compiled_kernel_is_an_abort_not_a_traceback(runner, monkeypatch):
    """numba turns a Ctrl-C in a kernel into a SystemError raised from the KeyboardInterrupt."""
    import gaitcap.markers.inspect as inspect_module

    def interrupted(*args, **kwargs):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SystemError("CPUDispatcher(<function capsule_sums_views>) returned a result with an exception set")

    monkeypatch.setattr(inspect_module, "describe_file", interrupted)  # the command imports it when run
    result = runner.invoke(cli, ["markers", "walk.c3d"])
    assert result.exit_code == 1 and "Aborted!" in result.output and "SystemError" not in result.output
    assert not isinstance(result.exception, SystemError)


def test_the_project_and_its_copied_data_carry_their_licences():
    """The project's own licence file (pyproject says MIT) and a licence or attribution file beside
    every folder of copied third-party data (the embedded walk, each fixture folder)."""
    root = Path(__file__).resolve().parents[1]
    assert "MIT License" in (root / "LICENSE").read_text()
    assert "Apache License" in (root / "src" / "gaitcap" / "data" / "LICENSE.txt").read_text()
    fixtures = root / "tests" / "fixtures"
    assert "Apache License" in (fixtures / "walking" / "LICENSE-Apache-2.0.txt").read_text()
    for folder in ("opencv_chessboard_9x6", "pose2sim_qualisys"):
        assert (fixtures / "calibration" / folder / "LICENSE.txt").stat().st_size > 0
    for readme in (fixtures / "walking" / "README.md", fixtures / "calibration" / "README.md"):
        assert "Attribution" in readme.read_text() or "attribute" in readme.read_text()


@pytest.mark.parametrize("args", [
    ["track", "SESSION", "-o", "OUT", "--height", "nan"],
    ["synth", "-o", "OUT", "--fps", "nan"],
    ["eval", "SESSION", "--truth", "SESSION", "--max-angle-rmse-deg", "inf"],
    ["synth", "-o", "OUT", "--subject-height", "nan"],
    ["eval", "SESSION", "--truth", "SESSION", "--max-mpjpe-mm", "nan"],
    ["eval", "SESSION", "--truth", "SESSION", "--min-compared-fraction", "nan"],
])  # fmt: skip
def test_a_number_option_refuses_nan_and_infinity(runner, tmp_path, args):
    """Found by giving nan to every float option: Click's range checks let NaN through (every comparison
    with it is false): --height nan failed late, --fps nan with a traceback, a threshold of nan never failed."""
    (tmp_path / "s").mkdir()
    args = [str(tmp_path / "s") if a == "SESSION" else str(tmp_path / "o") if a == "OUT" else a for a in args]
    result = runner.invoke(cli, args)
    assert result.exit_code == 2, result.output
    assert f"{args[-1]!r} is not a finite number" in result.output
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(("args", "expected"), [
    (["--fps", "1e9"], "Invalid value for '--fps': 1000000000.0 is not in the range 1<=x<=1000."),
    (["--size", "99998x99998"], "'99998x99998': width and height must be 64 to 8192 pixels"),
    (["--size", "8x6"], "'8x6': width and height must be 64 to 8192 pixels"),
    (["--size", "0x0"], "'0x0': width and height must be 64 to 8192 pixels"),
])  # fmt: skip
def test_synth_refuses_a_size_or_rate_that_cannot_be_rendered(runner, tmp_path, args, expected):
    """Found with synth --fps 1e9: the walk resampled at that rate asked for terabytes and the process was
    killed by the system (exit 137, nothing said); a huge --size the same; --size 8x6 was told to be
    'WIDTHxHEIGHT', which it is. Now a usage error giving the range."""
    result = runner.invoke(cli, ["synth", "-o", str(tmp_path / "s"), *args])
    assert result.exit_code == 2
    assert expected in " ".join(result.output.split())
    assert not (tmp_path / "s").exists()
