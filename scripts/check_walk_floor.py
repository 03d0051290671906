"""Where each walk's floor is: the ankle's height above z = 0 with the foot flat, against anatomy.

A synthetic session keeps its walk's z = 0 as the rendered floor and draws the shoe from the sole
points, so an ankle the walk carries low is drawn low inside the shoe. Prints, for each walk of the
shared data (``gaitcap.markers.motion.read_motion``'s joint centres): the ankle centre's median height
above z = 0 in the frames where a foot is flat on it, as millimetres and as a fraction of the leg (hip
-> knee -> ankle, as ``gaitcap eval`` measures it: ``gaitcap.body.measures.segment_lengths``), and the
toe marker's own height in those frames (the sole rule lowers it by that much); then, for each session
folder given (its ``truth.h5``, or a truth folder, itself or its ``truth/``, as ``gaitcap eval`` reads
them; the height from ``session.yaml``), the ankle's height above z = 0 (the rendered floor) in the
frames where heel and toe are both near their lowest, as a fraction of the subject's height. Anatomy for
comparison: the ankle (malleolus) 0.039 H above the floor barefoot, the leg (hip to ankle) 0.49 H
(Winter 2009, Fig. 4.1, as body.yaml): 0.080 of the leg barefoot, more with a shoe's sole under it.

Usage:
    python scripts/check_walk_floor.py [--data ../shared/data] [SESSION_DIR ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from gaitcap.body.measures import segment_lengths  # noqa: E402
from gaitcap.config import load_yaml_model  # noqa: E402
from gaitcap.errors import GaitcapError, InputError  # noqa: E402
from gaitcap.evaluation.report import read_truth_trajectory  # noqa: E402
from gaitcap.markers.motion import read_markers, read_motion  # noqa: E402
from gaitcap.session import SESSION_FILE, SessionInfo  # noqa: E402

DEFAULT_DATA = REPO.parent / "shared" / "data"
WALKS = {
    "vicon": ("walking/vicon_pig_lowerbody/walk.c3d", "LTOE", "RTOE"),
    "opensim": ("walking/opensim_gait2354_subject01/subject01_walk1.trc", "L.Toe.Tip", "R.Toe.Tip"),
    "c3dorg": ("walking/c3d_org_sample03/gait-pig.c3d", "LTOE", "RTOE"),
}
FLAT_M = 0.02  # a foot whose heel and toe (at the sole) are both this close to z = 0 (metres) is flat
FLAT_H = 0.012  # ... in a session: as a fraction of the subject's height


def walk_row(path: Path, toes: tuple[str, str]) -> str:
    traj = read_motion(path)
    raw = read_markers(path)
    leg = segment_lengths(traj.names, traj.points)["leg"]  # as gaitcap eval measures it
    ankle_mm, toe_mm, frames = [], [], 0
    for side, toe in zip("lr", toes):
        flat = (traj.point(f"heel_{side}")[:, 2] < FLAT_M) & (traj.point(f"toe_{side}")[:, 2] < FLAT_M)
        frames += int(flat.sum())
        ankle_mm.append(np.nanmedian(traj.point(f"ankle_{side}")[flat, 2]) * 1000)
        toe_mm.append(np.nanmedian(raw.point(toe)[flat, 2]) * 1000 if raw.has(toe) else np.nan)
    ankle = np.mean(ankle_mm)
    return (f"{path.name:24s} frames {frames:4d}  ankle {ankle:5.0f} mm = {ankle / 1000 / leg:.3f} of the leg"
            f"  toe marker {np.nanmean(toe_mm):5.1f} mm")  # fmt: skip


def session_row(folder: Path) -> str:
    truth = read_truth_trajectory(folder / "truth" if (folder / "truth").is_dir() else folder)
    height = load_yaml_model(SessionInfo, folder / SESSION_FILE).subject.height_m
    if height is None:
        raise InputError(f"{folder / SESSION_FILE}: no subject.height_m")
    heights = []
    for s in "lr":
        heel, toe = truth.point(f"heel_{s}")[:, 2], truth.point(f"toe_{s}")[:, 2]
        flat = (heel - np.nanmin(heel) < FLAT_H * height) & (toe - np.nanmin(toe) < FLAT_H * height)
        heights.append(truth.point(f"ankle_{s}")[flat, 2])
    h = np.concatenate(heights)
    ankle = np.median(h) / height if h.size else np.nan
    heel = min(np.nanmin(truth.point(f"heel_{s}")[:, 2]) for s in "lr") * 1000
    return (f"{folder.name:24s} H {height:.2f} m  flat frames {h.size:3d}  ankle {ankle:.3f} H"
            f"  lowest heel point {heel:3.0f} mm")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("sessions", nargs="*", type=Path, help="session folders with their truth")
    args = ap.parse_args()
    if not args.data.is_dir():
        ap.error(f"--data {args.data}: no such folder (the shared data; by default ../shared/data beside the checkout)")
    print("walk (joint centres as gaitcap reads them; heel and toe at the sole within 2 cm of z = 0)")
    for rel, *toes in WALKS.values():
        path = args.data / rel
        print(walk_row(path, tuple(toes)) if path.exists() else f"{rel}: missing")
    if args.sessions:
        print("sessions (truth; heel and toe within 0.012 H of their lowest)")
        for folder in args.sessions:
            try:
                print(session_row(folder))
            except InputError as e:
                sys.exit(f"error: {e}")


if __name__ == "__main__":
    try:
        main()
    except GaitcapError as e:  # a file of the data missing or unreadable
        sys.exit(f"error: {e}")
