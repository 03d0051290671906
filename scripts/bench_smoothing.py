"""The trajectories' low-pass (``smoothing.cutoff_hz``) chosen on finished suite runs, without tracking again.

    PYTHONPATH=src python scripts/bench_smoothing.py WORK [WORK ...] --cutoffs 6 5 4.5 4 [--out DIR]

WORK is a ``scripts/bench_suite.py --work`` folder whose runs have finished (``WORK/runs/<name>`` with
``trajectories.h5`` and ``eval.json``; sessions under ``WORK/sessions``, the external ones read from
``../shared/data/external_sessions``). The smoothing changes only the written points, not the tracking:
each run's raw estimate (``/points_unfiltered``, with its ``/quality`` flags) is filtered again at each
cut-off ("none": not filtered) by the function ``gaitcap track`` writes its points with
(``gaitcap.pipeline._finish_points``, order ``--order``), written into a copy of the run under ``--out``
(the other files linked), and scored by ``gaitcap eval`` as the suite scores it (``bench_suite.evaluate_run``).
A run of the suite tracked with the cut-off in its configuration gives the same figures (checked: 4.5 Hz,
tracker seed 0, 30 of 30 runs equal).

Printed per cut-off, pooled over the WORK folders: the lower-limb MPJPE's median, 90th percentile, worst
and mean, runs better / worse by more than 2 mm than at the first cut-off listed, knee flexion RMSE
median, event timing median and events missed, stride length |error| median, and how far each knee's
largest and smallest flexion over the clip lie from the truth's (medians over the runs, degrees: what
a low-pass takes off the peaks a clinician reads).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "scripts"))

from bench_suite import SHARED, evaluate_run, external_sessions  # noqa: E402

from gaitcap.evaluation.compare import align  # noqa: E402
from gaitcap.evaluation.report import read_tracked, read_truth_reference  # noqa: E402
from gaitcap.gait.analysis import analyse, angles_by_pass  # noqa: E402
from gaitcap.pipeline import _finish_points  # noqa: E402
from gaitcap.tracking.config import SmoothingConfig, TrackingConfig, load_tracking_config  # noqa: E402

KNEES = ("knee_flexion_l", "knee_flexion_r")


def truth_of(work: Path, name: str, external: dict[str, Path]) -> Path:
    """A suite run's truth: an external session's (``external``: name -> truth, as bench_suite.py names
    them), else its own session's truth.h5."""
    return external.get(name) or work / "sessions" / name / "truth.h5"


def smoothing(cutoff: str, order: int) -> TrackingConfig:
    """The shipped tracking configuration with the smoothing at ``cutoff`` (Hz, or "none") and ``order``."""
    smooth = SmoothingConfig(cutoff_hz=None if cutoff == "none" else float(cutoff), order=order)
    return load_tracking_config().model_copy(update={"smoothing": smooth})


def refiltered_copy(run: Path, out: Path, cfg: TrackingConfig) -> None:
    """``out``: ``run``'s files linked, its trajectories.h5 copied with /points written again with ``cfg``'s
    smoothing."""
    out.mkdir(parents=True, exist_ok=True)
    for f in run.iterdir():
        if f.name not in ("trajectories.h5", "eval.json") and not (out / f.name).exists():
            os.symlink(f.resolve(), out / f.name)
    shutil.copy(run / "trajectories.h5", out / "trajectories.h5")
    with h5py.File(out / "trajectories.h5", "r+") as h:
        points, _ = _finish_points(h["points_unfiltered"][...], h["quality"][...], float(h["points"].attrs["rate_hz"]),
                                   cfg)  # fmt: skip
        h["points"][...] = points


def knee_extremes(run: Path, truth: Path) -> tuple[float, float]:
    """|tracked - true| of each knee's largest and of its smallest flexion over the clip (degrees), the
    mean of both knees."""
    ref = read_truth_reference(truth).trajectory
    aligned = align(read_tracked(run), ref)
    passes = analyse(ref).passes
    est, _ = angles_by_pass(aligned.trajectory("est", mask_invalid=True), passes)
    true, _ = angles_by_pass(aligned.trajectory("ref"), passes)
    high = np.mean([abs(np.nanmax(est[k]) - np.nanmax(true[k])) for k in KNEES])
    low = np.mean([abs(np.nanmin(est[k]) - np.nanmin(true[k])) for k in KNEES])
    return float(high), float(low)


def scored(work: Path, name: str, out: Path, cutoff: str, cfg: TrackingConfig, truth: Path) -> dict:
    """The suite's row of ``name``'s run filtered at ``cutoff`` by ``cfg`` (cached in ``out``), scored
    against ``truth``, with the knees' extremes."""
    copy = out / work.name / cutoff / name
    if (copy / "row.json").exists():
        return json.loads((copy / "row.json").read_text())
    refiltered_copy(work / "runs" / name, copy, cfg)
    row = evaluate_run(copy, truth)
    if row.get("lower_mm") is not None:
        row["knee_high_deg"], row["knee_low_deg"] = knee_extremes(copy, truth)
    (copy / "row.json").write_text(json.dumps(row, default=float))
    return row


def median_of(rows: list[dict], key: str) -> float:
    vals = [r[key] for r in rows if r.get(key) is not None]
    return float(np.median(vals)) if vals else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("work", type=Path, nargs="+", help="bench_suite.py --work folders with finished runs")
    ap.add_argument("--cutoffs", nargs="+", default=["6", "5", "4.5", "4"], help="Hz, or 'none'")
    ap.add_argument("--order", type=int, default=4, help="the Butterworth's order (smoothing.order)")
    ap.add_argument("--out", type=Path, default=Path("/tmp/gaitcap-smoothing"), help="the filtered copies and their scores")
    args = ap.parse_args()
    runs = [(w, p.name) for w in args.work for p in sorted((w / "runs").glob("*")) if (p / "eval.json").exists()]
    if not runs:
        sys.exit("no finished runs under " + ", ".join(str(w / "runs") for w in args.work))
    shared = (SHARED / "external_sessions").is_dir()
    external = {r["name"]: r["truth"] for r in external_sessions()} if shared else {}
    table, first = [], None
    for cutoff in args.cutoffs:
        cfg = smoothing(cutoff, args.order)
        rows = [scored(w, name, args.out, cutoff, cfg, truth_of(w, name, external)) for w, name in runs]
        lower = np.array([np.nan if r.get("lower_mm") is None else r["lower_mm"] for r in rows])
        first = lower if first is None else first
        missed = sum(r.get("events_missed") or 0 for r in rows)
        better, worse = int(np.sum(lower < first - 2)), int(np.sum(lower > first + 2))
        table.append(f"| {cutoff} | {np.nanmedian(lower):.2f} | {np.nanpercentile(lower, 90):.2f} | "
                     f"{np.nanmax(lower):.1f} | {np.nanmean(lower):.2f} | {better} / {worse} | "
                     f"{median_of(rows, 'knee_deg'):.2f} | {median_of(rows, 'event_ms'):.1f} | {missed} | "
                     f"{median_of(rows, 'stride_pct'):.2f} | {median_of(rows, 'knee_high_deg'):.2f} | "
                     f"{median_of(rows, 'knee_low_deg'):.2f} |")  # fmt: skip
    print(f"{len(runs)} runs of {', '.join(str(w) for w in args.work)}; lower-limb mm, knee deg, events ms\n")
    print(f"| cut-off Hz | median | 90th pct | worst | mean | better / worse > 2 mm than {args.cutoffs[0]} | "
          "knee median | event median | events missed | stride % median | knee largest flexion, off by | "
          "knee smallest, off by |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(table))


if __name__ == "__main__":
    main()
