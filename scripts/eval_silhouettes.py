"""Silhouette quality: IoU on synthetic sessions, and the checks on real videos.

1. Synthetic (``gaitcap synth``, ground-truth masks in truth.h5): mean IoU per camera of the masks
   extracted as ``gaitcap track`` extracts them (the cameras together, shadows checked on the floor),
   with shadow suppression on and off, background from the plate and from the video alone, for
   sessions of two look seeds (person, clothes, room and light drawn by ``gaitcap synth --seed``);
   "no usable bg": the camera's background could not be estimated from its video alone.
   The varied suite, ``scripts/bench_suite.py``, measures IoU over many more.
2. Real, ``video/sports2d_walk/walk.mp4`` (no plate): foreground fraction over time
   (CSV + PNG plot) and a few overlay frames to look at.
3. Real, Pose2Sim 4-camera videos (the subject never leaves): the background usability check.

    python scripts/eval_silhouettes.py                       # everything, into out/eval_silhouettes
    python scripts/eval_silhouettes.py --only synth --size 640x480
    python scripts/eval_silhouettes.py --data /path/to/shared/data
"""

from __future__ import annotations

import argparse
import csv
import logging
import os
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from gaitcap.errors import GaitcapError  # noqa: E402
from gaitcap.config import model_from_mapping  # noqa: E402
from gaitcap.evaluation.metrics import mask_iou  # noqa: E402
from gaitcap.io.silhouettes_h5 import read_masks  # noqa: E402
from gaitcap.session import Session  # noqa: E402
from gaitcap.silhouette import SilhouetteConfig, SilhouetteExtractor  # noqa: E402
from gaitcap.silhouette.overlay import draw_overlay  # noqa: E402
from gaitcap.silhouette.joint import JointExtractor  # noqa: E402
from gaitcap.silhouette.run import Source, prepare_extractor  # noqa: E402
from gaitcap.video import VideoReader, iter_synchronised, sample_frames  # noqa: E402

DEFAULT_DATA = REPO.parent / "shared" / "data"
log = logging.getLogger("eval_silhouettes")


def synth(session: Path, args: argparse.Namespace, seed: int) -> None:
    if session.exists():
        return
    cmd = [sys.executable, "-m", "gaitcap", "-q", "synth", "-o", str(session), "--size", args.size, "--seed", str(seed)]
    env = dict(os.environ, PYTHONPATH=str(REPO / "src"))
    subprocess.run(cmd, check=True, env=env)


def session_ious(session: Path, config: SilhouetteConfig, use_plate: bool) -> dict[str, float]:
    """Mean IoU per camera over the frames where the true mask is not empty, of the masks extracted as
    ``gaitcap silhouettes`` and ``gaitcap track`` extract a calibrated session's: every camera's frame
    together, with the shadows checked on the floor across the cameras (:class:`JointExtractor`)."""
    s = Session.open(session)
    cams = s.camera_names
    extractors = [prepare_extractor(Source(c, s.videos[c], s.backgrounds.get(c) if use_plate else None), config)[0]
                  for c in cams]  # fmt: skip
    joint = JointExtractor(extractors, [s.rig[c] for c in cams])
    truth = {c: read_masks(session / "truth.h5", c) for c in cams}
    scores: dict[str, list[float]] = {c: [] for c in cams}
    for k, images in iter_synchronised({c: s.videos[c] for c in cams}, 0, None):
        for c, (mask, _) in zip(cams, joint.process([images[c] for c in cams])):
            if k < len(truth[c]) and truth[c][k].any():
                scores[c].append(float(mask_iou(mask[None], truth[c][k][None])[0]))
    out = {c: float(np.mean(scores[c])) for c in cams}
    for c, ex in zip(cams, extractors):
        if ex.report is not None and not ex.report.usable:
            out[c + " (no usable bg)"] = out[c]
    return out


def run_synth(args: argparse.Namespace, folder: Path) -> None:
    rows = []
    print(f"\n## Synthetic sessions ({args.size}, look seeds {args.seed} and {args.seed + 1})\n")
    print("| seed | background | shadow suppression | " + " | ".join(f"IoU {c}" for c in ("cam1", "cam2")) + " |")
    print("|---|---|---|---|---|")
    for seed in (args.seed, args.seed + 1):
        session = folder / f"synth_seed{seed}_{args.size}"
        synth(session, args, seed)
        for use_plate in (True, False):
            for shadow in (True, False):
                cfg = model_from_mapping(SilhouetteConfig, {"shadow": {"enabled": shadow}}, "eval")
                res = session_ious(session, cfg, use_plate)
                bg = "plate" if use_plate else "video median"
                cams = [k for k in res if "(" not in k]
                notes = [k for k in res if "(" in k]
                print(f"| {seed} | {bg} | {'on' if shadow else 'off'} | "
                      + " | ".join(f"{res[c]:.3f}" for c in cams) + " |" + (f" {notes}" if notes else ""), flush=True)
                rows.append([seed, bg, shadow] + [res[c] for c in cams])
    with (folder / "synth_iou.csv").open("w", newline="") as fh:
        csv.writer(fh).writerows([["seed", "background", "shadow", "iou_cam1", "iou_cam2"], *rows])


def run_sports2d(data: Path, folder: Path, frames_to_show: list[int]) -> None:
    video = data / "video" / "sports2d_walk" / "walk.mp4"
    print(f"\n## Real video {video.name} (no plate: temporal median of 31 frames)\n")
    cfg = SilhouetteConfig()
    ex = SilhouetteExtractor(cfg, name=video.name)
    t0 = time.perf_counter()
    report = ex.fit_background(samples=sample_frames(video, cfg.background.samples))
    print(f"background: {report.message} (fit {time.perf_counter() - t0:.1f} s)")
    fractions, flags = [], []
    shots = []
    t0 = time.perf_counter()
    with VideoReader(video) as reader:
        fps = reader.info.fps
        for k, frame in reader:
            mask, q = ex.process(frame)
            fractions.append(q.fraction)
            flags.append(",".join(q.flag_names))
            if k in frames_to_show:
                shot = draw_overlay(frame, mask, q)
                cv2.imwrite(str(folder / f"walk_overlay_{k:04d}.jpg"), shot)
                shots.append(cv2.resize(shot, (shot.shape[1] // 2, shot.shape[0] // 2)))
    dt = time.perf_counter() - t0
    print(f"{len(fractions)} frames in {dt:.1f} s ({len(fractions) / dt:.1f} fps, extraction + decoding)")
    with (folder / "walk_fraction.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frame", "time_s", "fraction", "flags"])
        for k, (f, fl) in enumerate(zip(fractions, flags)):
            w.writerow([k, f"{k / fps:.3f}", f"{f:.5f}", fl])
    if shots:
        rows = [np.hstack(shots[i : i + 2]) for i in range(0, len(shots) - 1, 2)]
        cv2.imwrite(str(folder / "walk_overlays.jpg"), np.vstack(rows))
    fr = np.array(fractions)
    print("foreground fraction (%) every 10 frames: "
          + " ".join(f"{k}:{100 * fr[k]:.2f}" for k in range(0, len(fr), 10)))
    counts = {name: sum(name in f.split(",") for f in flags) for name in ("empty", "border", "too_large")}
    print(f"flagged frames: {counts}")
    _plot_fraction(fr, fps, folder / "walk_fraction.png")


def _plot_fraction(fr: np.ndarray, fps: float, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 2.5))
    ax.plot(np.arange(len(fr)) / fps, 100 * fr)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("foreground (%)")
    ax.set_title("walk.mp4: foreground fraction")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def run_pose2sim(data: Path) -> None:
    folder = data / "calibration" / "pose2sim_qualisys_4cam" / "videos"
    print("\n## Pose2Sim 4-camera videos (subject never leaves the view)\n")
    print("| video | ambiguous pixels | usable |")
    print("|---|---|---|")
    cfg = SilhouetteConfig()
    for video in sorted(folder.glob("cam*.mp4")):
        ex = SilhouetteExtractor(cfg, name=video.name)
        report = ex.fit_background(samples=sample_frames(video, cfg.background.samples))
        print(f"| {video.name} | {100 * report.ambiguous_fraction:.2f}% | {report.usable} |")
    walk = data / "video" / "sports2d_walk" / "walk.mp4"
    ex = SilhouetteExtractor(cfg, name=walk.name)
    report = ex.fit_background(samples=sample_frames(walk, cfg.background.samples))
    print(f"| {walk.name} (for comparison) | {100 * report.ambiguous_fraction:.2f}% | {report.usable} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the shared data folder")
    ap.add_argument("--out", type=Path, default=REPO / "out" / "eval_silhouettes")
    ap.add_argument("--only", choices=["synth", "sports2d", "pose2sim"], action="append")
    ap.add_argument("--size", default="640x480")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--show", type=int, nargs="+", default=[20, 60, 100, 140, 180, 220])
    args = ap.parse_args()
    if not args.data.is_dir():
        ap.error(f"--data {args.data}: no such folder (the shared data; by default ../shared/data beside the checkout)")
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    args.out.mkdir(parents=True, exist_ok=True)
    parts = args.only or ["synth", "sports2d", "pose2sim"]
    if "synth" in parts:
        run_synth(args, args.out)
    if "sports2d" in parts:
        run_sports2d(args.data, args.out, args.show)
    if "pose2sim" in parts:
        run_pose2sim(args.data)


if __name__ == "__main__":
    try:
        main()
    except GaitcapError as e:  # a file of the data missing or unreadable
        sys.exit(f"error: {e}")
