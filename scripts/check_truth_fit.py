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
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import h5py
import numpy as np

from gaitcap.errors import GaitcapError, InputError
from gaitcap.evaluation.report import read_tracked, read_truth_trajectory
from gaitcap.pipeline import kernel_threads
from gaitcap.report.fit import load_fit_record
from gaitcap.report.sheet import tracked_model
from gaitcap.session import Session
from gaitcap.synth.fit import fit_poses
from gaitcap.tracking.config import load_tracking_config
from gaitcap.tracking.factored_ipf import FactoredIPF
from gaitcap.tracking.likelihood import SilhouetteLikelihood
from gaitcap.tracking.observation import observe, tracking_views
from gaitcap.trajectory import LOWER_LIMB


def lower_error_mm(model, q: np.ndarray, truth_lower: np.ndarray) -> float:
    """Mean distance (mm) of pose q's hips, knees and ankles from the truth's (6, 3) metres."""
    pts = model.forward(q[None])[0][[model.point_index(n) for n in LOWER_LIMB]]
    return float(1000.0 * np.linalg.norm(pts - truth_lower, axis=1).mean())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("session", type=Path)
    ap.add_argument("run", type=Path)
    ap.add_argument("--config", type=Path, default=None, help="the tracking configuration of the run")
    ap.add_argument("--min-error-mm", type=float, default=60.0)
    ap.add_argument("--tolerance", type=float, default=0.005, help="fit difference counted as a preference")
    ap.add_argument("--frames", type=int, nargs="*", default=None)
    args = ap.parse_args(argv)

    try:
        return check(args)
    except GaitcapError as e:
        sys.exit(f"error: {e}")


def check(args: argparse.Namespace) -> int:
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
    views = tracking_views(session.rig, cfg.scale)
    tracker = FactoredIPF(model, SilhouetteLikelihood(views, cfg.beta), cfg, np.random.default_rng(cfg.seed),
                          uncertainty=False)  # fmt: skip

    truth = read_truth_trajectory(args.session / "truth.h5")
    if abs(truth.rate_hz - rec.rate_hz) > 1e-6:
        truth = truth.resample(rec.rate_hz)
    true_poses, _ = fit_poses(model, truth)
    truth_lower = truth.subset(list(LOWER_LIMB)).points
    times = read_tracked(args.run).times()  # the run's time axis (its own t0)

    rows = []
    with h5py.File(args.run / "silhouettes.h5", "r") as masks, kernel_threads(cfg.threads):  # as in a run
        for t in range(rec.n_frames):
            j = truth.frame_of(float(times[t]))
            if not (0 <= j < truth.n_frames) or not np.all(np.isfinite(rec.poses[t])):
                continue
            err = lower_error_mm(model, rec.poses[t], truth_lower[j])
            if (err < args.min_error_mm) if args.frames is None else (t not in args.frames):
                continue
            obs = observe(views, [masks["masks/" + cam.name][t] for cam in session.rig.cameras])
            tracker.rng = np.random.default_rng([cfg.seed, t])  # each frame's result its own
            tracker.start(true_poses[j], fresh=False)
            tracker.step(obs)
            refined = tracker.q.copy()
            fits = [tracker.full_fit(obs, q)[1] for q in (rec.poses[t], true_poses[j], refined)]
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


if __name__ == "__main__":
    raise SystemExit(main())
