"""Measure gaitcap's calibration against the references in ../shared/data (prints a table).

    python scripts/check_calibration.py [--data PATH]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from gaitcap.calibration.boards import Board, detect_board  # noqa: E402
from gaitcap.calibration.extrinsics import ScenePoints, calibrate_from_board, calibrate_stereo, scene_reprojection  # noqa: E402
from gaitcap.calibration.formats import read_opencv_camera, read_qualisys  # noqa: E402
from gaitcap.calibration.intrinsics import calibrate_intrinsics  # noqa: E402
from gaitcap.calibration.synthetic import render_board_view  # noqa: E402
from gaitcap.calibration.views import detect_views  # noqa: E402
from gaitcap.camera import Camera  # noqa: E402
from gaitcap.config import load_yaml_model  # noqa: E402

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


def qualisys_scene(data: Path) -> None:
    qual = read_qualisys(data / "calibration" / "pose2sim_qualisys_4cam" / "calibration" / "Calib.qca.txt")
    scene = load_yaml_model(ScenePoints, REPO / "tests" / "fixtures" / "calibration" / "pose2sim_qualisys" / "scene_points.yaml")
    print("\n## Imported Qualisys calibration: reprojection of the located scene points (px)")
    for cam, errs in scene_reprojection(qual, scene).items():
        print(f"{cam:6} " + "  ".join(f"{k} {v:5.1f}" for k, v in errs.items()) + f"   mean {np.mean(list(errs.values())):5.1f}")
    vids = data / "calibration" / "pose2sim_qualisys_4cam" / "videos"
    for cam in qual:
        cap = cv2.VideoCapture(str(vids / f"{cam.name}.mp4"))
        ok, frame = cap.read()
        cap.release()
        if ok:
            print(f"{cam.name}: video {frame.shape[1]}x{frame.shape[0]}, calibration {cam.width}x{cam.height}")


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
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    args = ap.parse_args()
    opencv_sample(args.data)
    pose2sim_intrinsics(args.data)
    qualisys_scene(args.data)
    synthetic_floor()


if __name__ == "__main__":
    main()
