"""A tracking output evaluated whole, as ``gaitcap eval`` and ``gaitcap demo`` write it: the comparison
(:func:`gaitcap.evaluation.evaluate`), the silhouettes' IoU when both sides have masks, and what the run's
``track.json`` records (its verdict, its body's segment lengths against the reference's, and whether the
reference is from the session it tracked)."""

from __future__ import annotations

import logging
from pathlib import Path

from gaitcap.evaluation.compare import Evaluation, compare_lengths, evaluate
from gaitcap.evaluation.report import (TruthReference, other_run_session, other_session, out_masks, read_tracked,
                                       tracked_path)  # fmt: skip
from gaitcap.evaluation.silhouettes import silhouette_iou
from gaitcap.track_summary import read_verdict, run_record, unfinished

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
    found = run_record(tracked_path(out))  # the run's track.json, read once
    if warning := unfinished(tracked_path(out), found):
        ev.notes.append(warning)
        log.warning("%s", warning)
    record = found or {}
    if truth is not None:
        mismatch = other_session(truth, record.get("session"))
    else:  # another run: the session it tracked (its track.json), against OUT's
        mismatch = other_run_session(ref.source, record.get("session"))
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
