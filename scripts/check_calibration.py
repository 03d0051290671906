"""Measure gaitcap's calibration against the references in ../shared/data (prints a table).

    python scripts/check_calibration.py [--data PATH] [--only qualisys] [--overlay DIR]

Four sections (``--only`` runs one):

- ``opencv``: the 13 left chessboard images calibrated by gaitcap (CALIB_FIX_ASPECT_RATIO) against
  OpenCV's own reference (left_intrinsics.yml): fx, fy, cx, cy and the RMS reprojection error, ours,
  the reference's and their difference (pixels); then the stereo pairs' RMS, baseline and epipolar error;
- ``pose2sim``: each Pose2Sim demo camera's intrinsics from its checkerboard images against the
  Qualisys calibration's: focal lengths, their difference in %, the principal point's in pixels, RMS;
- ``qualisys``: the imported Qualisys calibration reprojecting the hand-located scene points, then
  against the 8 floor points clicked for Pose2Sim's two scene calibrations (mean and max pixels per
  camera; "click noise": the two clickings against each other, the floor under which a difference
  means nothing); ``--overlay DIR`` draws them on the scene images; then each camera's video size
  against its calibration's;
- ``synthetic``: a floor board rendered for 3 known cameras, solved from one position (solvePnP) and
  from four (bundle adjustment): each camera's position (mm) and rotation (degrees) error, RMS px,
  and the calibration's own 3D check (mm) and time.

The lines "no board corner in N of 16 image regions" are gaitcap's own coverage warnings.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from gaitcap.errors import GaitcapError  # noqa: E402
from gaitcap.calibration.boards import Board, detect_board  # noqa: E402
from gaitcap.calibration.extrinsics import (  # noqa: E402
    ScenePoints,
    calibrate_from_board,
    calibrate_stereo,
    scene_pixel_disagreement,
    scene_reprojection,
)
from gaitcap.calibration.formats import read_opencv_camera, read_qualisys  # noqa: E402
from gaitcap.calibration.intrinsics import calibrate_intrinsics  # noqa: E402
from gaitcap.calibration.synthetic import render_board_view  # noqa: E402
from gaitcap.calibration.views import detect_views  # noqa: E402
from gaitcap.camera import Camera  # noqa: E402
from gaitcap.config import load_yaml_model  # noqa: E402
from gaitcap.io.calibration_toml import read_calibration, write_calibration  # noqa: E402

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def opencv_sample(data: Path) -> None:
    d = data / "calibration" / "opencv_chessboard_9x6"
    board = Board(9, 6, 0.025)
    ref = read_opencv_camera(d / "left_intrinsics.yml")
    lv = detect_views(sorted(d.glob("left*.jpg")), board, max_blur=0.25)
    res = calibrate_intrinsics(lv.detections, board, "left", fix_aspect_ratio=True)
    K, R = res.camera.matrix, ref.matrix
    print("\n## OpenCV sample, 13 left images, CALIB_FIX_ASPECT_RATIO")
    print(f"{'':6}{'fx':>10}{'fy':>10}{'cx':>10}{'cy':>10}{'RMS px':>9}")
    print(f"{'ours':6}{K[0, 0]:10.3f}{K[1, 1]:10.3f}{K[0, 2]:10.3f}{K[1, 2]:10.3f}{res.rms_px:9.4f}")
    print(f"{'ref':6}{R[0, 0]:10.3f}{R[1, 1]:10.3f}{R[0, 2]:10.3f}{R[1, 2]:10.3f}{0.39259:9.4f}")
    print(f"{'diff':6}{K[0, 0] - R[0, 0]:10.3f}{K[1, 1] - R[1, 1]:10.3f}{K[0, 2] - R[0, 2]:10.3f}{K[1, 2] - R[1, 2]:10.3f}{res.rms_px - 0.39259:9.4f}")
    rv = detect_views(sorted(d.glob("right*.jpg")), board, max_blur=0.25)
    cr = calibrate_intrinsics(rv.detections, board, "right", fix_aspect_ratio=True).camera
    pairs = [(a, b) for a, b in zip(lv.frames, rv.frames) if a is not None and b is not None]
    st = calibrate_stereo(res.camera, cr, pairs, board)
    print(f"stereo: {st.n_pairs} pairs, RMS {st.rms_px:.4f} px, baseline {st.baseline_m * 1000:.2f} mm, "
          f"mean epipolar error {st.epipolar_px:.4f} px, right camera centre {np.round(st.rig['right'].center * 1000, 1)} mm")


def pose2sim_intrinsics(data: Path) -> None:
    d = data / "calibration" / "pose2sim_qualisys_4cam" / "calibration"
    qual = read_qualisys(d / "Calib.qca.txt")
    board = Board(4, 7, 0.06)
    print("\n## Pose2Sim demo checkerboards (4x7, 60 mm) vs Qualisys")
    print(f"{'cam':6}{'views':>6}{'fx':>10}{'fy':>10}{'ref fx':>10}{'ref fy':>10}{'dfx %':>8}{'dfy %':>8}{'dcx px':>8}{'dcy px':>8}{'RMS':>7}")
    for name in qual.names:
        views = detect_views([d / "intrinsics" / f"int_{name}_img"], board, max_blur=0.25)
        res = calibrate_intrinsics(views.detections, board, name)
        K, R = res.camera.matrix, qual[name].matrix
        print(f"{name:6}{len(views.detections):6d}{K[0, 0]:10.1f}{K[1, 1]:10.1f}{R[0, 0]:10.1f}{R[1, 1]:10.1f}"
              f"{100 * (K[0, 0] / R[0, 0] - 1):8.2f}{100 * (K[1, 1] / R[1, 1] - 1):8.2f}"
              f"{K[0, 2] - R[0, 2]:8.1f}{K[1, 2] - R[1, 2]:8.1f}{res.rms_px:7.3f}")


QUALISYS_FIX = REPO / "tests" / "fixtures" / "calibration" / "pose2sim_qualisys"
# Floor-point pixels derived from Pose2Sim's two scene calibrations (scripts/derive_floor_reference.py).
FLOOR_REFERENCES = {"Demo": QUALISYS_FIX / "floor_points_demo.yaml", "SinglePerson": QUALISYS_FIX / "floor_points_singleperson.yaml"}


def _mean_max(errs: dict[str, float]) -> str:
    v = list(errs.values())
    return f"{np.mean(v):6.1f} {np.max(v):6.1f}"


def qualisys_scene(data: Path, overlay: Path | None = None) -> None:
    calib = data / "calibration" / "pose2sim_qualisys_4cam" / "calibration"
    with tempfile.TemporaryDirectory() as tmp:  # the imported calibration as the session would hold it
        write_calibration(Path(tmp) / "calibration.toml", read_qualisys(calib / "Calib.qca.txt"))
        qual = read_calibration(Path(tmp) / "calibration.toml")
    scene = load_yaml_model(ScenePoints, QUALISYS_FIX / "scene_points.yaml")
    print("\n## Imported Qualisys calibration: reprojection of the hand-located scene points (px)")
    for cam, errs in scene_reprojection(qual, scene).items():
        print(f"{cam:6} " + "  ".join(f"{k} {v:5.1f}" for k, v in errs.items()) + f"   mean {np.mean(list(errs.values())):5.1f}")
    refs = {k: load_yaml_model(ScenePoints, p) for k, p in FLOOR_REFERENCES.items()}
    vs = {k: scene_reprojection(qual, ref) for k, ref in refs.items()}
    noise = scene_pixel_disagreement(*refs.values())
    print("\n## Imported Qualisys calibration (calibration.toml) vs the 8 floor points clicked for Pose2Sim's scene calibrations (px)")
    print(f"{'':6}" + "".join(f"{'vs ' + k:>17}" for k in refs) + f"{'click noise':>14}")
    print(f"{'cam':6}" + f"{'mean    max':>17}" * len(refs) + f"{'mean    max':>14}")
    for cam in qual.names:
        print(f"{cam:6}" + "".join(f"{_mean_max(vs[k][cam]):>17}" for k in refs) + f"{_mean_max(noise[cam]):>14}")
    every = [v for table in noise.values() for v in table.values()]
    print(f"click noise over all cameras: mean {np.mean(every):.1f} px, max {np.max(every):.1f} px")
    if overlay is not None:
        _draw_floor_points(qual, refs, calib / "extrinsics", overlay)
    vids = data / "calibration" / "pose2sim_qualisys_4cam" / "videos"
    for cam in qual:
        cap = cv2.VideoCapture(str(vids / f"{cam.name}.mp4"))
        ok, frame = cap.read()
        cap.release()
        if ok:
            print(f"{cam.name}: video {frame.shape[1]}x{frame.shape[0]}, calibration {cam.width}x{cam.height}")


def _draw_floor_points(rig, refs: dict[str, ScenePoints], ext_dir: Path, out_dir: Path) -> None:
    """camNN_ext.png with the references (circles: green, blue) and our projection (red crosses)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    colours = [(0, 200, 0), (255, 128, 0)]
    names = list(next(iter(refs.values())).points)
    for cam in rig:
        img = cv2.imread(str(ext_dir / f"{cam.name}_ext.png"))
        if img is None:
            print(f"{cam.name}: no {cam.name}_ext.png in {ext_dir}")
            continue
        for colour, ref in zip(colours, refs.values()):
            for uv in ref.pixels[cam.name].values():
                if uv is not None:
                    cv2.circle(img, tuple(int(round(c)) for c in uv), 9, colour, 2, cv2.LINE_AA)
        ours = cam.project(np.array([refs["Demo"].points[n] for n in names]))
        for n, uv in zip(names, ours):
            p = tuple(int(round(c)) for c in uv)
            cv2.drawMarker(img, p, (0, 0, 255), cv2.MARKER_CROSS, 18, 2, cv2.LINE_AA)
            cv2.putText(img, n, (p[0] + 8, p[1] - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 255), 1, cv2.LINE_AA)
        cv2.imwrite(str(out_dir / f"{cam.name}_floor_points.png"), img)
    print(f"overlays (green: Demo, blue: SinglePerson, red: ours) in {out_dir}")


def synthetic_floor(seed: int = 0) -> None:
    board = Board(9, 6, 0.12)
    t = [0.5, -0.3, 0.0]
    truth = [Camera.look_at("c1", [2.5, -2.0, 2.2], t, focal_px=800, dist=(-0.1, 0.02, 0.0, 0.0)),
             Camera.look_at("c2", [-1.5, -2.5, 2.0], t, focal_px=800),
             Camera.look_at("c3", [0.8, 2.2, 2.5], t, focal_px=700)]
    poses = [(np.zeros(3), np.zeros(3)), (np.array([0, 0, 0.5]), np.array([-0.3, 0.4, 0])),
             (np.array([0, 0, -0.4]), np.array([0.3, -0.5, 0])), (np.array([0, 0, 1.2]), np.array([0.0, 0.6, 0]))]
    rng = np.random.default_rng(seed)
    frames = {c.name: [detect_board(render_board_view(c, board, p, rng, noise=3.0), board, f"{c.name}#{k}") for k, p in enumerate(poses)]
              for c in truth}
    intr = [Camera(c.name, c.size, c.matrix, c.dist) for c in truth]
    print("\n## Synthetic floor board (9x6, 120 mm, 640x480, noise 3 grey levels), 3 cameras")
    for label, fr in (("1 position (solvePnP)", {k: v[:1] for k, v in frames.items()}), (f"{len(poses)} positions (bundle adj.)", frames)):
        t0 = time.perf_counter()
        res = calibrate_from_board(intr, fr, board)
        dt = time.perf_counter() - t0
        for est, true in zip(res.rig, truth):
            ang = np.degrees(np.linalg.norm(cv2.Rodrigues(est.R @ true.R.T)[0]))
            print(f"{label:28} {est.name}: position error {np.linalg.norm(est.center - true.center) * 1000:6.2f} mm, "
                  f"rotation error {ang:6.3f} deg, RMS {res.rms_px[est.name]:.3f} px")
        print(f"{label:28} 3D check {res.check_mm:.2f} mm, {dt:.2f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--only", choices=["opencv", "pose2sim", "qualisys", "synthetic"], help="run one section only")
    ap.add_argument("--overlay", type=Path, help="write camNN_floor_points.png overlays of the floor points here")
    args = ap.parse_args()
    if not args.data.is_dir():
        ap.error(f"--data {args.data}: no such folder (the shared data; by default ../shared/data beside the checkout)")
    sections = {
        "opencv": lambda: opencv_sample(args.data),
        "pose2sim": lambda: pose2sim_intrinsics(args.data),
        "qualisys": lambda: qualisys_scene(args.data, args.overlay),
        "synthetic": synthetic_floor,
    }
    for name, run in sections.items():
        if args.only in (None, name):
            run()


if __name__ == "__main__":
    try:
        main()
    except GaitcapError as e:  # a file of the data missing or unreadable
        sys.exit(f"error: {e}")
