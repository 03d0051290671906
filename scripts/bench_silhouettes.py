"""Throughput of silhouette extraction, frames per second per camera, on this machine.

Measures, for each frame size, the decoding of an MPEG-4 video (gaitcap.video.VideoReader),
the extraction alone (SilhouetteExtractor.process on decoded frames) and both together,
at working scale 1.0 and 0.5. Prints a Markdown table.

    python scripts/bench_silhouettes.py                     # 640x480 and 1920x1080
    python scripts/bench_silhouettes.py --sizes 1280x720 --frames 60
"""

from __future__ import annotations

import argparse
import platform
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from gaitcap.config import model_from_mapping  # noqa: E402
from gaitcap.io.video_write import AtomicVideoWriter as VideoWriter  # noqa: E402
from gaitcap.silhouette import SilhouetteConfig, SilhouetteExtractor  # noqa: E402
from gaitcap.video import VideoReader  # noqa: E402


def make_frames(w: int, h: int, n: int, seed: int = 0) -> tuple[np.ndarray, list[np.ndarray]]:
    """A textured plate and ``n`` frames of a dark figure with a shadow crossing it, with noise."""
    rng = np.random.default_rng(seed)
    tex = cv2.GaussianBlur(rng.normal(0, 1, (h, w)).astype(np.float32), (0, 0), 2.0)
    plate = np.clip(128 + 12 * tex / tex.std(), 0, 255).astype(np.uint8)
    plate = cv2.cvtColor(plate, cv2.COLOR_GRAY2BGR)
    frames = []
    for k in range(n):
        img = plate.astype(np.float32)
        cx, cy = int((0.1 + 0.8 * k / max(n - 1, 1)) * w), int(0.55 * h)
        cv2.ellipse(img, (cx + w // 12, int(0.88 * h)), (w // 10, h // 30), 0, 0, 360, (70, 70, 70), -1)
        cv2.ellipse(img, (cx, cy), (w // 25, h // 3), 0, 0, 360, (40, 40, 45), -1)
        img += rng.normal(0, 3, img.shape).astype(np.float32)
        frames.append(np.clip(img, 0, 255).astype(np.uint8))
    return plate, frames


def bench(w: int, h: int, n: int, scale: float, folder: Path) -> dict[str, float]:
    plate, frames = make_frames(w, h, n)
    video = folder / f"bench_{w}x{h}.mp4"
    if not video.exists():
        with VideoWriter(video, 25.0, (w, h)) as out:
            for f in frames:
                out.write(f)
    t0 = time.perf_counter()
    with VideoReader(video) as reader:
        decoded = sum(1 for _ in reader)
    t_decode = time.perf_counter() - t0

    cfg = model_from_mapping(SilhouetteConfig, {"scale": scale}, "bench")
    ex = SilhouetteExtractor(cfg)
    ex.fit_background(plate=plate, samples=np.stack(frames[:: max(1, n // 10)]))
    ex.process(frames[0])  # warm-up
    t0 = time.perf_counter()
    for f in frames:
        ex.process(f)
    t_extract = time.perf_counter() - t0

    ex = SilhouetteExtractor(cfg)
    ex.fit_background(plate=plate, samples=np.stack(frames[:: max(1, n // 10)]))
    t0 = time.perf_counter()
    with VideoReader(video) as reader:
        for _, f in reader:
            ex.process(f)
    t_both = time.perf_counter() - t0
    return {"decode": decoded / t_decode, "extract": n / t_extract, "both": decoded / t_both}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", nargs="+", default=["640x480", "1920x1080"])
    ap.add_argument("--scales", nargs="+", type=float, default=[1.0, 0.5])
    ap.add_argument("--frames", type=int, default=60)
    args = ap.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, OpenCV {cv2.__version__}, "
          f"{cv2.getNumberOfCPUs()} CPUs, {cv2.getNumThreads()} OpenCV threads; {args.frames} frames each\n")
    print("| size | scale | decode fps | extract fps | decode+extract fps |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for size in args.sizes:
            w, h = map(int, size.lower().split("x"))
            for scale in args.scales:
                r = bench(w, h, args.frames, scale, Path(tmp))
                print(f"| {w}x{h} | {scale:g} | {r['decode']:.1f} | {r['extract']:.1f} | {r['both']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
