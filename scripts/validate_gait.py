"""Validate gait events and joint angles on the ground truth of the real walks (prints tables).

1. Events: detected from the truth joint centres (read through the same code as ``gaitcap report``)
   vs the events recorded with the trials: the Vicon EVENT group of walk.c3d (100 Hz) and the
   force-plate contacts of the OpenSim subject01 walk (60 Hz; > 20 N threshold). Reported with and
   without the local refinement of the Zeni anchors.
2. Angles: hip and knee flexion (and pelvic tilt, ankle) vs the Plug-in-Gait channels stored in
   walk.c3d (LHipAngles, LKneeAngles, ... x component = flexion), RMSE in degrees, per frame over
   the whole trial; pelvis frame from joint centres only, and from the ASIS/PSIS markers.

    python scripts/validate_gait.py [--data ../shared/data]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from gaitcap.errors import GaitcapError
from gaitcap.gait.angles import joint_angles
from gaitcap.gait.events import detect_events
from gaitcap.gait.options import GaitOptions
from gaitcap.io.c3d import read_c3d_angles
from gaitcap.markers.motion import read_markers, read_motion
from gaitcap.report.pipeline import with_pelvis_markers

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
TOL_S = 0.020  # 2 frames at 100 Hz (the 'frames' column gives the error in each file's samples)


def event_table(name: str, path: Path, refine: bool) -> list[float]:
    traj = read_motion(path)
    found, _ = detect_events(traj, GaitOptions(refine=refine))
    errors = []
    print(f"\n{name} ({traj.rate_hz:g} Hz), refine={refine}")
    print(f"{'side':6} {'event':12} {'recorded_s':>10} {'detected_s':>10} {'error_ms':>9} {'frames':>7}")
    for ref in traj.events:
        same = [e.time_s for e in found if (e.side, e.event) == (ref.side, ref.event)]
        best = min(same, key=lambda t: abs(t - ref.time_s)) if same else None
        err = float("inf") if best is None else best - ref.time_s
        errors.append(err)
        det = f"{best:10.3f}" if best is not None else f"{'missed':>10}"
        print(f"{ref.side:6} {ref.event:12} {ref.time_s:10.3f} {det} {err * 1000:9.1f} {err * traj.rate_hz:7.2f}")
    print(f"detected {len(found)} events for {len(traj.events)} recorded")
    return errors


def angle_table(path: Path) -> None:
    pig = read_c3d_angles(path)
    joints = read_motion(path)
    variants = {"joint centres only": joints, "joint centres + ASIS/PSIS": with_pelvis_markers(joints, read_markers(path))}
    channels = [("hip_flexion", "HipAngles", 0), ("knee_flexion", "KneeAngles", 0),
                ("ankle_dorsiflexion", "AnkleAngles", 0), ("pelvis_tilt", "PelvisAngles", 0),
                ("pelvis_obliquity", "PelvisAngles", 1), ("pelvis_rotation", "PelvisAngles", 2),
                ("hip_adduction", "HipAngles", 1)]  # fmt: skip
    print(f"\nJoint angles vs Plug-in-Gait ({path.name}, {joints.n_frames} frames): RMSE, mean offset (ours - PiG), "
          "RMSE after removing the offset, correlation; degrees")
    print(f"{'pelvis frame':26} {'angle':20} {'side':5} {'RMSE':>6} {'offset':>7} {'RMSE-off':>8} {'r':>6}")
    for label, traj in variants.items():
        _, direction = detect_events(traj)
        ang, _ = joint_angles(traj, direction)
        for ours, theirs, comp in channels:
            for side, pfx in (("l", "L"), ("r", "R")):
                a = ang[f"{ours}_{side}"]
                b = pig.get(f"{pfx}{theirs}")[:, comp]
                ok = np.isfinite(a) & np.isfinite(b)
                d = a[ok] - b[ok]
                rmse, off = float(np.sqrt(np.mean(d**2))), float(np.mean(d))
                r = float(np.corrcoef(a[ok], b[ok])[0, 1])
                print(f"{label:26} {ours:20} {side:5} {rmse:6.2f} {off:7.2f} {np.std(d):8.2f} {r:6.3f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the shared data folder")
    args = ap.parse_args(argv)
    if not args.data.is_dir():
        ap.error(f"--data {args.data}: no such folder (the shared data; by default ../shared/data beside the checkout)")
    walks = {
        "Vicon PiG walk.c3d": args.data / "walking" / "vicon_pig_lowerbody" / "walk.c3d",
        "OpenSim subject01_walk1.trc": args.data / "walking" / "opensim_gait2354_subject01" / "subject01_walk1.trc",
        "C3D.ORG gait-pig.c3d": args.data / "walking" / "c3d_org_sample03" / "gait-pig.c3d",
    }
    for refine in (False, True):
        errs = []
        for name, path in walks.items():
            errs += event_table(name, path, refine)
        e = np.abs(np.array(errs))
        print(f"\nrefine={refine}: {np.sum(e <= TOL_S)}/{len(e)} recorded events within {TOL_S * 1000:.0f} ms "
              f"({100 * np.mean(e <= TOL_S):.0f} %), median |error| {1000 * np.median(e):.1f} ms, max {1000 * e.max():.1f} ms")
    angle_table(walks["Vicon PiG walk.c3d"])
    angle_table(walks["C3D.ORG gait-pig.c3d"])
    return 0


if __name__ == "__main__":
    try:
        raise SystemExit(main())
    except GaitcapError as e:  # a file of the data missing or unreadable
        sys.exit(f"error: {e}")
