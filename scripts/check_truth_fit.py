"""Does the silhouette objective prefer the truth? Frame by frame, a run's pose against the true pose.

    PYTHONPATH=src python scripts/check_truth_fit.py SESSION RUN [--config F] [--min-error-mm 60]
        [--tolerance 0.005] [--frames 10 20 ...]

SESSION is a synthetic session (its ``truth.h5``), RUN a ``gaitcap track --save-masks`` output of
it (``trajectories.h5`` with the tracked body's proportions, ``silhouettes.h5`` with the masks the
tracker saw). For each frame:

- the true pose in the run's own body model: the truth's joint centres fitted by
  ``gaitcap.synth.fit.fit_poses`` (bounded least squares, joint limits as bounds);
- that pose refined by one step of the configured tracker against the frame's silhouettes (the
  truth's joint centres and the run's body differ in shape: the refinement lets the pose settle
  into the nearest optimum of the objective);
- the fit (1 - xor/|S| averaged over the cameras, ``SilhouetteLikelihood.fit_of``) of the tracked
  pose, of the true pose and of the refined true pose, and the lower-limb error (hips, knees,
  ankles; mm) of the tracked and of the refined pose.

A frame where the tracked pose is far from the truth and yet fits better than the refined true
pose (by more than ``--tolerance``) is a failure of the objective: no search can fix it. One
where the refined true pose fits better is a failure of the search. The table lists the frames
whose tracked lower-limb error exceeds ``--min-error-mm`` (or ``--frames``), then counts both
kinds over them. With soft silhouettes (``tracking.soft_silhouettes``) the saved masks are the 0/1
ones, not the confidences the tracker saw.

    PYTHONPATH=src python scripts/check_truth_fit.py SESSION RUN --scan thigh_length
        [--factors 0.88 0.94 1 1.06 1.12] [--start truth|tracked] [--frames 0 3 6 9 12]

``--scan PARAMETER`` asks the same of the body instead of the pose: the run's body with one shape
parameter of ``shape.parameters`` moved by each factor (on top of the run's calibration), the truth's
joint centres fitted in it (``--start truth``), or the run's tracked poses moved vertically so that the
lowest point stays where it was (``--start tracked``: what the shape calibration starts from), refined
by one step as above; per factor, the mean fit over ``--frames`` (default: every third frame of the
first 13, the calibration window) and the refined poses' lower-limb error. A factor that fits best
from the truth but not from the tracked poses is a failure of the calibration's search; a flat fit
from the truth, one of the objective: the silhouettes do not tell that proportion.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from gaitcap.body.model import BodyModel
from gaitcap.errors import GaitcapError, InputError
from gaitcap.evaluation.report import read_tracked, read_truth_trajectory
from gaitcap.io.track_h5 import TrackRecord
from gaitcap.pipeline import kernel_threads
from gaitcap.report.fit import load_fit_record
from gaitcap.report.sheet import tracked_model
from gaitcap.session import Session
from gaitcap.synth.fit import fit_poses
from gaitcap.tracking.config import TrackingConfig, load_tracking_config
from gaitcap.tracking.factored_ipf import FactoredIPF
from gaitcap.tracking.likelihood import SilhouetteLikelihood
from gaitcap.tracking.observation import Observation, TrackingView, observe, tracking_views
from gaitcap.tracking.shape import planted_poses, scaled_model
from gaitcap.trajectory import LOWER_LIMB, Trajectory


def lower_error_mm(model, q: np.ndarray, truth_lower: np.ndarray) -> float:
    """Mean distance (mm) of pose q's hips, knees and ankles from the truth's (6, 3) metres."""
    pts = model.forward(q[None])[0][[model.point_index(n) for n in LOWER_LIMB]]
    return float(1000.0 * np.linalg.norm(pts - truth_lower, axis=1).mean())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("session", type=Path)
    ap.add_argument("run", type=Path)
    ap.add_argument("--config", type=Path, default=None, help="the tracking configuration of the run")
    ap.add_argument("--min-error-mm", type=float, default=60.0)
    ap.add_argument("--tolerance", type=float, default=0.005, help="fit difference counted as a preference")
    ap.add_argument("--frames", type=int, nargs="*", default=None)
    ap.add_argument("--scan", metavar="PARAMETER", default=None, help="a shape parameter to scan (tracking.yaml)")
    ap.add_argument("--factors", type=float, nargs="+", default=[0.88, 0.94, 1.0, 1.06, 1.12])
    ap.add_argument("--start", choices=("truth", "tracked"), default="truth", help="--scan: the poses refined")
    args = ap.parse_args(argv)

    try:
        return check(args)
    except GaitcapError as e:
        sys.exit(f"error: {e}")


@dataclass
class Inputs:
    """What both checks read: the session, the run's body and record, its configuration and views,
    the truth at the run's rate, and the truth frame of each run frame (-1: none)."""

    session: Session
    model: BodyModel
    record: TrackRecord  # poses (T, D), n_frames
    cfg: TrackingConfig
    views: list[TrackingView]
    truth: Trajectory
    truth_frame: np.ndarray  # (T,) int

    def scorable(self, t: int) -> bool:
        """Whether run frame t has a tracked pose and a truth frame."""
        return 0 <= t < self.record.n_frames and self.truth_frame[t] >= 0 and bool(np.all(np.isfinite(self.record.poses[t])))


def read_inputs(args: argparse.Namespace) -> Inputs:
    for path in (args.session / "truth.h5", args.run / "trajectories.h5", args.run / "silhouettes.h5"):
        if not path.is_file():
            raise InputError(f"{path}: file not found" + (" (track with --save-masks)" if path.name == "silhouettes.h5" else ""))
    session = Session.open(args.session)
    fit = load_fit_record(args.run / "trajectories.h5")
    if fit is None:
        raise InputError(f"{args.run / 'trajectories.h5'}: not a tracking output")
    model, why = tracked_model(fit)  # the body the run tracked, as report.html draws it
    if model is None:
        raise InputError(f"{args.run}: {why}")
    rec = fit.record
    cfg = load_tracking_config(args.config, model=model)
    truth = read_truth_trajectory(args.session / "truth.h5")
    if abs(truth.rate_hz - rec.rate_hz) > 1e-6:
        truth = truth.resample(rec.rate_hz)
    times = read_tracked(args.run).times()  # the run's time axis (its own t0)
    frames = np.array([truth.frame_of(float(t)) for t in times[: rec.n_frames]])
    frames[(frames < 0) | (frames >= truth.n_frames)] = -1
    return Inputs(session, model, rec, cfg, tracking_views(session.rig, cfg.scale), truth, frames)


def observations(inputs: Inputs, run: Path, frames: list[int]) -> dict[int, Observation]:
    """The run's saved masks of ``frames`` as the tracker sees them."""
    with h5py.File(run / "silhouettes.h5", "r") as masks:
        return {t: observe(inputs.views, [masks["masks/" + cam.name][t] for cam in inputs.session.rig.cameras])
                for t in frames}  # fmt: skip


def refine(tracker: FactoredIPF, obs: Observation, q: np.ndarray, seed: int, t: int) -> np.ndarray:
    """Pose q (D,) after one tracker step against ``obs``, frame t's own random stream."""
    tracker.rng = np.random.default_rng([seed, t])
    tracker.start(q, fresh=False)
    tracker.step(obs)
    return tracker.q.copy()


def tracker_for(inputs: Inputs, model: BodyModel) -> FactoredIPF:
    return FactoredIPF(model, SilhouetteLikelihood(inputs.views, inputs.cfg.beta), inputs.cfg,
                       np.random.default_rng(inputs.cfg.seed), uncertainty=False)  # fmt: skip


def check(args: argparse.Namespace) -> int:
    if args.scan is not None:
        return scan(args)
    inputs = read_inputs(args)
    model, rec, cfg, truth = inputs.model, inputs.record, inputs.cfg, inputs.truth
    tracker = tracker_for(inputs, model)
    true_poses, _ = fit_poses(model, truth)
    truth_lower = truth.subset(list(LOWER_LIMB)).points

    picked = []
    for t in range(rec.n_frames):
        if not inputs.scorable(t):
            continue
        err = lower_error_mm(model, rec.poses[t], truth_lower[inputs.truth_frame[t]])
        if (err >= args.min_error_mm) if args.frames is None else (t in args.frames):
            picked.append((t, err))
    obs = observations(inputs, args.run, [t for t, _ in picked])
    rows = []
    with kernel_threads(cfg.threads):  # as in a run
        for t, err in picked:
            j = inputs.truth_frame[t]
            refined = refine(tracker, obs[t], true_poses[j], cfg.seed, t)  # each frame's result its own
            fits = [tracker.full_fit(obs[t], q)[1] for q in (rec.poses[t], true_poses[j], refined)]
            rows.append((t, err, lower_error_mm(model, refined, truth_lower[j]), *fits))

    print(f"{args.run}: {len(rows)} frames (tracked lower-limb error >= {args.min_error_mm:g} mm"
          f"{'' if args.frames is None else ', or as given'})\n")  # fmt: skip
    print("| frame | tracked mm | true refined mm | fit tracked | fit true | fit true refined | prefers |")
    print("|---|---|---|---|---|---|---|")
    kinds = {"tracked (objective)": 0, "truth (search)": 0, "tie": 0}
    for t, err, err_r, f_trk, f_true, f_ref in rows:
        kind = ("tracked (objective)" if f_trk > f_ref + args.tolerance else
                "truth (search)" if f_ref > f_trk + args.tolerance else "tie")  # fmt: skip
        kinds[kind] += 1
        print(f"| {t} | {err:.0f} | {err_r:.0f} | {f_trk:.4f} | {f_true:.4f} | {f_ref:.4f} | {kind} |")
    print("\n" + ", ".join(f"{k}: {v}" for k, v in kinds.items()))
    return 0


def scan(args: argparse.Namespace) -> int:
    """The ``--scan`` table (module docstring)."""
    inputs = read_inputs(args)
    cfg, rec = inputs.cfg, inputs.record
    if args.scan not in cfg.shape.parameters:
        raise InputError(f"--scan {args.scan}: not in shape.parameters ({', '.join(cfg.shape.parameters)})")
    frames = args.frames if args.frames is not None else list(range(0, min(cfg.shape.frames, rec.n_frames), 3))
    frames = [t for t in frames if inputs.scorable(t)]
    if not frames:
        raise InputError(f"{args.run}: none of the frames has a tracked pose and a truth frame")
    obs = observations(inputs, args.run, frames)
    truth_lower = inputs.truth.subset(list(LOWER_LIMB)).points
    print(f"{args.run}: {args.scan} x factor on top of the run's body, poses from the {args.start}, "
          f"frames {' '.join(map(str, frames))}\n")  # fmt: skip
    print("| factor | fit before refining | fit refined | refined lower-limb mm |")
    print("|---|---|---|---|")
    for factor in args.factors:
        model = scaled_model(inputs.model, cfg.shape.parameters, {args.scan: factor})
        tracker = tracker_for(inputs, model)
        if args.start == "truth":
            starts = fit_poses(model, inputs.truth)[0][inputs.truth_frame[frames]]
        else:
            starts = planted_poses(inputs.model, model, [rec.poses[t] for t in frames])
        before, after, errs = [], [], []
        with kernel_threads(cfg.threads):
            for t, q in zip(frames, starts):
                refined = refine(tracker, obs[t], q, cfg.seed, t)
                before.append(tracker.full_fit(obs[t], q)[1])
                after.append(tracker.full_fit(obs[t], refined)[1])
                errs.append(lower_error_mm(model, refined, truth_lower[inputs.truth_frame[t]]))
        print(f"| {factor:g} | {np.mean(before):.4f} | {np.mean(after):.4f} | {np.mean(errs):.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
