"""Build gaitcap's embedded default trial src/gaitcap/data/walk_pig.c3d from the Vicon walk.

Keeps only the marker points the Plug-in-Gait mapping read when the file was built (``MARKERS``), the
Plug-in-Gait angle channels the gait report validates against, the events and PROCESSING:Height; no
analogs: the file it writes is byte for byte the shipped one. Then checks that the trimmed file has the
original's events, time axis and height, and prints each joint centre's largest distance between the two
as gaitcap reads them: 0 but for the hips (and so the pelvis), which the mapping now takes from the
original's own LFEP/RFEP when present, and from the pelvis markers (Harrington) in the trimmed file.

Usage:
    python scripts/make_embedded_walk.py [--data ../shared/data] [--out src/gaitcap/data/walk_pig.c3d]
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from gaitcap.errors import GaitcapError  # noqa: E402
from gaitcap.markers.motion import read_motion  # noqa: E402

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
#: the markers kept: those the Plug-in-Gait mapping read when the file was built (its hips from the pelvis
#: markers, Harrington). The mapping now prefers a file's own hip centres (LFEP/RFEP), which are not kept:
#: the embedded walk's hips are Harrington's, about 35 mm from the original's LFEP/RFEP.
MARKERS = ("LASI", "RASI", "LPSI", "RPSI", "LKJC", "RKJC", "LAJC", "RAJC", "LHEE", "LTOE", "RHEE", "RTOE")
ANGLES = ("LHipAngles", "RHipAngles", "LKneeAngles", "RKneeAngles", "LAnkleAngles", "RAnkleAngles",
          "LPelvisAngles", "RPelvisAngles")  # fmt: skip
#: copied as they are when present
COPIED = {
    "POINT": ("UNITS", "X_SCREEN", "Y_SCREEN", "ANGLE_UNITS"),
    "EVENT": ("CONTEXTS", "LABELS", "DESCRIPTIONS", "TIMES"),
    "PROCESSING": ("Height", "Bodymass", "LLegLength", "RLegLength"),
    "TRIAL": ("ACTUAL_START_FIELD", "ACTUAL_END_FIELD", "CAMERA_RATE"),
}


def _value(v: object) -> object:
    """ezc3d parameter values as types ezc3d's setter accepts."""
    arr = np.asarray(v)
    if arr.dtype.kind in "iu":
        return [int(x) for x in arr.ravel()]
    if arr.dtype.kind == "f":
        return arr.astype(np.float64) if arr.ndim > 1 else [float(x) for x in arr.ravel()]
    return [str(x) for x in v]  # type: ignore[union-attr]


def build(src: Path, out: Path) -> None:
    import ezc3d

    c = ezc3d.c3d(str(src))
    labels = [s.strip() for s in c["parameters"]["POINT"]["LABELS"]["value"]]
    keep = list(MARKERS) + list(ANGLES)
    idx = [labels.index(n) for n in keep]
    points = np.asarray(c["data"]["points"])[:, idx, :]
    residuals = np.asarray(c["data"]["meta_points"]["residuals"])[0, idx, :]
    points[:3, residuals < 0] = np.nan

    new = ezc3d.c3d()
    new["parameters"]["POINT"]["RATE"]["value"] = [float(c["header"]["points"]["frame_rate"])]
    new["parameters"]["POINT"]["LABELS"]["value"] = keep
    new["data"]["points"] = points
    new.add_parameter("POINT", "ANGLES", list(ANGLES))
    for group, names in COPIED.items():
        for name in names:
            param = c["parameters"].get(group, {}).get(name)
            if param is not None:
                new.add_parameter(group, name, _value(param["value"]))
    new.add_parameter("EVENT", "USED", [len(c["parameters"]["EVENT"]["LABELS"]["value"])])
    new["header"]["points"]["first_frame"] = c["header"]["points"]["first_frame"]
    out.parent.mkdir(parents=True, exist_ok=True)
    new.write(str(out))


def verify(src: Path, out: Path) -> dict[str, float]:
    """Each joint centre's largest distance (m) between the original and the trimmed file, as gaitcap
    reads them; exits when their names, time axis, events or height differ."""
    a, b = read_motion(src), read_motion(out)
    if a.names != b.names or a.t0_s != b.t0_s or a.rate_hz != b.rate_hz or a.events != b.events:
        raise SystemExit(f"mismatch: names/t0/rate/events differ\n{a.events}\n{b.events}")
    if a.meta.get("height_m") != b.meta.get("height_m"):
        raise SystemExit("mismatch: height")
    dist = np.linalg.norm(a.points - b.points, axis=2)
    return {name: float(np.nanmax(dist[:, k])) for k, name in enumerate(a.names)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the shared data folder")
    ap.add_argument("--out", type=Path, default=REPO / "src" / "gaitcap" / "data" / "walk_pig.c3d")
    args = ap.parse_args()
    if not args.data.is_dir():
        ap.error(f"--data {args.data}: no such folder (the shared data; by default ../shared/data beside the checkout)")
    folder = args.data / "walking" / "vicon_pig_lowerbody"
    src = folder / "walk.c3d"
    if not src.is_file():
        sys.exit(f"error: {src}: file not found (the Vicon walk of the shared data)")
    build(src, args.out)
    shutil.copyfile(folder / "LICENSE.txt", args.out.parent / "LICENSE.txt")
    err = verify(src, args.out)
    print(f"{args.out}: {args.out.stat().st_size} bytes; largest joint-centre difference vs the original, mm: "
          + ", ".join(f"{k} {1000 * v:.1f}" for k, v in err.items()))


if __name__ == "__main__":
    try:
        main()
    except GaitcapError as e:  # a file of the data missing or unreadable
        sys.exit(f"error: {e}")
