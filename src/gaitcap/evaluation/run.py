"""A tracking output evaluated whole, as ``gaitcap eval`` and ``gaitcap demo`` write it: the comparison
(:func:`gaitcap.evaluation.evaluate`), the silhouettes' IoU when both sides have masks, and what the run's
``track.json`` records (its verdict, its body's segment lengths against the reference's, and whether the
reference is from the session it tracked)."""

from __future__ import annotations

import logging
from pathlib import Path

from gaitcap.evaluation.compare import Evaluation, compare_lengths, evaluate
from gaitcap.evaluation.report import (TruthReference, other_run_session, other_session, out_masks, read_tracked,
                                       recorded_session, tracked_path)  # fmt: skip
from gaitcap.evaluation.silhouettes import silhouette_iou
from gaitcap.io.track_h5 import read_root_attrs, skip_frames_of
from gaitcap.track_summary import format_verdict, read_verdict, run_record, unfinished

log = logging.getLogger(__name__)


def evaluate_output(out: Path, ref: TruthReference, truth: Path | None = None) -> Evaluation:
    """The evaluation of the tracking output ``out`` (a folder or its trajectories.h5) against ``ref``;
    ``truth``: the path ``ref`` was read from when it is a truth (checked against the session the run
    tracked), None for another run."""
    ev = evaluate(read_tracked(out), ref.trajectory, out_source=str(tracked_path(out)),
                  reference_source=str(ref.source), reference_parameters=ref.parameters)  # fmt: skip
    masks = out_masks(out)
    if ref.masks is not None and masks is not None:
        ev.silhouettes, notes = silhouette_iou(masks, ref.masks)
        ev.notes += notes
    elif ref.masks is not None:
        ev.notes.append("silhouettes not compared: OUT holds no silhouettes.h5 (track with --save-masks)")
    trajectories = tracked_path(out)
    if skipped := skipped_frames_note(trajectories):
        ev.notes.append(skipped)
        log.warning("%s", skipped)
    found = run_record(trajectories)  # the run's track.json, read once
    if warning := unfinished(trajectories, found):
        ev.notes.append(warning)
        log.warning("%s", warning)
    record = found or {}
    session = recorded_session(trajectories, record)
    if truth is not None:
        mismatch = other_session(truth, session)
    else:  # another run: the session it tracked (its track.json), against OUT's
        mismatch = other_run_session(ref.source, session)
        ev.reference_is_run = True
        for note in reference_run_notes(ref.source, ev):
            ev.notes.append(note)
            log.warning("%s", note)
    if mismatch:
        ev.notes.append(mismatch)
        log.warning("%s", mismatch)
    body = record.get("body") or {}
    if body.get("segment_lengths_m"):
        ev.segment_lengths = compare_lengths(body["segment_lengths_m"], ref.trajectory)
    verdict = read_verdict(record)
    if verdict is not None:
        ev.verdict, ev.verdict_reasons = verdict.verdict, list(verdict.reasons)
    return ev


def skipped_frames_note(trajectories: Path) -> str | None:
    """A note when the run skipped frames at the start of some camera's video (trajectories.h5's
    ``skip_frames`` attribute: session.yaml's, or those a run tracked again in step found): its frame k
    is not frame k of those videos, while the reference is compared from its own first frame."""
    skips = {c: n for c, n in (skip_frames_of(read_root_attrs(trajectories, "skip_frames")) or {}).items() if n}
    if not skips:
        return None
    listed = ", ".join(f"{c}: {n}" for c, n in skips.items())
    return (f"OUT skipped the first frames of some cameras' videos (skip_frames: {{{listed}}}): its frame k is frame "
            f"k + n of such a camera's video, and the reference is compared from its own first frame; a reference "
            f"timed by those videos' frames is n frames ahead of OUT")


def reference_run_notes(reference: Path, ev: Evaluation) -> list[str]:
    """What a reference run (``gaitcap eval --reference``; its trajectories.h5) is, by its track.json: its
    verdict goes to ``ev.reference_verdict``; a note when it is not a finished run or its own verdict is
    failed (a reference saved from a run that went wrong: OUT alike to it is no sign of a good run)."""
    record = run_record(reference)
    notes = []
    if warning := unfinished(reference, record):
        notes.append(f"the reference {warning}")
    verdict = read_verdict(record)
    ev.reference_verdict = verdict.verdict if verdict is not None else None
    if verdict is not None and verdict.verdict == "failed":
        notes.append(f"the reference run's own verdict is {format_verdict(verdict.verdict, verdict.reasons)} "
                     f"({reference.parent / 'track.json'}): being alike to it says nothing of OUT's accuracy; "
                     "save a reference from a run judged ok")
    return notes
