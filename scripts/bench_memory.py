"""Peak memory of ``gaitcap track`` against video length: does it stream?

    PYTHONPATH=src python scripts/bench_memory.py [--session SESSION] [--work /tmp/gaitcap-bench]
        [--seconds 5 20] [--fps 25] [-- extra gaitcap track options, e.g. --tracker ipf]

Takes a synthetic session (default: the embedded walk, rendered once into --work), builds longer
sessions from it by playing its videos forwards then backwards, again and again (a ping-pong
loop: the subject never jumps, so the tracker follows one continuous motion), to each length of
--seconds at --fps (written with gaitcap.io.video_write.AtomicVideoWriter; calibration.toml,
background/ and session.yaml copied), then runs ``python -m gaitcap -q track`` on each in a
child process and prints a markdown table: video seconds, frames, the child's peak resident set
size (``ru_maxrss`` from ``os.wait4``), wall seconds and ms/frame (track.json's seconds / frames).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from gaitcap.data import embedded_walk
from gaitcap.errors import GaitcapError
from gaitcap.io.trc import write_trc
from gaitcap.io.video_write import AtomicVideoWriter
from gaitcap.markers.motion import read_motion
from gaitcap.session import BACKGROUND_DIR, CALIBRATION_FILE, SESSION_FILE, VIDEOS_DIR, Session
from gaitcap.synth.session import TRUTH_FILE, SynthOptions, synthesize
from gaitcap.video import VideoReader, probe_video

REPO = Path(__file__).resolve().parents[1]


def base_session(work: Path, fps: float) -> Path:
    """The embedded walk rendered at ``fps`` (cached in ``work``)."""
    root = work / f"embedded-walk-{fps:g}fps"
    if not (root / TRUTH_FILE).is_file():
        synthesize(embedded_walk(), root, SynthOptions(fps=fps), force=True, progress=False)
    return root


def turn_session(work: Path, n_frames: int, fps: float, turn_s: float = 1.0) -> Path:
    """The embedded walk up and down a walkway, as a lab records a longer clip: the walk (2.2 s), a
    standing pivot of 180 degrees over ``turn_s`` seconds, the walk back over the same ground (its
    last stride twice, 2.3 s), and so on (``make_turn_walk.turned_walk``), cut to ``n_frames`` at
    ``fps`` and rendered by ``gaitcap synth`` with the defaults the embedded walk's session has
    (cached in ``work``)."""
    from make_turn_walk import turned_walk  # scripts/, beside this file

    root = work / f"walkway-{fps:g}fps-{n_frames}frames"
    if (root / TRUTH_FILE).is_file() and _has_frames(root, n_frames):
        return root
    walk = read_motion(embedded_walk())
    samples = round((n_frames - 1) / fps * walk.rate_hz) + 1  # frames 0 .. n_frames - 1

    def up_and_down(turns: int) -> np.ndarray:
        return turned_walk(walk.points, walk.names.index("pelvis"), walk.rate_hz, turn_s, 180.0, turns, strides=2)

    turns, points = 1, up_and_down(1)
    while len(points) < samples:
        turns += 1
        points = up_and_down(turns)
    points = points[:samples]
    work.mkdir(parents=True, exist_ok=True)
    trc = work / f"{root.name}.trc"
    write_trc(trc, replace(walk, points=points, events=()), units="mm")
    synthesize(trc, root, SynthOptions(fps=fps, height_m=walk.meta.get("height_m", 1.639)), force=True, progress=False)
    if not _has_frames(root, n_frames):
        raise SystemExit(f"{root}: the turning walk did not render to {n_frames} frames")
    return root


def ping_pong(n_source: int, n_out: int) -> np.ndarray:
    """Frame indices 0, 1, ..., n-1, n-2, ..., 1, 0, 1, ... of length ``n_out``, shape (n_out,)."""
    if n_source < 2:
        return np.zeros(n_out, dtype=int)
    cycle = np.concatenate([np.arange(n_source), np.arange(n_source - 2, 0, -1)])
    return np.resize(cycle, n_out)


def _has_frames(session: Path, n_frames: int) -> bool:
    """``session`` is already a complete session of ``n_frames`` frames per camera."""
    try:
        return all(probe_video(v).frame_count == n_frames for v in Session.open(session).videos.values())
    except GaitcapError:
        return False


def long_session(source: Path, target: Path, n_frames: int, fps: float) -> Path:
    """A copy of ``source`` whose videos are looped (ping-pong) to ``n_frames`` at ``fps``."""
    if _has_frames(target, n_frames):
        return target
    shutil.rmtree(target, ignore_errors=True)
    (target / VIDEOS_DIR).mkdir(parents=True)
    shutil.copy2(source / CALIBRATION_FILE, target / CALIBRATION_FILE)
    if (source / SESSION_FILE).is_file():
        shutil.copy2(source / SESSION_FILE, target / SESSION_FILE)
    if (source / BACKGROUND_DIR).is_dir():
        shutil.copytree(source / BACKGROUND_DIR, target / BACKGROUND_DIR)
    for cam, video in Session.open(source).videos.items():
        with VideoReader(video) as reader:
            frames = [frame for _, frame in reader]
        h, w = frames[0].shape[:2]
        with AtomicVideoWriter(target / VIDEOS_DIR / video.name, fps, (w, h)) as writer:
            for i in ping_pong(len(frames), n_frames):
                writer.write(frames[i])
    return target


def gaitcap_in_child(args: list[str], ok_codes: tuple[int, ...] = (0,)) -> tuple[float, float]:
    """Run ``python -m gaitcap -q ARGS`` with this checkout's modules, its output (a batch's summary)
    left out of the table: (peak RSS MB, wall s). An exit code outside ``ok_codes`` ends the benchmark."""
    env = dict(os.environ, PYTHONPATH=str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    # the checkout's modules compiled once, as `pip install .` compiles an installed package's: with
    # PYTHONDONTWRITEBYTECODE set, every run would compile them again, a start-up no user pays
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    cmd = [sys.executable, "-m", "gaitcap", "-q", *args]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode not in ok_codes:
        raise SystemExit(f"{' '.join(cmd)} failed with exit code {proc.returncode}")
    return usage.ru_maxrss / 1024.0, wall  # ru_maxrss is in KiB on Linux


def track_in_child(session: Path, out: Path, extra: list[str]) -> tuple[float, float, dict]:
    """Run ``python -m gaitcap -q track`` on ``session``: (peak RSS MB, wall s, track.json). A run that
    exits 1 with its track.json written (a failed verdict) is measured like any other; one that wrote
    none ends the benchmark."""
    (out / "track.json").unlink(missing_ok=True)
    rss, wall = gaitcap_in_child(["track", str(session), "-o", str(out), "--force", *extra], ok_codes=(0, 1))
    if not (out / "track.json").is_file():
        raise SystemExit(f"gaitcap track {session} wrote no {out / 'track.json'}: the run failed (see its log)")
    return rss, wall, json.loads((out / "track.json").read_text())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--session", type=Path, default=None, help="session to loop (default: the embedded walk)")
    ap.add_argument("--work", type=Path, default=Path("/tmp/gaitcap-bench"))
    ap.add_argument("--seconds", type=float, nargs="+", default=[5.0, 20.0])
    ap.add_argument("--fps", type=float, default=25.0)
    ap.add_argument("extra", nargs="*", help="options passed on to gaitcap track (after --)")
    args = ap.parse_args()
    if args.session is not None:
        try:
            Session.open(args.session)
        except GaitcapError as e:
            sys.exit(f"error: --session: {e}")
    source = args.session or base_session(args.work, args.fps)
    rows = []
    for seconds in args.seconds:
        n = int(round(seconds * args.fps))
        session = long_session(source, args.work / f"{source.name}-{n}frames", n, args.fps)
        rss, wall, summary = track_in_child(session, args.work / f"{session.name}-out", args.extra)
        frames = summary["n_frames"]
        rows.append((seconds, frames, rss, wall, 1000 * summary["seconds"] / max(frames, 1)))
        print(f"<!-- {seconds:g} s: {frames} frames, {rss:.0f} MB, {wall:.0f} s -->", flush=True)
    print("| video s | frames | peak RSS MB | wall s | ms/frame |")
    print("|---|---|---|---|---|")
    for seconds, frames, rss, wall, ms in rows:
        print(f"| {seconds:g} | {frames} | {rss:.0f} | {wall:.0f} | {ms:.0f} |")


if __name__ == "__main__":
    main()
