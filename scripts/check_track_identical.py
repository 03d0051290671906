"""Does ``gaitcap track`` still give bit-identical results? (a check for speed work, not a test)

    python scripts/check_track_identical.py --save REF [--work /tmp/gaitcap-identical]   # with the old code
    python scripts/check_track_identical.py --against REF [--work ...]                  # with the new code

Renders the embedded walk once into --work (``gaitcap synth``, seed 0), then runs ``python -m gaitcap
-q track`` of this checkout (its ``src`` first on the child's path) in a child process for each case
below (default configuration, seed 0) and either saves the outputs under REF or compares every
dataset of ``trajectories.h5`` (points, points_unfiltered, uncertainty, spread, poses, likelihood, fit,
quality, times) and the root attributes ``shape`` / ``height_m`` with exact equality
(``np.array_equal``, NaN equal to NaN). Prints one line per case with its wall seconds (IDENTICAL or
DIFFERENT, and each difference) and exits 1 when a case differs.

Cases (``--cases``): ``full``, the whole session (56 frames: shape calibration on the first 13, then
tracking); ``max12``, ``--max-frames 12`` (the shape window cut short); ``ipf6`` and
``condensation6``, the other trackers on 6 frames. Default: full and max12; ``--quick``: max12.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CASES = {"full": [], "max12": ["--max-frames", "12"], "ipf6": ["--tracker", "ipf", "--max-frames", "6"],
         "condensation6": ["--tracker", "condensation", "--max-frames", "6"]}
ATTRS = ("shape", "height_m", "tracker")


def session(work: Path) -> Path:
    root = work / "walk"
    if not (root / "truth.h5").is_file():
        subprocess.run([sys.executable, "-m", "gaitcap", "-q", "synth", "-o", str(root), "--force"], check=True)
    return root


def track(ses: Path, out: Path, extra: list[str]) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "gaitcap", "-q", "track", str(ses), "-o", str(out), "--force", *extra])
    finished = (out / "track.json").is_file() and json.loads((out / "track.json").read_text()).get("status") == "ok"
    if proc.returncode != 0 and not finished:  # a run judged failed exits 1 but is written: compared
        raise SystemExit(f"gaitcap track {ses} failed (exit {proc.returncode})")
    return time.perf_counter() - t0


def read(path: Path) -> tuple[dict[str, np.ndarray], dict[str, object]]:
    with h5py.File(path / "trajectories.h5", "r") as f:
        data = {k: f[k][()] for k in f.keys() if isinstance(f[k], h5py.Dataset)}
        attrs = {k: f.attrs[k] for k in ATTRS if k in f.attrs}
    return data, attrs


def compare(ref: Path, new: Path) -> list[str]:
    (rd, ra), (nd, na) = read(ref), read(new)
    errors = []
    if set(rd) != set(nd):
        errors.append(f"datasets differ: {sorted(rd)} vs {sorted(nd)}")
    for k in sorted(set(rd) & set(nd)):
        a, b = rd[k], nd[k]
        nan = a.dtype.kind == "f"
        if a.shape != b.shape or not np.array_equal(a, b, equal_nan=nan):
            diff = np.nanmax(np.abs(a - b)) if a.shape == b.shape and nan else "shape"
            errors.append(f"/{k}: differs (max abs difference {diff})")
    for k in ATTRS:
        if ra.get(k) != na.get(k):
            errors.append(f"attribute {k}: {ra.get(k)!r} vs {na.get(k)!r}")
    return errors


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--save", type=Path, help="save the reference outputs here")
    g.add_argument("--against", type=Path, help="compare with the reference outputs saved here")
    p.add_argument("--work", type=Path, default=Path("/tmp/gaitcap-identical"))
    p.add_argument("--cases", nargs="+", choices=sorted(CASES), default=["full", "max12"])
    p.add_argument("--quick", action="store_true", help="the max12 case only")
    args = p.parse_args()
    if args.quick:
        args.cases = ["max12"]
    if args.against:  # before any tracking: a case never saved could not be compared
        missing = [c for c in args.cases if not (args.against / c / "trajectories.h5").is_file()]
        if missing:
            p.error(f"--against {args.against}: no saved reference for {', '.join(missing)} (save it first with the "
                    f"old code: --save {args.against} --cases {' '.join(args.cases)})")
    os.environ.setdefault("OMP_WAIT_POLICY", "passive")
    # the children run this checkout's gaitcap, not whichever one the environment has installed
    # (an editable install of another tree would be checked instead)
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "src"), os.environ.get("PYTHONPATH")]))
    ses = session(args.work)
    failed = False
    for name in args.cases:
        extra = CASES[name]
        if args.save:
            out = args.save / name
            shutil.rmtree(out, ignore_errors=True)
            seconds = track(ses, out, extra)
            print(f"{name}: saved {out} ({seconds:.1f} s)")
            continue
        out = args.work / "new" / name
        shutil.rmtree(out, ignore_errors=True)  # a run that fails must not leave an earlier one to compare
        seconds = track(ses, out, extra)
        errors = compare(args.against / name, out)
        print(f"{name}: {'IDENTICAL' if not errors else 'DIFFERENT'} ({seconds:.1f} s)")
        for e in errors:
            print("   ", e)
        failed |= bool(errors)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
