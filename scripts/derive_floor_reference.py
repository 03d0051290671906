"""Derive the floor-point reference pixels of the Pose2Sim demo lab from Pose2Sim's scene calibrations.

Pose2Sim (perfanalytics/pose2sim, BSD-3-Clause, Pagnon et al. JOSS 2022) ships two scene
calibrations of the demo cameras, each solved (solvePnP) from the 8 floor points clicked in
``calibration/extrinsics/camNN_ext.png``:

* ``Pose2Sim/Demo_SinglePerson/calibration/Calib_scene.toml`` (checkerboard intrinsics),
* ``Pose2Sim/Demo/calibration/Calib_intcheckerboard_extscene.toml`` (Qualisys intrinsics;
  rotation/translation written as nested lists ``[[x], [y], [z]]``).

Projecting the 8 points through such a file (with its own distortion) gives back the clicked
pixels to within its PnP residual. This script writes one ``ScenePoints`` YAML per file (the
schema of ``tests/fixtures/calibration/pose2sim_qualisys/scene_points.yaml``); the Pose2Sim files
themselves are not stored in the repository.

    python scripts/derive_floor_reference.py Calib_scene.toml floor_points_singleperson.yaml \\
        --source Pose2Sim/Demo_SinglePerson/calibration/Calib_scene.toml
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from gaitcap.errors import GaitcapError  # noqa: E402
from gaitcap.io.calibration_toml import read_calibration  # noqa: E402

# The lab's scene-calibration points (metres, z up), as listed for the Pose2Sim demo.
FLOOR_POINTS = {
    "p0": (-2.0, 0.3, 0.0), "p1": (-2.0, 0.0, 0.0), "p2": (-2.0, 0.0, 0.05), "p3": (-2.0, -0.3, 0.0),
    "p4": (0.0, 0.3, 0.0), "p5": (0.0, 0.0, 0.0), "p6": (0.0, 0.0, 0.05), "p7": (0.0, -0.3, 0.0),
}


def camera_key(name: str) -> str:
    """``int_cam01_img`` / ``cam_01`` -> ``cam01`` (the names of the Qualisys file)."""
    m = re.search(r"cam_?(\d+)", name)
    if m is None:
        raise SystemExit(f"cannot tell the camera number from table {name!r}")
    return f"cam{int(m.group(1)):02d}"


def derive(toml_path: Path, source: str) -> dict:
    """``ScenePoints`` mapping: the floor points and their pixels projected through ``toml_path``."""
    rig = read_calibration(toml_path)
    names = list(FLOOR_POINTS)
    pixels = {}
    for cam in rig:
        uv = cam.project([FLOOR_POINTS[n] for n in names])
        pixels[camera_key(cam.name)] = {n: [round(float(u), 1), round(float(v), 1)] for n, (u, v) in zip(names, uv)}
    notes = (
        f"Derived from {source} (perfanalytics/pose2sim, BSD-3-Clause, Pagnon et al. JOSS 2022): "
        "the 8 floor points projected through that scene calibration (OpenCV model, its own "
        "intrinsics and distortion) by scripts/derive_floor_reference.py. That calibration was solved "
        "from the points clicked in camNN_ext.png (1088x1920), so these are the clicked pixels to "
        "within its PnP residual."
    )
    return {"points": {n: list(p) for n, p in FLOOR_POINTS.items()}, "pixels": pixels, "notes": notes}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("toml", type=Path, help="a Pose2Sim scene calibration (calibration.toml convention)")
    ap.add_argument("out", type=Path, help="the ScenePoints YAML to write")
    ap.add_argument("--source", required=True, help="the file's path in the Pose2Sim repository (recorded in notes)")
    args = ap.parse_args()
    try:
        data = derive(args.toml, args.source)
    except GaitcapError as e:
        sys.exit(f"error: {e}")
    header = f"# Floor points of the Pose2Sim demo lab and their pixels per camera, derived from {args.source}\n"
    args.out.write_text(header + yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=120), encoding="utf-8")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
