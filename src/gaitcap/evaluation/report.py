"""Inputs and outputs of ``gaitcap eval``: read OUT / truth / reference, write ``eval.json``, and
render the readable table."""

from __future__ import annotations

import json
import math
from pathlib import Path

from gaitcap.errors import OutputError
from gaitcap.evaluation.compare import CHECKED_ANGLES, Evaluation
from gaitcap.gait.angles import ANGLE_NAMES
from gaitcap.gait.parameters import OVERALL_KEYS
from gaitcap.io.atomic import write_text_atomic
from gaitcap.io.trajectories_h5 import read_trajectory
from gaitcap.synth.truth import read_truth
from gaitcap.trajectory import Trajectory

TRAJECTORIES_FILE = "trajectories.h5"
TRUTH_FILE = "truth.h5"
EVAL_FILE = "eval.json"


def tracked_path(path: str | Path) -> Path:
    """``path`` itself if it is a file, else ``path/trajectories.h5`` (a tracking output folder)."""
    path = Path(path)
    return path / TRAJECTORIES_FILE if path.is_dir() else path


def read_tracked(path: str | Path) -> Trajectory:
    """The trajectory of a tracking output folder or ``trajectories.h5`` file."""
    return read_trajectory(tracked_path(path))


def read_truth_trajectory(path: str | Path) -> Trajectory:
    """The ground-truth trajectory (with its recorded events) of a ``truth.h5`` file, or of the
    synthetic session folder holding one."""
    path = Path(path)
    return read_truth(path / TRUTH_FILE if path.is_dir() else path).trajectory


def write_evaluation(path: str | Path, ev: Evaluation, force: bool = False) -> Path:
    """Write ``eval.json`` atomically; an existing file is kept unless ``force``."""
    path = Path(path)
    if path.exists() and not force:
        raise OutputError(f"{path}: exists already (use --force to overwrite)")
    write_text_atomic(path, json.dumps(ev.to_dict(), indent=2) + "\n")
    return path


def _f(v: float | None, digits: int = 1) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{v:.{digits}f}"


def _positions_lines(ev: Evaluation) -> list[str]:
    lines = [f"{'positions (mm)':<22}{'MPJPE':>8}{'median':>8}{'p95':>8}{'max':>8}   (per-frame median/p95/max)"]
    labels = {"all": "all points", "lower_limb": "lower limb", "heel_toe": "heel/toe"}
    for key, label in labels.items():
        g = ev.positions.get(key)
        if g is None:
            continue
        lines.append(f"  {label + ' (' + str(g['n_points']) + ')':<20}{_f(g['mpjpe_mm']):>8}{_f(g['frame_median_mm']):>8}"
                     f"{_f(g['frame_p95_mm']):>8}{_f(g['frame_max_mm']):>8}")  # fmt: skip
    names = list(ev.per_point_mm)
    for i in range(0, len(names), 5):
        lines.append("  " + "  ".join(f"{n} {_f(ev.per_point_mm[n])}" for n in names[i : i + 5]))
    s = ev.swaps
    lines.append(f"left/right swaps: {s['n_frames']} frames in {len(s['runs'])} runs")
    return lines


def _angle_lines(ev: Evaluation) -> list[str]:
    if not ev.angles_rmse_deg:
        return []
    lines = [f"{'joint angles RMSE (deg)':<26}{'left':>7}{'right':>7}"]
    for n in ANGLE_NAMES:
        mark = " *" if n in CHECKED_ANGLES else ""
        lines.append(f"  {n:<24}{_f(ev.angles_rmse_deg.get(n + '_l')):>7}{_f(ev.angles_rmse_deg.get(n + '_r')):>7}{mark}")
    lines.append("  (* checked by --max-angle-rmse-deg)")
    return lines


def _event_summary(label: str, e: dict) -> str:
    return (f"{label}: {e['n_reference']} reference ({e['reference_events']}), {e['n_matched']} matched, "
            f"{e['n_missed']} missed, {e['n_extra']} extra; |error| mean {_f(e['mean_abs_ms'], 0)} ms "
            f"({_f(e['mean_abs_frames'], 2)} frames), max {_f(e['max_abs_ms'], 0)} ms ({_f(e['max_abs_frames'], 2)} frames), "
            f"bias {_f(e['mean_ms'], 0)} ms")  # fmt: skip


def _event_lines(ev: Evaluation) -> list[str]:
    lines = []
    if ev.events:
        lines.append(_event_summary("events of OUT", ev.events))
        for m in ev.events["matches"]:
            lines.append(f"  {m['side']:<6}{m['event']:<12}{m['reference_s']:8.3f} s  {m['error_ms']:+6.0f} ms  {m['error_frames']:+5.2f} frames")
        for m in ev.events["missed"]:
            lines.append(f"  {m['side']:<6}{m['event']:<12}{m['time_s']:8.3f} s  missed")
    if ev.events_baseline:
        lines.append(_event_summary("method baseline (events detected on the reference)", ev.events_baseline))
    return lines


def _parameter_lines(ev: Evaluation) -> list[str]:
    p = ev.parameters
    lines = [f"gait parameters (OUT {p['out_status']}, reference {p['reference_status']})"]
    if not p["values"]:
        return lines
    lines.append(f"  {'':<24}{'reference':>10}{'OUT':>10}{'diff':>10}{'diff %':>8}")
    for key in OVERALL_KEYS:
        v = p["values"].get(key)
        if v is None:
            continue
        d = 3 if key.endswith(("_m", "_s", "_m_s")) else 1
        lines.append(f"  {key:<24}{_f(v['reference'], d):>10}{_f(v['out'], d):>10}{_f(v['diff'], d):>10}{_f(v['diff_pct']):>8}")
    return lines


def format_evaluation(ev: Evaluation) -> str:
    """The readable report of an evaluation (what ``gaitcap eval`` prints)."""
    compared = ev.n_frames - ev.n_flagged - ev.n_reference_missing
    head = [f"{ev.out_source} against {ev.reference_source}",
            f"{compared} of {ev.n_frames} frames compared at {ev.rate_hz:g} Hz ({ev.n_flagged} flagged in OUT, "
            f"{ev.n_reference_missing} missing in the reference), {len(ev.points)} points"]  # fmt: skip
    sections = [head, _positions_lines(ev), _angle_lines(ev), _event_lines(ev), _parameter_lines(ev)]
    if ev.notes:
        sections.append(["notes:", *(f"  {n}" for n in ev.notes)])
    if ev.failures:
        sections.append(["THRESHOLDS EXCEEDED:", *(f"  {f}" for f in ev.failures)])
    return "\n\n".join("\n".join(s) for s in sections if s)
