"""The demo: every stage on the embedded walk, with default settings, into one folder.

embedded walk --synth--> ROOT/session (videos, calibration, truth.h5)
              --track--> ROOT/track (trajectories.h5, joints.csv, joints.trc, track.json)
              --eval---> ROOT/track/eval.json (against ROOT/session/truth.h5)
              --report-> ROOT/track/gait/report.html (events, parameters, angles, C3D)
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from gaitcap.data import embedded_walk
from gaitcap.evaluation import Evaluation
from gaitcap.evaluation.report import read_truth_reference, write_evaluation
from gaitcap.evaluation.run import evaluate_output
from gaitcap.pipeline import run_track
from gaitcap.report.pipeline import ReportResult, run_report
from gaitcap.synth.checks import truth_inside_masks
from gaitcap.synth.session import TRUTH_FILE, SynthOptions, SynthResult, synthesize
from gaitcap.track_summary import EVAL_FILE, TrackSummary

log = logging.getLogger("gaitcap.demo")

SESSION_DIR = "session"
TRACK_DIR = "track"


@dataclass(frozen=True)
class DemoResult:
    """Where each stage of the demo wrote, and what it found."""

    session: Path
    synth: SynthResult
    truth_inside: dict[str, float]
    track: TrackSummary
    evaluation: Evaluation
    eval_path: Path
    report: ReportResult

    @property
    def report_html(self) -> Path:
        return self.report.out_dir / "report.html"


def run_demo(root: Path, *, max_frames: int | None = None, progress: bool = True) -> DemoResult:
    """Run synth -> track -> eval -> report on the embedded walk into ``root`` (see the module
    docstring); every output there is replaced. ``max_frames`` tracks only the first frames."""
    root = Path(root)
    session, out = root / SESSION_DIR, root / TRACK_DIR
    log.info("1/4 synth: rendering a 2-camera session from %s", embedded_walk().name)
    synth = synthesize(embedded_walk(), session, SynthOptions(), force=True, progress=progress)
    inside = truth_inside_masks(session)
    log.info("    %d frames x %d cameras; truth points inside the rendered silhouettes: %s", synth.n_frames,
             len(synth.cameras), ", ".join(f"{k} {100 * v:.1f} %" for k, v in inside.items()))  # fmt: skip
    log.info("2/4 track: silhouettes and factored IPF (default settings)")
    track = run_track(session, out, force=True, progress=progress, max_frames=max_frames)
    log.info("    %s", track.message)
    log.info("3/4 eval: against the ground truth")
    ev = evaluate_output(out, read_truth_reference(session / TRUTH_FILE), session / TRUTH_FILE)  # as gaitcap eval
    eval_path = write_evaluation(out / EVAL_FILE, ev, force=True)
    log.info("4/4 report: gait events, parameters and angles")
    report = run_report(out)
    return DemoResult(session, synth, inside, track, ev, eval_path, report)
