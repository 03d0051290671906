"""Are a run's legs placed on its silhouettes, or guessed where the masks have none? (a diagnostic)

    PYTHONPATH=src python scripts/leg_support.py RUN... [--below 0.5] [--segments foot_l foot_r]

RUN is a ``gaitcap track --save-masks`` output folder (``scripts/bench_suite.py``'s runs keep their
masks). For every tracked frame, each leg segment (thighs, shanks) is drawn as the tracker draws it
(the run's own body, ``gaitcap.pipeline.read_body``; its poses; the session's calibration) into
each camera, and its support is the fraction of its pixels that lie on the run's mask there; a
frame's support of a segment is its lowest over the cameras (``gaitcap.tracking.support``, as the
verdict's note measures it on the tracker's own silhouettes). Prints, per run and segment, the 10th
percentile of that support over the frames and the share of frames below ``--below``, with the
run's verdict and, when ``RUN/eval.json`` exists, its lower-limb error and knee RMSE: a leg the
masks lost in one camera is placed by the others and the priors alone, which the verdict notes
(``verdict.min_leg_support``; docs/validation.md, "Legs placed where the masks have none").
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from gaitcap.io.calibration_toml import read_calibration
from gaitcap.io.silhouettes_h5 import read_masks
from gaitcap.pipeline import read_body
from gaitcap.tracking.likelihood import SilhouetteLikelihood
from gaitcap.tracking.observation import observe, tracking_views
from gaitcap.tracking.support import LEG_SEGMENTS, segment_support


def support(run: Path, segments: tuple[str, ...] = LEG_SEGMENTS) -> dict[str, np.ndarray]:
    """Per segment (default: the legs'), each tracked frame's support (:func:`segment_support`, at full
    resolution on the run's saved masks): (T,) arrays (NaN: not judged in any camera)."""
    model = read_body(run).model
    with h5py.File(run / "trajectories.h5", "r") as f:
        poses = f["poses"][()]
        session = Path(str(f.attrs["session"]))
    rig = read_calibration(session / "calibration.toml")
    views = tracking_views(rig, 1.0)
    likelihood = SilhouetteLikelihood(views, 1.0)
    masks = [read_masks(run / "silhouettes.h5", cam) for cam in rig.names]
    out = {s: np.full(len(poses), np.nan) for s in segments}
    for t in np.flatnonzero(np.all(np.isfinite(poses), axis=1)):
        shares = segment_support(model, likelihood, observe(views, [m[t] for m in masks]), poses[t], segments)
        for s, share in zip(segments, shares):
            out[s][t] = share
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--below", type=float, default=0.5, help="support counted as missing below this (0-1)")
    parser.add_argument("--segments", nargs="+", default=list(LEG_SEGMENTS),
                        help="the body model's segments to judge (default: thighs and shanks)")  # fmt: skip
    args = parser.parse_args(argv)
    segments = tuple(args.segments)
    for run in args.runs:
        for need in ("trajectories.h5", "track.json", "silhouettes.h5"):
            if not (run / need).is_file():
                print(f"error: {run / need}: missing (a gaitcap track --save-masks output folder?)", file=sys.stderr)
                return 1
    print("| run | lower-limb mm | knee RMSE l, r (deg) | verdict | " + " | ".join(segments) + " |")
    print("|---|---|---|---|" + "---|" * len(segments))
    for run in args.runs:
        by_segment = support(run, segments)
        verdict = json.loads((run / "track.json").read_text()).get("verdict", "?")
        mm, knees = "-", "-"
        if (run / "eval.json").is_file():
            e = json.loads((run / "eval.json").read_text())
            mm = f"{e['positions_mm']['lower_limb']['mpjpe_mm']:.1f}"
            knees = f"{e['angles_rmse_deg']['knee_flexion_l']:.1f}, {e['angles_rmse_deg']['knee_flexion_r']:.1f}"
        cells = []
        for s in segments:
            v = by_segment[s][np.isfinite(by_segment[s])]
            cells.append(f"{np.percentile(v, 10):.2f} ({np.mean(v < args.below):.0%})" if len(v) else "-")
        print(f"| {run.name} | {mm} | {knees} | {verdict} | " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
