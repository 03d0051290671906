"""Tracking benchmark: speed and accuracy of each tracker and particle budget on synthetic sessions.

    PYTHONPATH=src python scripts/bench_track.py [--data ../shared/data] [--work /tmp/gaitcap-bench]
        [--trackers factored-ipf ipf condensation] [--budgets factored-ipf=150/360,250/600 ipf=1500,6000]
        [--max-frames N] [--seed 0] [--tracker-seeds 0 1 2 3 4 5]

Renders (once, cached in --work) a synthetic session from each real walk of ../shared/data/walking
(the Plug-in-Gait C3D and the OpenSim TRC), then tracks every session with every (tracker, budget)
of the grid, each budget written into a temporary copy of the shipped configs/tracking.yaml.
Prints one markdown table, a row per tracker x budget x session:

- tracking ms/frame: the per-frame loop alone (FrameTiming.tracking_s / the frames it searched,
  not those taken as the initialisation's leg check tracked them); "first frame s": the loop's time
  on the first frame, which holds the initialisation's search when the loop finds the first pose
  (with the shape calibration on, the first pose is found before the loop and the first frames
  are taken as already tracked: about 0); end-to-end ms/frame: wall time of run_track / frames
  (silhouettes, observation, tracking, outputs);
- lower-limb MPJPE (hips, knees, ankles) and heel/toe error in mm, on the frames not flagged;
- knee flexion RMSE in degrees (gaitcap.gait.angles on both, left and right pooled) and its bias,
  the mean of estimate - truth (RMSE^2 = bias^2 + the difference's variance: a systematic error,
  e.g. knees bent in stance because the calibrated legs and hips disagree, shows here);
- % frames flagged (NaN in /points), left/right swap frames (gaitcap.evaluation.metrics.swap_mask)
  and the longest run of them.

With ``--tracker-seeds``, every row is tracked once per tracker seed (the rendering keeps
``--seed``) and its cells give the mean and, in brackets, the range over the seeds (swap columns:
the largest); then, per factored-ipf budget, how many runs meet the issue's accuracy targets
(lower-limb MPJPE <= 35 mm, knee RMSE <= 5 degrees, no swap longer than 2 frames). One seed's
figures move a lot: knee RMSE by +-1.5 degrees between seeds of one configuration.

Then the ratio rows: factored-ipf speed against ipf at equal-or-better accuracy (lower-limb
MPJPE), and condensation accuracy against factored-ipf at about the same tracking ms/frame.
A budget is ``particles/root_particles`` for factored-ipf and ``particles`` for the others,
optionally followed by ``@T``: the compiled kernels' threads (an integer, or ``all``: one per core;
default: the shipped config's ``threads``), e.g. ``ipf=6000,6000@all``.
"""

from __future__ import annotations

import argparse
import sys
import logging
import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from gaitcap.errors import GaitcapError
from gaitcap.config import default_config_path, read_yaml
from gaitcap.evaluation.compare import align
from gaitcap.evaluation.metrics import angle_bias_deg, angle_rmse_deg, group_errors, point_distances_mm, runs, swap_mask
from gaitcap.evaluation.report import read_tracked, read_truth_trajectory
from gaitcap.gait.angles import joint_angles
from gaitcap.gait.events import estimate_walking_direction
from gaitcap.pipeline import FrameTiming, run_track
from gaitcap.synth.session import TRUTH_FILE, SynthOptions, synthesize
from gaitcap.trajectory import FOOT, LOWER_LIMB

REPO = Path(__file__).resolve().parents[1]
TRIALS = {
    "vicon_pig_lowerbody": "walking/vicon_pig_lowerbody/walk.c3d",
    "opensim_gait2354": "walking/opensim_gait2354_subject01/subject01_walk1.trc",
}
#: factored-ipf: the shipped budget, and a small one for the speed ratio (the tracking time barely falls below
#: about 30 ms per frame, whatever the budget: the per-node work outside the likelihood kernel)
DEFAULT_BUDGETS = {"factored-ipf": ["15/40", "100/240"], "ipf": ["1500", "6000", "6000@all"],
                   "condensation": ["1500", "6000", "6000@all"]}
#: "about the same ms/frame" for the condensation comparison: within this factor
SAME_SPEED_FACTOR = 1.5
#: the accuracy targets of the tracking issue: lower-limb MPJPE mm, knee RMSE deg, longest swap frames
TARGETS = (35.0, 5.0, 2)


@dataclass
class Row:
    tracker: str
    budget: str
    session: str
    frames: int
    tracking_ms: float
    first_s: float
    total_ms: float
    lower_mm: float
    foot_mm: float
    knee_rmse_deg: float
    knee_bias_deg: float
    flagged_pct: float
    swaps: int
    longest_swap: int
    seed: int = 0


@dataclass
class Summary:
    """A row's runs over the tracker seeds: means (the attributes the ratio lines read) and ranges."""

    runs: list[Row]

    @property
    def tracker(self) -> str:
        return self.runs[0].tracker

    @property
    def budget(self) -> str:
        return self.runs[0].budget

    @property
    def session(self) -> str:
        return self.runs[0].session

    @property
    def tracking_ms(self) -> float:
        return float(np.mean([r.tracking_ms for r in self.runs]))

    @property
    def lower_mm(self) -> float:
        return float(np.mean([r.lower_mm for r in self.runs]))

    @property
    def knee_rmse_deg(self) -> float:
        return float(np.mean([r.knee_rmse_deg for r in self.runs]))

    def cell(self, name: str, digits: int = 1) -> str:
        values = np.array([getattr(r, name) for r in self.runs], dtype=float)
        if len(values) == 1:
            return _f(values[0], digits)
        return f"{_f(values.mean(), digits)} ({_f(values.min(), digits)}-{_f(values.max(), digits)})"

    def meeting(self) -> str:
        lower, knee, swap = TARGETS
        n = len(self.runs)
        ok = [sum(r.lower_mm <= lower for r in self.runs), sum(r.knee_rmse_deg <= knee for r in self.runs),
              sum(r.longest_swap <= swap for r in self.runs)]  # fmt: skip
        all_ok = sum(r.lower_mm <= lower and r.knee_rmse_deg <= knee and r.longest_swap <= swap for r in self.runs)
        return (f"lower-limb MPJPE <= {lower:g} mm in {ok[0]}/{n} runs, knee RMSE <= {knee:g} deg in {ok[1]}/{n}, "
                f"no swap longer than {swap} frames in {ok[2]}/{n}; all three in {all_ok}/{n}")


def session_for(trial: str, motion: Path, work: Path, seed: int) -> Path:
    """The synthetic session of ``motion`` under ``work`` (rendered unless already there)."""
    root = work / f"{trial}-seed{seed}"
    if (root / TRUTH_FILE).is_file():
        return root
    t0 = time.perf_counter()
    res = synthesize(motion, root, SynthOptions(seed=seed), force=True, progress=False)
    print(f"<!-- rendered {trial}: {res.n_frames} frames in {time.perf_counter() - t0:.0f} s -> {root} -->", flush=True)
    return root


def tracking_config(tracker: str, budget: str, seed: int, folder: Path) -> Path:
    """The shipped tracking.yaml with ``tracker``, its particle budget and the seed changed."""
    cfg = read_yaml(default_config_path("tracking.yaml"))
    cfg["tracker"] = tracker
    cfg["seed"] = seed
    budget, _, threads = budget.partition("@")
    if threads:
        cfg["threads"] = None if threads == "all" else int(threads)
    if tracker == "factored-ipf":
        particles, _, root = budget.partition("/")
        cfg["factored_ipf"]["particles"] = int(particles)
        cfg["factored_ipf"]["root_particles"] = int(root or particles)
    else:
        cfg[tracker.replace("-", "_")]["particles"] = int(budget)
    path = folder / f"tracking-{tracker}-{budget.replace('/', '_')}-{threads or 'cfg'}.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


def measure(out: Path, session: Path) -> dict[str, float]:
    """Accuracy of the run in ``out`` against the session's truth (see the module docstring)."""
    truth = read_truth_trajectory(session)
    a = align(read_tracked(out), truth)
    dist = point_distances_mm(a.est[a.valid], a.ref[a.valid])
    lower = group_errors(dist, a.names, LOWER_LIMB) or {}
    foot = group_errors(dist, a.names, FOOT) or {}
    swapped = swap_mask(a.est, a.ref, list(a.names)) & a.valid
    direction = estimate_walking_direction(truth)
    est_angles, _ = joint_angles(a.trajectory("est", mask_invalid=True), direction)
    ref_angles, _ = joint_angles(a.trajectory("ref"), direction)
    est_knee = np.concatenate([est_angles["knee_flexion_l"], est_angles["knee_flexion_r"]])
    ref_knee = np.concatenate([ref_angles["knee_flexion_l"], ref_angles["knee_flexion_r"]])
    knee, _ = angle_rmse_deg(est_knee, ref_knee)
    return {
        "lower_mm": lower.get("mpjpe_mm", math.nan),
        "foot_mm": foot.get("mpjpe_mm", math.nan),
        "knee_rmse_deg": knee,
        "knee_bias_deg": angle_bias_deg(est_knee, ref_knee)[0],
        "flagged_pct": 100.0 * float(a.flagged.mean()),
        "swaps": int(swapped.sum()),
        "longest_swap": max((b - a_ for a_, b in runs(swapped)), default=0),
    }


def run_one(session: Path, trial: str, tracker: str, budget: str, seed: int, args: argparse.Namespace,
            tmp: Path) -> Row:  # fmt: skip
    config = tracking_config(tracker, budget, seed, tmp)
    out = tmp / f"out-{trial}-{tracker}-{budget.replace('/', '_').replace('@', '_')}-{seed}"
    last = FrameTiming()
    first: list[float] = []

    def on_frame(count: int, timing: FrameTiming) -> None:
        last.tracking_s, last.total_s, last.searched = timing.tracking_s, timing.total_s, timing.searched
        if count == 1:
            first.append(timing.tracking_s)

    t0 = time.perf_counter()
    summary = run_track(session, out, config=config, force=True, progress=False, max_frames=args.max_frames,
                        on_frame=on_frame)  # fmt: skip
    wall = time.perf_counter() - t0
    n = max(summary.n_frames, 1)
    searched = max(last.searched, 1)  # the frames the initialisation tracked already are taken at no cost
    return Row(tracker, budget, trial, summary.n_frames, 1000 * last.tracking_s / searched, first[0] if first else math.nan,
               1000 * wall / n,
               **measure(out, session), seed=seed)  # fmt: skip


def _f(v: float, digits: int = 1) -> str:
    return "-" if not math.isfinite(v) else f"{v:.{digits}f}"


def summarise(rows: list[Row]) -> list[Summary]:
    """One :class:`Summary` per (tracker, budget, session), in the order run."""
    groups: dict[tuple[str, str, str], list[Row]] = {}
    for r in rows:
        groups.setdefault((r.tracker, r.budget, r.session), []).append(r)
    return [Summary(g) for g in groups.values()]


def print_table(rows: list[Summary]) -> None:
    print("| tracker | budget | session | seeds | frames | tracking ms/frame | first frame s | end-to-end ms/frame "
          "| lower-limb MPJPE mm | heel/toe mm | knee flexion RMSE deg | knee bias deg | % flagged | swap frames | longest swap |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        swaps = max(x.swaps for x in r.runs)
        longest = max(x.longest_swap for x in r.runs)
        print(f"| {r.tracker} | {r.budget} | {r.session} | {len(r.runs)} | {r.runs[0].frames} | {r.cell('tracking_ms', 0)} "
              f"| {r.cell('first_s')} | {r.cell('total_ms', 0)} | {r.cell('lower_mm')} | {r.cell('foot_mm')} "
              f"| {r.cell('knee_rmse_deg')} | {r.cell('knee_bias_deg')} | {r.cell('flagged_pct')} | {swaps} | {longest} |")


def ratio_lines(rows: list[Summary]) -> list[str]:
    """The comparisons the issue asks for, per session (on the means over the tracker seeds)."""
    lines = []
    for session in dict.fromkeys(r.session for r in rows):
        mine = [r for r in rows if r.session == session]
        fact = [r for r in mine if r.tracker == "factored-ipf" and math.isfinite(r.lower_mm)]
        for ipf in (r for r in mine if r.tracker == "ipf"):
            better = [f for f in fact if f.lower_mm <= ipf.lower_mm]
            if not better:
                lines.append(f"- {session}: no factored-ipf budget is as accurate as ipf {ipf.budget} "
                             f"({_f(ipf.lower_mm)} mm)")  # fmt: skip
                continue
            f = min(better, key=lambda r: r.tracking_ms)
            lines.append(f"- {session}: speed factored-ipf / ipf = {ipf.tracking_ms / f.tracking_ms:.2f} at equal-or-better "
                         f"lower-limb MPJPE: factored-ipf {f.budget} ({_f(f.lower_mm)} mm, {_f(f.tracking_ms, 0)} ms/frame) "
                         f"vs ipf {ipf.budget} ({_f(ipf.lower_mm)} mm, {_f(ipf.tracking_ms, 0)} ms/frame)")  # fmt: skip
        for cond in (r for r in mine if r.tracker == "condensation"):
            near = [f for f in fact if 1 / SAME_SPEED_FACTOR <= cond.tracking_ms / f.tracking_ms <= SAME_SPEED_FACTOR]
            if not near:
                lines.append(f"- {session}: no factored-ipf budget within {SAME_SPEED_FACTOR}x of condensation "
                             f"{cond.budget}'s {_f(cond.tracking_ms, 0)} ms/frame")  # fmt: skip
                continue
            f = min(near, key=lambda r: abs(math.log(cond.tracking_ms / r.tracking_ms)))
            lines.append(f"- {session}: at about the same speed (condensation {cond.budget} {_f(cond.tracking_ms, 0)} vs "
                         f"factored-ipf {f.budget} {_f(f.tracking_ms, 0)} ms/frame) condensation's lower-limb MPJPE is "
                         f"{_f(cond.lower_mm)} mm vs {_f(f.lower_mm)} mm ({cond.lower_mm / f.lower_mm:.2f}x), knee RMSE "
                         f"{_f(cond.knee_rmse_deg)} vs {_f(f.knee_rmse_deg)} deg")  # fmt: skip
    for r in rows:
        if r.tracker == "factored-ipf":
            lines.append(f"- {r.session}: factored-ipf {r.budget}: {r.meeting()}")
    return lines


def parse_budgets(items: list[str] | None) -> dict[str, list[str]]:
    budgets = {k: list(v) for k, v in DEFAULT_BUDGETS.items()}
    for item in items or []:
        tracker, sep, values = item.partition("=")
        if not sep or tracker not in DEFAULT_BUDGETS:
            raise SystemExit(f"--budgets: expected TRACKER=B1,B2 with TRACKER in {', '.join(DEFAULT_BUDGETS)}, got {item!r}")
        budgets[tracker] = [v for v in values.split(",") if v]
    return budgets


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    ap.add_argument("--work", type=Path, default=Path("/tmp/gaitcap-bench"), help="cache of the rendered sessions")
    ap.add_argument("--trackers", nargs="+", choices=list(DEFAULT_BUDGETS), default=list(DEFAULT_BUDGETS))
    ap.add_argument("--budgets", nargs="+", default=None,
                    help="per tracker, e.g. factored-ipf=150/360,250/600 ipf=1500,6000 condensation=1500")
    ap.add_argument("--max-frames", type=int, default=None, help="track only the first N frames (default all)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the rendering and of the trackers")
    ap.add_argument("--tracker-seeds", type=int, nargs="+", default=None,
                    help="track every row once per seed (default: --seed) and give mean and range")
    args = ap.parse_args()
    if not args.data.is_dir():
        ap.error(f"--data {args.data}: no such folder (the shared data; by default ../shared/data beside the checkout)")
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    budgets = parse_budgets(args.budgets)
    sessions = {name: session_for(name, args.data / rel, args.work, args.seed) for name, rel in TRIALS.items()}
    rows: list[Row] = []
    with tempfile.TemporaryDirectory(prefix="bench-track-", dir=args.work) as tmp:
        for tracker in args.trackers:
            for budget in budgets[tracker]:
                for trial, session in sessions.items():
                    for seed in args.tracker_seeds or [args.seed]:
                        rows.append(run_one(session, trial, tracker, budget, seed, args, Path(tmp)))
                        r = rows[-1]
                        print(f"<!-- {tracker} {budget} {trial} seed {seed}: {r.frames} frames, {r.tracking_ms:.0f} "
                              f"ms/frame, {r.lower_mm:.1f} mm, knee {r.knee_rmse_deg:.1f} deg, longest swap "
                              f"{r.longest_swap} -->", flush=True)  # fmt: skip
    summaries = summarise(rows)
    print()
    print_table(summaries)
    print()
    print("\n".join(ratio_lines(summaries)))


if __name__ == "__main__":
    try:
        main()
    except GaitcapError as e:  # a file of the data missing or unreadable
        sys.exit(f"error: {e}")
