"""A stand-in for ``gaitcap.pipeline.run_track`` in the batch tests (same signature and contract).

It writes a small ``joints.csv`` and then ``track.json`` atomically, logs a line, and fails for a
session folder that holds a ``FAIL`` file (a typed error) or a ``CRASH`` file (any exception).
Module-level so that spawned worker processes and Dask workers can import it by name.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from gaitcap.errors import OutputError, TrackingError
from gaitcap.io.atomic import write_text_atomic
from gaitcap.track_summary import STATUS_OK, TrackSummary, is_finished, write_track_json

log = logging.getLogger("gaitcap.fake_track")

N_FRAMES = 12


def fake_track(
    session: Path, out: Path, *, config: Path | None = None, tracker: str | None = None,
    height_m: float | None = None, force: bool = False, progress: bool = True, max_frames: int | None = None,
    save_masks: bool = False, body: Path | None = None, silhouette_config: Path | None = None, seed: int | None = None,
) -> TrackSummary:  # fmt: skip
    session, out = Path(session), Path(out)
    if is_finished(out) and not force:
        raise OutputError(f"{out}: finished already (use --force to redo)")
    log.info("fake tracking of %s (tracker=%s, progress=%s)", session.name, tracker, progress)
    if (session / "FAIL").exists():
        raise TrackingError(f"{session}: the subject is never in view of two cameras")
    if (session / "CRASH").exists():
        raise ZeroDivisionError("division by zero")
    write_text_atomic(out / "joints.csv", f"frame,pid\n0,{os.getpid()}\n")
    summary = TrackSummary(session, out, STATUS_OK, N_FRAMES, 1, 0.01, f"pid {os.getpid()}", verdict="doubtful",
                           verdict_reasons=["a poor fit for 1 of 12 frames"])
    write_track_json(summary)
    return summary
