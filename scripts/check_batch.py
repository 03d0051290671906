"""Folder-of-sessions checks for `gaitcap track FOLDER`, printed as a table.

    python scripts/check_batch.py [--work /tmp/gaitcap-batch] [--max-frames 20]

1. four synthetic sessions of the embedded walk (seeds 0-3); --jobs 1 vs --jobs 2 (wall time);
2. a re-run: every session skipped;
3. a copy of the folder with one video corrupted: the others succeed, the exit is 1, the summary
   names the failed session;
4. the same folder through a local Dask cluster: outputs identical to --jobs 1.
"""

from __future__ import annotations

import argparse
import filecmp
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
sys.path.insert(0, str(SRC))  # this checkout's gaitcap, not an installed one

from gaitcap.data import embedded_walk
from gaitcap.synth.session import SynthOptions, synthesize


def track(folder: Path, out: Path, *extra: str) -> tuple[float, subprocess.CompletedProcess]:
    t = time.perf_counter()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(SRC), os.environ.get("PYTHONPATH")])))
    proc = subprocess.run([sys.executable, "-m", "gaitcap", "-q", "track", str(folder), "-o", str(out), *extra],
                          capture_output=True, text=True, env=env)  # fmt: skip
    return time.perf_counter() - t, proc


def same_outputs(a: Path, b: Path) -> bool:
    for session in sorted(p.name for p in a.iterdir() if p.is_dir()):
        for name in ("joints.csv", "joints.trc"):
            if not filecmp.cmp(a / session / name, b / session / name, shallow=False):
                return False
    return True


#: what the checks write under --work, removed at the start of each call (nothing else there is touched)
OUTPUTS = ("sessions", "out_j1", "out_j2", "out_broken", "out_dask", "broken")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", type=Path, default=Path("/tmp/gaitcap-batch"))
    ap.add_argument("--max-frames", default="20")
    args = ap.parse_args()
    work = args.work
    for name in OUTPUTS:
        shutil.rmtree(work / name, ignore_errors=True)
    sessions = work / "sessions"
    for seed in range(4):
        synthesize(embedded_walk(), sessions / f"walk{seed}", SynthOptions(seed=seed), progress=False)
    mf = ("--max-frames", args.max_frames)
    rows = []
    t1, p1 = track(sessions, work / "out_j1", *mf, "--jobs", "1")
    rows.append(("4 sessions, --jobs 1", f"{t1:.1f} s", p1.returncode))
    t2, p2 = track(sessions, work / "out_j2", *mf, "--jobs", "2")
    rows.append(("4 sessions, --jobs 2", f"{t2:.1f} s (speed-up {t1 / t2:.2f}x)", p2.returncode))
    t3, p3 = track(sessions, work / "out_j2", *mf, "--jobs", "2")
    skipped = sum(line.split()[1:2] == ["skipped"] for line in p3.stdout.splitlines())  # the sessions' rows
    rows.append(("re-run of --jobs 2", f"{t3:.1f} s, {skipped} of 4 sessions skipped", p3.returncode))
    broken = work / "broken"
    shutil.copytree(sessions, broken)
    (broken / "walk2" / "videos" / "cam1.mp4").write_bytes(b"not a video" * 100)
    t4, p4 = track(broken, work / "out_broken", *mf, "--jobs", "2")
    names_failed = "walk2" in p4.stdout and "failed" in p4.stdout
    rows.append(("one corrupt video", f"{t4:.1f} s, summary names walk2 as failed: {names_failed}", p4.returncode))
    t5, p5 = track(sessions, work / "out_dask", *mf, "--scheduler", "local", "--jobs", "2")
    rows.append(("Dask local cluster", f"{t5:.1f} s, outputs identical to --jobs 1: "
                 f"{same_outputs(work / 'out_j1', work / 'out_dask')}", p5.returncode))  # fmt: skip
    rows.append(("--jobs 2 vs --jobs 1", f"outputs identical: {same_outputs(work / 'out_j1', work / 'out_j2')}", ""))
    print("| run | result | exit |\n|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]} | {r[2]} |")
    print("\nsummary printed for the corrupt-video folder:\n" + p4.stdout + p4.stderr[-600:])


if __name__ == "__main__":
    main()
