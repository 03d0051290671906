"""CPU cost of the floor check's same-ratio rule (``shadow.floor_same_ratio``) per frame pair.

Runs ``JointExtractor.process`` over the first frames of a calibrated session with the rule off
and on, alternately (``--rounds`` times each: the machine's noise shows in the spread), one
OpenCV thread, and prints the median CPU milliseconds (``time.process_time``) per frame of each
round and their medians.

    PYTHONPATH=src python scripts/bench_floor_check.py SESSION [--frames 60] [--rounds 4]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import cv2

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from gaitcap.silhouette.config import SilhouetteConfig  # noqa: E402
from gaitcap.silhouette.joint import JointExtractor  # noqa: E402
from gaitcap.silhouette.run import prepare_extractor, sources_from_session  # noqa: E402
from gaitcap.video import VideoReader  # noqa: E402


def round_ms(session: Path, frames: dict[str, list], same_ratio: bool) -> float:
    """Median CPU ms per frame of one pass over ``frames`` with the rule ``same_ratio``."""
    sources = sources_from_session(session)
    config = SilhouetteConfig.load()
    config.shadow.floor_same_ratio = same_ratio
    joint = JointExtractor([prepare_extractor(s, config)[0] for s in sources], [s.calibration for s in sources])
    times = []
    for k in range(min(len(v) for v in frames.values())):
        t0 = time.process_time()
        joint.process([frames[s.camera][k] for s in sources])
        times.append(time.process_time() - t0)
    return 1000 * statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("session", type=Path)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--rounds", type=int, default=4)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    frames = {s.camera: [f for i, f in VideoReader(s.video) if i < args.frames] for s in sources_from_session(args.session)}
    rounds: dict[bool, list[float]] = {False: [], True: []}
    for _ in range(args.rounds):
        for same in (False, True):
            rounds[same].append(round_ms(args.session, frames, same))
    print("| floor_same_ratio | CPU ms per frame pair, each round | median |")
    print("|---|---|---|")
    for same, values in rounds.items():
        print(f"| {str(same).lower()} | {' / '.join(f'{v:.1f}' for v in values)} | {statistics.median(values):.1f} |")


if __name__ == "__main__":
    main()
