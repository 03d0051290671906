"""Silhouette extraction per frame pair: CPU cost, and whether its outputs stay byte-identical.

    PYTHONPATH=src python scripts/check_silhouettes_identical.py SESSION... [--frames N] [--save REF.json]
    PYTHONPATH=src python scripts/check_silhouettes_identical.py SESSION... [--frames N] [--against REF.json]

Runs the calibrated sessions' cameras together, as ``gaitcap track`` does (backgrounds fitted by
``prepare_extractor``, then ``JointExtractor.process_soft`` frame by frame, one camera after the
other in this thread), and prints per session a table row: frames, CPU milliseconds per frame
(all cameras) of the decoding and of the extraction (``time.process_time``: the process's CPU
time, not disturbed much by other jobs on the machine), and, with ``--against``, whether every
frame's outputs equal the reference's. Each frame of each camera is reduced to a SHA-256 of its
full-resolution mask, its soft silhouette and its quality record (``--save`` writes them to a
JSON file); the check exits 1 when a session differs or has no reference in the file (a session is
known by its resolved path: compare on the same folders as saved).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from gaitcap.errors import GaitcapError
from gaitcap.session import Session
from gaitcap.silhouette.config import SilhouetteConfig
from gaitcap.silhouette.joint import JointExtractor
from gaitcap.silhouette.run import Source, prepare_extractor
from gaitcap.video import iter_synchronised


def digest(mask: np.ndarray, soft: np.ndarray, quality: object) -> str:
    """SHA-256 of one camera's outputs for one frame: mask (H, W) uint8, soft (H, W) float32, quality."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mask).tobytes())
    h.update(np.ascontiguousarray(soft).tobytes())
    h.update(repr(quality).encode())
    return h.hexdigest()


def run(session: Path, max_frames: int | None) -> tuple[list[list[str]], float, float]:
    """(digests per frame per camera, decoding CPU s, extraction CPU s) of one session."""
    ses = Session.open(session)
    cfg = SilhouetteConfig.load()
    cams = ses.rig.names
    extractors = [prepare_extractor(Source(c, ses.videos[c], ses.backgrounds.get(c)), cfg)[0] for c in cams]
    joint = JointExtractor(extractors, [ses.rig[c] for c in cams])
    digests: list[list[str]] = []
    decode = extract = 0.0
    frames = iter_synchronised({c: ses.videos[c] for c in cams}, 0, max_frames)
    while True:
        t0 = time.process_time()
        item = next(frames, None)
        t1 = time.process_time()
        decode += t1 - t0
        if item is None:
            break
        out = joint.process_soft([item[1][c] for c in cams])
        extract += time.process_time() - t1
        digests.append([digest(m, s, q) for m, s, q in out])
    return digests, decode, extract


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sessions", type=Path, nargs="+")
    p.add_argument("--frames", type=int, default=None, help="at most this many frames per session")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--save", type=Path, help="write the per-frame digests here (JSON)")
    g.add_argument("--against", type=Path, help="compare with the digests saved here")
    args = p.parse_args()
    ref: dict[str, list[list[str]]] = {}
    if args.against:
        try:
            ref = json.loads(args.against.read_text())
        except (OSError, ValueError) as e:
            sys.exit(f"error: --against {args.against}: cannot read the saved digests ({e})")
    try:
        for session in args.sessions:  # a wrong path ends the check before any work
            Session.open(session)
    except GaitcapError as e:
        sys.exit(f"error: {e}")
    saved: dict[str, list[list[str]]] = {}
    print("| session | frames | decode ms/frame (CPU) | extract ms/frame (CPU) | identical |")
    print("|---|---|---|---|---|")
    status = 0
    for session in args.sessions:
        digests, decode, extract = run(session, args.frames)
        n = max(len(digests), 1)
        key = str(session.resolve())
        saved[key] = digests
        same = "-"
        if args.against:
            want = ref.get(key)
            if want is None:
                same = "no reference"
                status = 1
            else:
                diff = next((i for i, (a, b) in enumerate(zip(digests, want)) if a != b), None)
                if args.frames is not None:
                    want = want[: len(digests)]
                if diff is None and len(digests) == len(want):
                    same = "yes"
                else:
                    same = f"no (frame {diff if diff is not None else min(len(digests), len(want))})"
                    status = 1
        print(f"| {session.name} | {len(digests)} | {1000 * decode / n:.1f} | {1000 * extract / n:.1f} | {same} |",
              flush=True)  # fmt: skip
    if args.save:
        args.save.write_text(json.dumps(saved))
    return status


if __name__ == "__main__":
    sys.exit(main())
