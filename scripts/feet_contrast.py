"""Could a background test still find the feet a suite's masks miss? (a diagnostic, not a test)

    PYTHONPATH=src python scripts/feet_contrast.py WORK... [--sigma 3]

WORK is a folder of ``scripts/bench_suite.py`` (its ``suite.json``, ``sessions/`` and ``runs/``,
the runs tracked with ``--save-masks`` as the suite does). For every foot that a run's masks miss
in a camera-frame (``suite.json``'s ``parts_missing_by_part``: the masks hold less than half of the
foot's true pixels, ``gaitcap.evaluation.silhouettes.part_coverage``), the foot's true pixels that
the masks miss are compared with the floor around the foot, in the frame minus the camera's
background plate (BGR): the floor's pixels in the foot's box grown by the foot's radius, off the
true mask dilated by 3 pixels, give the mean and the standard deviation of each channel's
difference (the light's change and the noise there); a missed pixel *stands out* when one channel's
difference lies more than ``--sigma`` standard deviations from the floor's mean.

Each missed foot is then **camouflaged** (under a quarter of its missed pixels stand out: no test
on the pixel's colour against the plate can find it, whatever its threshold), **partly** (a quarter
to 60 %) or **visible** (more than 60 %: a colour test found it and a later one, the shadow test,
the floor check or the clean-up, dropped it). Prints a markdown table: per session, the feet missed
(one per foot and camera-frame), the median share of their missed pixels that stands out, and the
three counts; then the totals.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

import cv2
import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from gaitcap.evaluation.report import read_truth_reference
from gaitcap.evaluation.silhouettes import part_centres, part_pixels, project_part
from gaitcap.io.calibration_toml import read_calibration
from gaitcap.silhouette.run import read_plate
from gaitcap.video import read_frames

#: shares of a missed foot's pixels that stand out, below which it is camouflaged, above which visible
CAMOUFLAGED, VISIBLE = 0.25, 0.6
#: the true mask is grown by this many pixels on each side before the floor around a foot is taken
MARGIN_PX = 3


def standing_out(diff: np.ndarray, missed: np.ndarray, floor: np.ndarray, sigma: float) -> float | None:
    """Share of the ``missed`` pixels (H, W bool) whose difference from the plate ``diff`` (H, W, 3)
    lies more than ``sigma`` standard deviations from the ``floor`` pixels' (H, W bool) mean in
    some channel; None with under 5 missed or 20 floor pixels."""
    if missed.sum() < 5 or floor.sum() < 20:
        return None
    mean, sd = diff[floor].mean(axis=0), diff[floor].std(axis=0) + 1e-6
    return float(np.mean(np.abs((diff[missed] - mean) / sd).max(axis=1) > sigma))


def foot_shares(work: Path, row: dict, sigma: float) -> list[float]:
    """:func:`standing_out` of every foot missed in one run of the suite (``row``: its suite.json row)."""
    missed = {part: items for part, items in (row.get("parts_missing_by_part") or {}).items() if items}
    session, run = work / "sessions" / row["name"], work / "runs" / row["name"]
    if not missed:
        return []
    if not (session / "truth.h5").exists():  # an external session (bench_suite.py reads it in place)
        print(f"<!-- {row['name']}: {session} not found, skipped -->")
        return []
    rig = read_calibration(session / "calibration.toml")
    centres = part_centres(read_truth_reference(session / "truth.h5").trajectory)
    grow = np.ones((2 * MARGIN_PX + 1, 2 * MARGIN_PX + 1), np.uint8)
    by_camera: dict[str, list[tuple[str, int]]] = {}
    for part, items in missed.items():
        for item in items:
            cam, k = item.rsplit(":", 1)
            by_camera.setdefault(cam, []).append((part, int(k)))
    shares = []
    with h5py.File(session / "truth.h5", "r") as truth, h5py.File(run / "silhouettes.h5", "r") as masks:
        for cam, feet in by_camera.items():
            plate = read_plate(session / "background" / f"{cam}.png").astype(float)
            frames = read_frames(session / "videos" / f"{cam}.mp4", [k for _, k in feet])
            for part, k in feet:
                true, ours = truth["masks"][cam][k] > 0, masks["masks"][cam][k] > 0
                pix, radius = project_part(rig[cam], centres[part][k : k + 1], part)
                found = part_pixels(true.astype(np.uint8), pix[0], radius[0])
                if found is None or k not in frames:
                    continue
                box, inside = found
                foot = np.zeros_like(true)
                foot[box] = inside
                r = int(radius[0])
                floor = np.zeros_like(true)
                floor[max(box[0].start - r, 0) : box[0].stop + r, max(box[1].start - r, 0) : box[1].stop + r] = True
                floor &= ~cv2.dilate(true.astype(np.uint8), grow).astype(bool)
                share = standing_out(frames[k].astype(float) - plate, foot & ~ours, floor, sigma)
                if share is not None:
                    shares.append(share)
    return shares


def kind(share: float) -> str:
    """camouflaged, partly or visible (module docstring)."""
    return "camouflaged" if share < CAMOUFLAGED else ("partly" if share <= VISIBLE else "visible")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("work", type=Path, nargs="+", help="bench_suite.py work folders")
    ap.add_argument("--sigma", type=float, default=3.0, help="standard deviations of the floor's difference")
    args = ap.parse_args()
    for work in args.work:
        if not (work / "suite.json").is_file():
            sys.exit(f"error: {work}: not a scripts/bench_suite.py work folder (no suite.json: run bench_suite.py "
                     f"--work {work} first)")  # fmt: skip
    kinds = ("camouflaged", "partly", "visible")
    total: Counter[str] = Counter()
    print("| work | session | feet missed | median share standing out | " + " | ".join(kinds) + " |")
    print("|---|---|---|---|" + "---|" * len(kinds))
    for work in args.work:
        for row in json.loads((work / "suite.json").read_text()):
            shares = foot_shares(work, row, args.sigma)
            if not shares:
                continue
            counts = Counter(kind(s) for s in shares)
            total.update(counts)
            print(f"| {work.name} | {row['name']} | {len(shares)} | {np.median(shares):.2f} | "
                  + " | ".join(str(counts[k]) for k in kinds) + " |")  # fmt: skip
    print(f"| all | | {sum(total.values())} | | " + " | ".join(str(total[k]) for k in kinds) + " |")


if __name__ == "__main__":
    main()
