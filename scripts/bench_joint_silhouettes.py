"""CPU cost of a calibrated session's silhouettes, as ``gaitcap track`` extracts them, per frame.

    PYTHONPATH=src python scripts/bench_joint_silhouettes.py SESSION [SESSION ...] [--frames 60]
        [--rounds 3] [--set shadow.floor_same_ratio=false ...]

Each session's first ``--frames`` frames are decoded once. Then ``JointExtractor.process`` (every
camera in turn, the floor check across them) runs over them ``--rounds`` times on one OpenCV thread,
with the shipped silhouette.yaml and, when given, with each ``--set SECTION.KEY=VALUE`` in turn
(alternately, round by round: the machine's noise shows in the spread). Prints per session and
configuration the CPU milliseconds (``time.process_time``) per frame of all cameras, each round and
their median, and, over the frames and cameras, the median share of the image taken by the bounding
box of the foreground candidates (the shadow test and the floor check run in it).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from gaitcap.config import model_from_mapping, parse_yaml
from gaitcap.errors import ConfigError, GaitcapError
from gaitcap.session import Session
from gaitcap.silhouette.config import SilhouetteConfig
from gaitcap.silhouette.joint import JointExtractor
from gaitcap.silhouette.run import prepare_extractor, sources_from_session
from gaitcap.video import VideoReader


def configured(override: str | None) -> SilhouetteConfig:
    """The shipped configuration, with ``SECTION.KEY=VALUE`` set (None: as shipped), validated by the
    schema (:func:`~gaitcap.config.model_from_mapping`: an unknown key is named, with the closest one)."""
    config = SilhouetteConfig.load()
    if override is None:
        return config
    key, sep, value = override.partition("=")
    if not sep:
        raise ConfigError(f"--set {override}: expected SECTION.KEY=VALUE")
    data = config.model_dump()
    *sections, name = key.split(".")
    target = data
    for section in sections:
        target = target.setdefault(section, {})
        if not isinstance(target, dict):
            raise ConfigError(f"--set {override}: {section} is not a section")
    target[name] = parse_yaml(value)
    return model_from_mapping(SilhouetteConfig, data, "--set")


def one_round(session: Path, frames: list[list[np.ndarray]], config: SilhouetteConfig) -> tuple[float, list[float]]:
    """CPU ms per frame of one pass over ``frames`` (per frame, one image per camera), and per frame
    and camera the share of the image taken by the candidates' bounding box."""
    sources = sources_from_session(session)
    joint = JointExtractor([prepare_extractor(s, config)[0] for s in sources], [s.calibration for s in sources])
    candidates, cpu = [], 0.0
    for images in frames:
        t0 = time.process_time()
        evidence, shadows = joint.observe(images)
        joint.finish(evidence, shadows)
        cpu += time.process_time() - t0
        for e in evidence:
            _, _, w, h = cv2.boundingRect(e.candidate.view(np.uint8))
            candidates.append(w * h / e.candidate.size)
    return 1000 * cpu / len(frames), candidates


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sessions", type=Path, nargs="+")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                    help="a configuration to compare with the shipped one (repeatable)")  # fmt: skip
    args = ap.parse_args()
    cv2.setNumThreads(1)
    variants: list[str | None] = [None, *args.overrides]
    try:
        for v in args.overrides:  # before any session is decoded
            configured(v)
        for session in args.sessions:  # a wrong path ends the script before any work
            Session.open(session)
    except GaitcapError as e:
        raise SystemExit(f"error: {e}") from None
    print("| session | cameras | configuration | CPU ms per frame, each round | median | per camera-frame | "
          "candidates' box, share of the image |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for session in args.sessions:
        readers = [VideoReader(s.video) for s in sources_from_session(session)]
        frames = [[image for _, image in pair] for _, pair in zip(range(args.frames), zip(*readers))]
        for reader in readers:
            reader.close()
        ms: dict[str | None, list[float]] = {v: [] for v in variants}
        shares: dict[str | None, list[float]] = {}
        for _ in range(args.rounds):
            for v in variants:
                cost, shares[v] = one_round(session, frames, configured(v))
                ms[v].append(cost)
        n_cams = len(frames[0])
        for v in variants:
            med = statistics.median(ms[v])
            rounds = " / ".join(f"{m:.1f}" for m in ms[v])
            print(f"| {session.name} | {n_cams} | {v or 'shipped'} | {rounds} | {med:.1f} | {med / n_cams:.1f} | "
                  f"{statistics.median(shares[v]):.2f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
