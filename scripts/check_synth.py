"""Render synthetic sessions from the real walks and print the synth contract figures.

    python scripts/check_synth.py [--data ../shared/data] [--out /tmp/gaitcap-synth]

Prints a markdown table, a row per trial: frames, seconds to render, the body fit's residual to the
marker joint centres (mean over hips, knees and ankles, and the largest; mm), the share of (frame,
point) truth positions that project inside the rendered true masks per camera (%; 100 is the
contract), and the largest bone-length variation over the clip ((max - min) / mean, %; the truth is
the markers' own joint centres, whose bones vary by several % in real data:
``gaitcap.synth.checks.bone_length_variation``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from gaitcap.errors import GaitcapError
from gaitcap.synth.checks import bone_length_variation, truth_inside_masks
from gaitcap.synth.session import SynthOptions, synthesize

REPO = Path(__file__).resolve().parents[1]
TRIALS = {
    "vicon_pig_lowerbody": "walking/vicon_pig_lowerbody/walk.c3d",
    "opensim_gait2354": "walking/opensim_gait2354_subject01/subject01_walk1.trc",
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    ap.add_argument("--out", type=Path, default=Path("/tmp/gaitcap-synth"))
    ap.add_argument("--seed", type=int, default=0, help="look seed (person, clothes, room, light, cameras)")
    args = ap.parse_args()
    if not args.data.is_dir():
        ap.error(f"--data {args.data}: no such folder (the shared data; by default ../shared/data beside the checkout)")
    print("| trial | frames | s to render | fit residual hips/knees/ankles mm | truth in mask % per camera | max bone variation % |")
    print("|---|---|---|---|---|---|")
    for name, rel in TRIALS.items():
        t0 = time.perf_counter()
        res = synthesize(args.data / rel, args.out / name, SynthOptions(seed=args.seed), force=True, progress=False)
        dt = time.perf_counter() - t0
        lower = [res.fit.residual_m[k] * 1000 for k in ("hip_l", "hip_r", "knee_l", "knee_r", "ankle_l", "ankle_r")]
        inside = truth_inside_masks(res.session)
        bones = bone_length_variation(res.session)
        print(f"| {name} | {res.n_frames} | {dt:.1f} | {np.mean(lower):.1f} (max {np.max(lower):.1f}) | "
              + ", ".join(f"{k} {100 * v:.2f}" for k, v in inside.items())
              + f" | {100 * max(bones.values()):.1f} |")


if __name__ == "__main__":
    try:
        main()
    except GaitcapError as e:  # a file of the data missing or unreadable
        sys.exit(f"error: {e}")
