"""End-to-end speed of ``gaitcap track`` on short and long clips, stage by stage, against its floor.

    PYTHONPATH=src python scripts/bench_speed.py [--runs 3] [--seconds 2.5 5 20] [--fps 25] [--reuse-body]
        [--batch K] [--walk turns|ping-pong] [--work /tmp/gaitcap-bench] [-- extra gaitcap track options]

The clips (2 cameras, 640x480, ``gaitcap synth``'s defaults, rendered once into --work):

- ``--walk turns`` (the default): the embedded walk up and down a walkway, as a lab records a longer
  clip: the walk (2.2 s), a standing pivot of 180 degrees (1 s), the walk back over the same ground
  (2.3 s), and so on, rendered to each clip length (``bench_memory.turn_session``);
- ``--walk ping-pong``: the sessions of scripts/bench_memory.py, the embedded walk's videos played
  forwards and backwards to each clip length (the figures quoted before 2026-11-30). Played
  backwards, the subject walks backwards: a run whose body moves against the way it faces is one
  the verdict would doubt, so the backward pass is tracked a second time from a fresh start
  (``backward.restart``), a cost a subject walking forwards does not have.

Each clip is tracked ``--runs`` times by ``python -m gaitcap -q track`` in a child process;
the table gives the medians of:

- wall: the child's wall time, start to exit; fps: frames / wall;
- start-up: wall minus the run's own seconds (track.json): interpreter, imports, exit;
- the stages of track.json's ``stages_s`` (gaitcap.pipeline.Stages): setup (configuration,
  session and video checks), kernels (numba: loaded from the cache, or compiled; and the late
  imports), first frames (waiting for the frames the initialisation looks at: background fitting
  and their silhouettes; the rest of the shape window is read during the initialisation), init
  (initialisation), shape window (the calibration window tracked with the shipped proportions),
  shape (the calibration's search: every candidate's re-fits), legs settled (the first frames
  tracked from the calibrated start and its mirror), tracking (the per-frame loop), backward (the second
  pass over the clip, tracking/backward.py: the stretches of it not tracked beside the forward pass,
  on every core, and the merge), verdict (the legs' support on the spooled silhouettes and the
  run's verdict, gaitcap.quality), writing (read-back,
  smoothing, CSV/TRC); background (its fitting, in the prefetch thread, overlapping setup, kernels
  and first frames) is shown apart;
- with ``--reuse-body``, each clip is also tracked ``--runs`` times with the body its first run
  calibrated (``gaitcap track --body``: a lab's further clips of the same subject, no shape
  calibration), in a row of its own marked "--body"; the stages it skips show 0;
- with ``--batch K``, each clip is also copied K times (symbolic links) into a folder tracked by one
  ``python -m gaitcap -q track FOLDER --body BODY`` (BODY: the clip's first run, as ``--reuse-body``):
  a lab's further clips of one subject in one process, whose start-up and kernels are paid once.
  Its row ("batch") gives the medians over the copies 2 to K (the first also loads the kernels):
  each copy's stages from its track.json, wall its own seconds plus an even share of the process's
  start-up (the process's wall minus the copies' seconds, shown as start-up), and the floor of
  the clip's other runs;
- floor: in this process, the same decoding and silhouettes alone (gaitcap.pipeline's
  observation stream: background fitting, decoding, extraction and preparation of every frame of
  both cameras, side by side as in a run), and wall / floor; floor CPU ms/frame: the process's
  CPU time over the floor (``time.process_time``, all threads) per frame, a figure that other jobs
  on the machine disturb far less than wall times;
- where the clip has a truth (``--walk turns``: ``truth.h5``), each run scored by ``gaitcap eval``
  (not timed): lower-limb mm (the median over the runs) and the runs' verdicts (track.json), so
  that a faster run is also seen to be as accurate.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_memory import base_session, gaitcap_in_child, long_session, track_in_child, turn_session  # noqa: E402
from bench_suite import evaluate_run  # noqa: E402

from gaitcap.pipeline import Stages, _observations  # noqa: E402
from gaitcap.session import Session  # noqa: E402
from gaitcap.session_check import check_session_videos  # noqa: E402
from gaitcap.silhouette.config import SilhouetteConfig  # noqa: E402
from gaitcap.tracking.config import load_tracking_config  # noqa: E402
from gaitcap.tracking.observation import tracking_views  # noqa: E402

#: track.json's main-thread stages, in their order, and the table's headings for them
STAGES = {"setup": "setup", "kernels": "kernels", "first_frames": "first frames", "initialisation": "init",
          "shape_window": "shape window", "shape": "shape", "shape_settle": "legs settled", "tracking": "tracking",
          "backward": "backward", "verdict": "verdict", "writing": "writing"}  # fmt: skip


def floor_seconds(session: Path) -> tuple[float, float, int]:
    """(wall seconds, CPU seconds, frames) of the observation stream alone (no tracking) over the
    whole session."""
    ses = Session.open(session)
    rig = check_session_videos(ses).rig
    views = tracking_views(rig, load_tracking_config().scale)
    t0, c0 = time.perf_counter(), time.process_time()
    frames = sum(1 for _ in _observations(ses, rig.names, views, SilhouetteConfig.load(), 10**9, Stages()))
    if frames == 0:
        raise SystemExit(f"{session}: no frame decoded")
    return time.perf_counter() - t0, time.process_time() - c0, frames


def lower_limb_mm(session: Path, out: Path) -> float:
    """``gaitcap eval`` of the run ``out`` against ``session``'s truth (``bench_suite.evaluate_run``): its
    lower-limb MPJPE in mm (NaN: the session has no truth.h5, or eval failed)."""
    truth = session / "truth.h5"
    if not truth.is_file():
        return math.nan
    lower = evaluate_run(out, truth).get("lower_mm")
    return math.nan if lower is None else float(lower)


def run_row(session: Path, out: Path, summary: dict, wall: float, start_up: float) -> dict[str, float]:
    """The table's quantities of one run (its track.json ``summary``, written to ``out``), but the floor."""
    stages = summary.get("stages_s", {})
    row = {"frames": summary["n_frames"], "wall": wall, "start-up": start_up,
           "lower mm": lower_limb_mm(session, out), "run verdict": summary.get("verdict", "?")}  # fmt: skip
    row |= {name: stages.get(key, float("nan")) for key, name in STAGES.items()}
    row["background"] = stages.get("background", float("nan"))
    return row


def measure(session: Path, out: Path, extra: list[str]) -> dict[str, float]:
    """One tracking run and one floor measurement of ``session``: the table's quantities."""
    _, wall, summary = track_in_child(session, out, extra)
    row = run_row(session, out, summary, wall, wall - summary["seconds"])
    row["floor"], cpu, frames = floor_seconds(session)
    row["floor CPU ms/frame"] = 1000 * cpu / frames
    return row


def measure_batch(session: Path, work: Path, body: Path, k: int, extra: list[str], floor: float,
                  floor_cpu: float) -> list[dict[str, float]]:  # fmt: skip
    """``k`` copies of ``session`` tracked by one ``gaitcap track FOLDER --body BODY`` process: the
    rows of copies 2 to k (the table's quantities; the floor given, measured on the clip's runs)."""
    folder, out = work / f"{session.name}-batch{k}", work / f"{session.name}-batch{k}-out"
    names = [f"copy{i + 1:02d}" for i in range(k)]
    for name in names:
        if not (folder / name).is_dir():
            shutil.copytree(session, folder / name, copy_function=os.symlink)
    _, wall = gaitcap_in_child(["track", str(folder), "-o", str(out), "--force", "--body", str(body), *extra])
    summaries = [json.loads((out / name / "track.json").read_text()) for name in names]
    start_up = (wall - sum(s["seconds"] for s in summaries)) / k
    return [run_row(session, out / name, summary, summary["seconds"] + start_up, start_up)
            | {"floor": floor, "floor CPU ms/frame": floor_cpu}
            for name, summary in zip(names[1:], summaries[1:], strict=True)]  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3, help="runs per clip (the table gives their medians)")
    ap.add_argument("--seconds", type=float, nargs="+", default=[2.5, 5.0, 20.0], help="clip lengths")
    ap.add_argument("--fps", type=float, default=25.0)
    ap.add_argument("--work", type=Path, default=Path("/tmp/gaitcap-bench"))
    ap.add_argument("--reuse-body", action="store_true",
                    help="also time each clip tracked with the body its first run calibrated (gaitcap track --body)")
    ap.add_argument("--batch", type=int, default=0, metavar="K",
                    help="also time K copies of each clip tracked in one process with its first run's body")
    ap.add_argument("--walk", choices=["turns", "ping-pong"], default="turns",
                    help="the clips: the walk up and down a walkway, or its videos played forwards and backwards")
    ap.add_argument("extra", nargs="*", help="options passed on to gaitcap track (after --)")
    args = ap.parse_args()
    source = base_session(args.work, args.fps) if args.walk == "ping-pong" else None
    cols = ["wall", "start-up", *STAGES.values(), "background", "floor"]
    print(f"| clip s | frames | fps | {' | '.join(c + ' s' for c in cols)} | wall / floor | floor CPU ms/frame "
          "| lower-limb mm | verdicts |")  # fmt: skip
    print("|" + "---|" * (len(cols) + 7))
    for seconds in args.seconds:
        n = int(round(seconds * args.fps))
        if source is None:
            session = turn_session(args.work, n, args.fps)
        else:
            session = long_session(source, args.work / f"{source.name}-{n}frames", n, args.fps)
        out = args.work / f"{session.name}-speed-out"
        body = args.work / f"{session.name}-body"
        variants = [("", args.extra)] + ([(" (--body)", [*args.extra, "--body", str(body)])] if args.reuse_body else [])
        for label, extra in variants:
            runs = []
            for k in range(args.runs):
                runs.append(measure(session, out, extra))
                print(f"<!-- {seconds:g} s{label}, run {k + 1}: wall {runs[-1]['wall']:.1f} s, "
                      f"floor {runs[-1]['floor']:.2f} s -->", flush=True)  # fmt: skip
                if (args.reuse_body or args.batch) and not label and k == 0:  # the body the first run calibrated
                    shutil.rmtree(body, ignore_errors=True)
                    shutil.copytree(out, body)
            print_row(f"{seconds:g}{label}", runs, cols)
            if not label:
                floor = tuple(statistics.median(r[c] for r in runs) for c in ("floor", "floor CPU ms/frame"))
        if args.batch > 1:
            batch = [row for _ in range(args.runs) for row in measure_batch(session, args.work, body, args.batch,
                                                                            args.extra, *floor)]  # fmt: skip
            print_row(f"{seconds:g} (batch of {args.batch}, --body)", batch, cols)


def print_row(label: str, runs: list[dict[str, float]], cols: list[str]) -> None:
    """The table's row of ``runs``: the medians of each column (a stage a run skipped counts 0)."""
    keys = ["frames", *cols, "floor CPU ms/frame"]
    med = {c: statistics.median(0.0 if math.isnan(r[c]) else r[c] for r in runs) for c in keys}
    scored = [r["lower mm"] for r in runs if not math.isnan(r["lower mm"])]
    lower = f"{statistics.median(scored):.1f}" if scored else "-"
    verdicts = ", ".join(sorted({str(r["run verdict"]) for r in runs}))
    print(f"| {label} | {med['frames']:.0f} | {med['frames'] / med['wall']:.1f} | "
          + " | ".join(f"{med[c]:.2f}" for c in cols)
          + f" | {med['wall'] / med['floor']:.0f} | {med['floor CPU ms/frame']:.1f} | {lower} | {verdicts} |",
          flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
