"""Bone-length constancy of the joint centres read from the walking trials.

Prints, for each trial, the mean length and coefficient of variation (std / mean over frames)
of the thigh (hip-knee), shank (knee-ankle) and foot (heel-toe) segments, and the events.

Usage:
    python scripts/motion_bone_lengths.py [--data ../shared/data]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from gaitcap.errors import GaitcapError  # noqa: E402
from gaitcap.markers.motion import read_motion  # noqa: E402

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
SEGMENTS = {"thigh": ("hip", "knee"), "shank": ("knee", "ankle"), "foot": ("heel", "toe")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    args = ap.parse_args()
    if not args.data.is_dir():
        ap.error(f"--data {args.data}: no such folder (the shared data; by default ../shared/data beside the checkout)")
    trials = [args.data / "walking" / "vicon_pig_lowerbody" / "walk.c3d",
              args.data / "walking" / "opensim_gait2354_subject01" / "subject01_walk1.trc"]  # fmt: skip
    for path in trials:
        traj = read_motion(path)
        print(f"{path.name}: mapping {traj.meta['mapping']}, {traj.n_frames} frames at {traj.rate_hz:g} Hz")
        for seg, (a, b) in SEGMENTS.items():
            for side in ("l", "r"):
                length = np.linalg.norm(traj.point(f"{a}_{side}") - traj.point(f"{b}_{side}"), axis=1)
                mean, cv = np.nanmean(length), np.nanstd(length) / np.nanmean(length)
                print(f"  {seg}_{side}: mean {mean * 1000:.1f} mm, CV {cv * 100:.2f} %")
        for e in traj.events:
            print(f"  {e.time_s:.3f} s {e.side} {e.event} ({e.source})")


if __name__ == "__main__":
    try:
        main()
    except GaitcapError as e:  # a file of the data missing or unreadable
        sys.exit(f"error: {e}")
