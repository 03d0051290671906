"""The verdict and the calibrated uncertainty (gaitcap.quality) measured on a validation suite's runs.

Reads a work folder of ``scripts/bench_suite.py`` (``WORK/suite.json``, ``WORK/runs/<name>/``
trajectories.h5 and eval.json, the sessions' truths) and recomputes, from what each run recorded,
with the current tracking configuration (or ``--config``):

1. the verdict of every run against its lower-limb MPJPE, and the targets: every run above 60 mm
   (lost runs included) doubtful or failed, at least 80 % of the runs under 35 mm ok;
2. a leave-one-walk-out check of the verdict: each threshold chosen again from a grid of round
   values on the other walks (fewest misses, then fewest false alarms, then nearest the
   configured value), then applied to the held-out walk;
3. the per-point uncertainty before (the particles' spread, ``/spread``, or ``/uncertainty`` of a run
   written before the calibration) and after (the calibrated one): the fraction of lower-limb
   joint-frame errors within 1 and 2 reported uncertainties and the correlation of the per-run mean
   uncertainty with the per-run mean error, by point and pooled;
4. with ``--fit``: the uncertainty's coefficients fitted again (log |error| regressed on the terms
   of gaitcap.quality.calibrated_uncertainty, the intercept moved so that 95 % of the errors fall
   within 2 u), pooled and leaving each walk out in turn, with the held-out coverage and correlation.

Errors are those of the output points (``/points``: filtered, flagged frames NaN) on the frames
the tracker did not flag.

    python scripts/bench_uncertainty.py --work /tmp/gaitcap_suite
    python scripts/bench_uncertainty.py --work /tmp/gaitcap_suite --fit --json uncertainty.json
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from gaitcap.errors import GaitcapError  # noqa: E402
from gaitcap.evaluation.compare import align  # noqa: E402
from gaitcap.evaluation.report import read_truth_reference  # noqa: E402
from gaitcap.io.calibration_toml import read_calibration  # noqa: E402
from gaitcap.quality import RunSignals, assess, judge, point_residuals, run_signals  # noqa: E402
from gaitcap.tracking.config import TrackingConfig, UncertaintyCoefficients, load_tracking_config  # noqa: E402
from gaitcap.trajectory import LOWER_LIMB, Trajectory  # noqa: E402

GOOD_MM, BAD_MM = 35.0, 60.0
GROUPS = ("vicon", "opensim", "c3dorg", "external")
#: round values each verdict threshold is chosen from in the leave-one-walk-out check
GRID = {
    "crossed_margin_m": (0.0, 0.02, 0.05),
    "max_flagged_fraction": (0.3, 0.4, 0.5, 0.6, 0.7),
    "max_crossed_fraction": (0.1, 0.15, 0.2, 0.25, 0.3),
    "max_floor_offset_m": (0.05, 0.1, 0.15, 0.2),
    "segment_ratio": ((0.7, 1.4), (0.75, 1.33), (0.8, 1.25), (0.85, 1.18)),
    "min_exchanged_frames": (2, 3, 4, 5, 6),
    "exchanged_margin_m": (0.0, 0.03, 0.05, 0.1),
}
JOINTS = tuple(dict.fromkeys(p[:-2] for p in LOWER_LIMB))  # hip, knee, ankle
#: the points each joint's fitted scale goes to: the pelvis with the hips, the foot with the ankle
JOINT_PATTERNS = {"hip": "pelvis|hip_[lr]", "knee": "knee_[lr]", "ankle": "(ankle|heel|toe)_[lr]"}
TERMS = ("log_residual", "fit", "crossed_run", "floor", "crossed_frame")


@dataclass
class Run:
    name: str
    names: tuple[str, ...]  # the P points
    group: str
    lower_mm: float  # inf: lost
    signals: RunSignals
    verdict: str
    reasons: tuple[str, ...]
    notes: tuple[str, ...]
    before: np.ndarray  # (T, P) metres
    after: np.ndarray  # (T, P)
    error: np.ndarray  # (T, P) metres, NaN where not compared
    terms: np.ndarray  # (T, P, len(TERMS))
    raw: np.ndarray  # (T, P, 3) the tracker's points
    quality: np.ndarray  # (T,)
    height_m: float
    rate_hz: float
    swap_frames: int | None  # frames with the legs swapped against the truth (gaitcap eval), None: unknown
    _by_margin: dict = field(default_factory=dict)

    def signals_at(self, margin_m: float, exchanged_margin_m: float) -> RunSignals:
        """The signals with ankles counted as crossed beyond ``margin_m`` and out of the stride's rhythm
        beyond ``exchanged_margin_m`` (the image heights and view angles kept)."""
        key = (margin_m, exchanged_margin_m)
        if key not in self._by_margin:
            s = run_signals(self.raw, self.names, self.quality, self.height_m, None, margin_m, rate_hz=self.rate_hz,
                            exchanged_margin_m=exchanged_margin_m)  # fmt: skip
            self._by_margin[key] = replace(s, image_height_px=self.signals.image_height_px,
                                           view_angles_deg=self.signals.view_angles_deg)  # fmt: skip
        return self._by_margin[key]


def truth_points(traj: Trajectory, truth: Path) -> np.ndarray:
    """The truth's points (T, P, 3) on the frames and points of ``traj`` (NaN where it has none)."""
    ref = read_truth_reference(truth).trajectory
    whole = replace(traj, points=np.zeros_like(traj.points))  # every frame and point kept by align
    a = align(whole, ref)
    out = np.full(traj.points.shape, np.nan)
    frames = np.rint((a.times - traj.t0_s) * traj.rate_hz).astype(int)
    for k, name in enumerate(a.names):
        out[frames, traj.names.index(name)] = a.ref[:, k]
    return out


def find_truth(run: Path, session: Path) -> Path | None:
    ev = run / "eval.json"
    if ev.is_file():
        return Path(json.loads(ev.read_text())["reference"])
    for cand in (session / "truth.h5", session / "truth"):
        if cand.exists():
            return cand
    return None


def load_run(row: dict, run: Path, cfg: TrackingConfig) -> Run:
    with h5py.File(run / "trajectories.h5", "r") as f:
        names = tuple(str(n) for n in f["points"].attrs["names"])
        rate = float(f["points"].attrs["rate_hz"])
        points, raw = f["points"][()], f["points_unfiltered"][()]
        fit, quality = f["fit"][()], f["quality"][()]
        before = f["spread"][()] if "spread" in f else f["uncertainty"][()]
        height, session = float(f.attrs["height_m"]), Path(str(f.attrs["session"]))
    rig = read_calibration(session / "calibration.toml") if (session / "calibration.toml").is_file() else None
    judged = assess(raw, names, fit, quality, height, rate, cfg.verdict, cfg.uncertainty, rig)
    truth = find_truth(run, session)
    error = np.full(points.shape[:2], np.nan)
    if truth is not None:
        ref = truth_points(Trajectory(names, points, rate), truth)
        error = np.linalg.norm(points - ref, axis=2)
        error[quality != 0] = np.nan
    s = judged.signals
    res = np.maximum(point_residuals(raw, rate, cfg.uncertainty.cutoff_hz), cfg.uncertainty.min_residual_m)
    floor = abs(s.floor_m) if np.isfinite(s.floor_m) else 0.0
    T, P = res.shape
    per_frame = [1 - fit, np.full(T, s.crossed_fraction), np.full(T, floor), s.crossed.astype(float)]
    terms = np.stack([np.log(res), *(np.broadcast_to(v[:, None], (T, P)) for v in per_frame)], axis=2)
    mm = row.get("lower_mm")
    group = "external" if row.get("source") == "external" else str(row.get("walk"))
    return Run(row["name"], names, group, float(mm) if mm is not None else np.inf, s, judged.verdict.verdict,
               judged.verdict.reasons, judged.verdict.notes, before, judged.uncertainty, error, terms, raw, quality,
               height, rate, row.get("swap_frames"))  # fmt: skip


# ------------------------------------------------------------------------------------------- verdict
def verdict_targets(runs: list[Run], verdicts: list[str]) -> dict:
    bad = [(r, v) for r, v in zip(runs, verdicts, strict=True) if r.lower_mm > BAD_MM]
    good = [(r, v) for r, v in zip(runs, verdicts, strict=True) if r.lower_mm < GOOD_MM]
    return {"bad": len(bad), "bad_caught": sum(v != "ok" for _, v in bad),
            "missed": [r.name for r, v in bad if v == "ok"],
            "good": len(good), "good_ok": sum(v == "ok" for _, v in good),
            "false_alarms": [r.name for r, v in good if v != "ok"]}  # fmt: skip


def print_verdicts(runs: list[Run]) -> dict:
    print("\n## Verdict per run (lower-limb MPJPE; lost = every frame flagged)\n")
    print("| run | walk | lower mm | swap frames | out of rhythm | crossed | verdict | reasons |")
    print("|---|---|---|---|---|---|---|---|")
    for r in sorted(runs, key=lambda r: r.lower_mm):
        mm = "lost" if not np.isfinite(r.lower_mm) else f"{r.lower_mm:.1f}"
        swaps = "-" if r.swap_frames is None else r.swap_frames
        print(f"| {r.name} | {r.group} | {mm} | {swaps} | {r.signals.n_exchanged} | {r.signals.n_crossed} | "
              f"{r.verdict} | {'; '.join(r.reasons + tuple(f'(note) {n}' for n in r.notes))} |")  # fmt: skip
    t = verdict_targets(runs, [r.verdict for r in runs])
    print(f"\nruns above {BAD_MM:.0f} mm doubtful or failed: {t['bad_caught']} of {t['bad']} (missed: "
          f"{', '.join(t['missed']) or 'none'}); runs under {GOOD_MM:.0f} mm ok: {t['good_ok']} of {t['good']} "
          f"(false alarms: {', '.join(t['false_alarms']) or 'none'})")  # fmt: skip
    return t


def _judge_all(runs: list[Run], vcfg) -> list[str]:
    return [judge(r.signals_at(vcfg.crossed_margin_m, vcfg.exchanged_margin_m), vcfg).verdict for r in runs]


def _score(runs: list[Run], vcfg) -> tuple[int, int]:
    t = verdict_targets(runs, _judge_all(runs, vcfg))
    return t["bad"] - t["bad_caught"], t["good"] - t["good_ok"]


def _distance(values: dict, vcfg) -> float:
    """How far from the configured thresholds, in grid steps."""
    return sum(abs(GRID[k].index(v) - GRID[k].index(_nearest(k, getattr(vcfg, k)))) for k, v in values.items())


def _nearest(key: str, value) -> object:
    grid = GRID[key]
    if isinstance(value, tuple):
        return min(grid, key=lambda g: abs(g[0] - value[0]))
    return min(grid, key=lambda g: abs(g - value))


def leave_one_walk_out_verdict(runs: list[Run], cfg: TrackingConfig) -> list[dict]:
    print("\n## Verdict, leave one walk out (thresholds chosen again on the other walks)\n")
    print("| held out | chosen thresholds | above 60 mm caught | under 35 mm ok |\n|---|---|---|---|")
    out = []
    keys = list(GRID)
    for group in GROUPS:
        train, test = [r for r in runs if r.group != group], [r for r in runs if r.group == group]
        if not test:
            continue
        best = None
        for combo in itertools.product(*(GRID[k] for k in keys)):
            values = dict(zip(keys, combo, strict=True))
            vcfg = cfg.verdict.model_copy(update=values)
            key = (*_score(train, vcfg), _distance(values, cfg.verdict))
            if best is None or key < best[0]:
                best = (key, values, vcfg)
        _, values, vcfg = best
        t = verdict_targets(test, _judge_all(test, vcfg))
        chosen = ", ".join(f"{k} {v}" for k, v in values.items())
        print(f"| {group} | {chosen} | {t['bad_caught']} of {t['bad']} | {t['good_ok']} of {t['good']} |")
        out.append({"held_out": group, "thresholds": values, **t})
    return out


# --------------------------------------------------------------------------------------- uncertainty
def coverage_table(runs: list[Run], which: str) -> dict:
    """Per lower-limb point and pooled: within 1 u, within 2 u, correlation of the per-run means."""
    table = {}
    for name in (*LOWER_LIMB, "all"):
        pts = [LOWER_LIMB.index(name)] if name != "all" else list(range(len(LOWER_LIMB)))
        errs, us, run_e, run_u = [], [], [], []
        for r in runs:
            idx = [_point_index(r, LOWER_LIMB[p]) for p in pts]
            e, u = r.error[:, idx].ravel(), getattr(r, which)[:, idx].ravel()
            ok = np.isfinite(e) & np.isfinite(u)
            if ok.sum() == 0:
                continue
            errs.append(e[ok]), us.append(u[ok]), run_e.append(e[ok].mean()), run_u.append(u[ok].mean())
        e, u = np.concatenate(errs), np.concatenate(us)
        table[name] = {"within_1": float(np.mean(e <= u)), "within_2": float(np.mean(e <= 2 * u)),
                       "run_corr": float(np.corrcoef(run_e, run_u)[0, 1]), "median_u_mm": float(1000 * np.median(u)),
                       "n": int(len(e)), "runs": len(run_e)}  # fmt: skip
    return table


def _point_index(run: Run, point: str) -> int:
    return run.names.index(point)


def print_coverage(before: dict, after: dict, title: str) -> None:
    print(f"\n## {title}\n")
    print("| point | within 1 u before | after | within 2 u before | after | run corr before | after "
          "| median u mm before | after |")
    print("|---|---|---|---|---|---|---|---|---|")
    for k in before:
        b, a = before[k], after[k]
        cells = [f"{x[key]:.{d}f}" for key, d in (("within_1", 3), ("within_2", 3), ("run_corr", 2), ("median_u_mm", 1))
                 for x in (b, a)]  # fmt: skip
        print(f"| {k} | " + " | ".join(cells) + " |")


def _samples(runs: list[Run]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Terms (N, len(TERMS)), log error (N,) and joint name without side (N,) of every compared
    lower-limb joint-frame."""
    X, y, joint = [], [], []
    for r in runs:
        idx = [_point_index(r, p) for p in LOWER_LIMB]
        e, t = r.error[:, idx], r.terms[:, idx]
        ok = np.isfinite(e) & (e > 0) & np.all(np.isfinite(t), axis=2)
        X.append(t[ok]), y.append(np.log(e[ok]))
        joint.append(np.broadcast_to(np.array([p[:-2] for p in LOWER_LIMB]), e.shape)[ok])
    return np.vstack(X), np.concatenate(y), np.concatenate(joint)


def fit_coefficients(runs: list[Run]) -> tuple[UncertaintyCoefficients, dict[str, float]]:
    """Least squares of log |error| on the terms; the intercept then moved so that 95 % of the
    training errors fall within 2 u, and each joint's scale (``point_scale``, both sides alike)
    so that 95 % of its own errors do."""
    X, y, joint = _samples(runs)
    A = np.c_[np.ones(len(X)), X]
    w = np.linalg.lstsq(A, y, rcond=None)[0]
    w[1:] = np.maximum(w[1:], 0.0)  # the schema's sign constraint (more jitter, worse fit: never less uncertain)
    ratio = np.exp(y - A @ w)
    pooled = np.quantile(ratio, 0.95)
    intercept = w[0] + np.log(pooled / 2)
    scales = {JOINT_PATTERNS[j]: round(float(np.quantile(ratio[joint == j], 0.95) / pooled), 2) for j in JOINTS}
    coeffs = UncertaintyCoefficients(intercept=round(float(intercept), 3),
                                     **{k: round(float(v), 3) for k, v in zip(TERMS, w[1:], strict=True)})  # fmt: skip
    return coeffs, scales


def apply(coeffs: UncertaintyCoefficients, scales: dict[str, float], run: Run, cfg: TrackingConfig) -> np.ndarray:
    c = np.array([getattr(coeffs, k) for k in TERMS])
    s = cfg.uncertainty.model_copy(update={"point_scale": scales}).scales(run.names)
    return np.maximum(np.exp(coeffs.intercept + run.terms @ c) * s, cfg.uncertainty.min_m)


def refit(runs: list[Run], cfg: TrackingConfig) -> dict:
    measured = [r for r in runs if np.isfinite(r.error).any()]
    pooled, scales = fit_coefficients(measured)
    print("\n## Coefficients fitted on every run (for tracking.yaml's uncertainty)\n")
    print("  coefficients: " + ", ".join(f"{k}: {v}" for k, v in pooled.model_dump().items()))
    print("  point_scale: " + ", ".join(f'"{k}": {v}' for k, v in scales.items()))
    print("\n## Held-out walks: coefficients fitted on the others, measured on it\n")
    held = [replace(r, after=np.full_like(r.after, np.nan)) for r in measured]
    rows = []
    print("| held out | runs | within 1 u | within 2 u | run corr |\n|---|---|---|---|---|")
    for group in GROUPS:
        test = [r for r in held if r.group == group]
        if not test:
            continue
        coeffs, scales_out = fit_coefficients([r for r in measured if r.group != group])
        for r in test:
            r.after = apply(coeffs, scales_out, r, cfg)
        t = coverage_table(test, "after")["all"]
        rows.append({"held_out": group, **t})
        print(f"| {group} | {t['runs']} | {t['within_1']:.3f} | {t['within_2']:.3f} | {t['run_corr']:.2f} |")
    pooled_table = coverage_table(held, "after")
    print_coverage(coverage_table(measured, "before"), pooled_table,
                   "Uncertainty, every run held out with its walk (before: particle spread; after: held-out fit)")
    return {"coefficients": pooled.model_dump(), "point_scale": scales, "held_out": rows,
            "held_out_by_point": pooled_table}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", type=Path, default=Path("/tmp/gaitcap_suite"), help="bench_suite.py's work folder")
    ap.add_argument("--config", type=Path, default=None, help="tracking.yaml to judge with (default: the shipped one)")
    ap.add_argument("--fit", action="store_true",
                    help="fit the uncertainty's coefficients again (pooled, and leaving each walk out)")
    ap.add_argument("--json", type=Path, default=None, help="also write the tables here")
    args = ap.parse_args()
    if not (args.work / "suite.json").is_file():
        sys.exit(f"error: {args.work}: not a scripts/bench_suite.py work folder (no suite.json: run bench_suite.py "
                 f"--work {args.work} first)")  # fmt: skip
    try:
        cfg = load_tracking_config(args.config)
    except GaitcapError as e:
        sys.exit(f"error: --config: {e}")
    rows = json.loads((args.work / "suite.json").read_text())
    runs = []
    for row in rows:
        run = args.work / "runs" / row["name"]
        if not (run / "trajectories.h5").is_file():
            print(f"{row['name']}: no trajectories.h5, left out", file=sys.stderr)
            continue
        runs.append(load_run(row, run, cfg))
    if not runs:
        sys.exit(f"error: {args.work}: no finished run under {args.work / 'runs'} (its suite.json lists "
                 f"{len(rows)} sessions)")  # fmt: skip
    doc = {"verdict": print_verdicts(runs), "verdict_held_out": leave_one_walk_out_verdict(runs, cfg)}
    measured = [r for r in runs if np.isfinite(r.error).any()]
    before, after = coverage_table(measured, "before"), coverage_table(measured, "after")
    print_coverage(before, after, f"Uncertainty on {len(measured)} runs (before: particle spread; after: calibrated, "
                                  "the configured coefficients)")  # fmt: skip
    doc.update(uncertainty_before=before, uncertainty_after=after,
               runs=[{"name": r.name, "walk": r.group, "lower_mm": r.lower_mm if np.isfinite(r.lower_mm) else None,
                      "swap_frames": r.swap_frames, "out_of_rhythm": r.signals.n_exchanged,
                      "crossed": r.signals.n_crossed, "verdict": r.verdict, "reasons": list(r.reasons),
                      "notes": list(r.notes)} for r in runs])  # fmt: skip
    if args.fit:
        doc["fit"] = refit(runs, cfg)
    if args.json:
        args.json.write_text(json.dumps(doc, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
