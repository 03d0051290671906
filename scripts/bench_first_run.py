"""The first run after a fresh install against the next ones (issue 30: the first within 20 % of the second).

    python scripts/bench_first_run.py [--work /tmp/gaitcap-first-run] [--runs 2] [--python python3]

Builds a new virtual environment in ``WORK/venv`` and installs this checkout into it as the README
says a user does (``pip install .``: the build compiles the numba kernels into the wheel), then runs
``gaitcap demo -o WORK/demo-K`` for K = 1..``--runs``, one after the other, each in a child process
and a fresh output folder, and prints a markdown table: the install's wall time, each run's wall
time and its ratio to the second run (the first is what a new user sees; the second finds whatever
the first left behind). The demo's own lines (its accuracy) are kept in ``WORK/demo-K.log``.

Packages come from the registry (or pip's cache) at install time; the runs need no network. The
virtual environment is built again at every call: what is measured is a first run, not a warm one.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def timed(cmd: list[str], log: Path, cwd: Path) -> float:
    """Wall seconds of ``cmd`` run to completion in ``cwd``, its output written to ``log``; exits
    with the command's message when it fails."""
    t0 = time.perf_counter()
    with log.open("w") as out:
        proc = subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT, cwd=cwd, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)}: exit {proc.returncode}; its output: {log}")
    return wall


def table(install_s: float, walls: list[float]) -> str:
    """The markdown table of an install time and the runs' wall times (seconds), each run's ratio to
    the second (or to the first when there is only one)."""
    base = walls[1] if len(walls) > 1 else walls[0]
    rows = ["| step | wall s | / second run |", "|---|---|---|", f"| `pip install .` | {install_s:.1f} | |"]
    rows += [f"| `gaitcap demo`, run {k} | {w:.1f} | {w / base:.2f} |" for k, w in enumerate(walls, 1)]
    return "\n".join(rows)


def clear_outputs(work: Path) -> None:
    """Remove this script's outputs of an earlier call from ``work`` (the venv, the demo folders and
    logs; nothing else), creating ``work`` when it does not exist."""
    for old in [work / "venv", *work.glob("demo-*")]:
        if old.is_dir() and not old.is_symlink():
            shutil.rmtree(old)
        else:
            old.unlink(missing_ok=True)
    work.mkdir(parents=True, exist_ok=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", type=Path, default=Path("/tmp/gaitcap-first-run"), help="venv, outputs and logs")
    ap.add_argument("--runs", type=int, default=2, help="demo runs after the install (>= 1)")
    ap.add_argument("--python", default=sys.executable, help="the interpreter the venv is built from")
    args = ap.parse_args()
    if args.runs < 1:
        ap.error("--runs must be at least 1")
    clear_outputs(args.work)
    venv = args.work / "venv"
    subprocess.run([args.python, "-m", "venv", str(venv)], check=True)
    install_s = timed([str(venv / "bin" / "pip"), "install", "-q", str(REPO)], args.work / "install.log", args.work)
    walls = [timed([str(venv / "bin" / "gaitcap"), "demo", "-o", str(args.work / f"demo-{k}")],
                   args.work / f"demo-{k}.log", args.work) for k in range(1, args.runs + 1)]  # fmt: skip
    print(table(install_s, walls))


if __name__ == "__main__":
    main()
