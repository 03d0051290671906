"""Inputs and outputs of ``gaitcap eval``: read OUT / truth / reference, write ``eval.json``, and
render the readable table."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from gaitcap.errors import InputError
from gaitcap.evaluation.compare import CHECKED_ANGLES, Evaluation
from gaitcap.gait.angles import ANGLE_NAMES
from gaitcap.gait.parameters import OVERALL_KEYS
from gaitcap.io.atomic import refuse_existing, write_text_atomic
from gaitcap.io.silhouettes_h5 import SILHOUETTES_FILE
from gaitcap.io.track_h5 import read_root_attrs
from gaitcap.io.trajectories_h5 import read_trajectory
from gaitcap.io.truth_folder import JOINTS_FILE, is_truth_folder, read_truth_folder
from gaitcap.synth.truth import read_truth
from gaitcap.session import CALIBRATION_FILE
from gaitcap.track_summary import TRAJECTORIES_H5, format_verdict, read_track_json
from gaitcap.trajectory import FOOT, LOWER_LIMB, Trajectory

TRUTH_FILE = "truth.h5"


def tracked_path(path: str | Path) -> Path:
    """``path`` itself if it is a file, else ``path/trajectories.h5`` (a tracking output folder)."""
    path = Path(path)
    return path / TRAJECTORIES_H5 if path.is_dir() else path


def read_tracked(path: str | Path) -> Trajectory:
    """The trajectory of a tracking output folder or ``trajectories.h5`` file.

    Raises:
        InputError: no such file, not a trajectories.h5, or a batch's output folder (one run per session in it).
    """
    from gaitcap.batch import BATCH_JSON

    path = Path(path)
    if path.is_dir() and not tracked_path(path).is_file() and (path / BATCH_JSON).is_file():
        runs = sorted(p.name for p in path.iterdir() if (p / TRAJECTORIES_H5).is_file())
        listed = ", ".join(runs[:3]) + (", ..." if len(runs) > 3 else "")
        raise InputError(f"{path}: a batch's output ({BATCH_JSON}), one run per session: evaluate each run's folder"
                         + (f" ({path / '<session>'}: {listed})" if runs else ""))
    return read_trajectory(tracked_path(path))


@dataclass(frozen=True)
class TruthReference:
    """A ground truth as ``gaitcap eval --truth`` reads it.

    Attributes:
        source: the file or folder it was read from.
        trajectory: the true points (with the recorded events, if any).
        parameters: gait parameters the truth states (truth folder's parameters.json), or None.
        masks: a file holding the true silhouettes (masks.h5, or truth.h5 with masks), or None.
    """

    source: Path
    trajectory: Trajectory
    parameters: dict[str, dict[str, float]] | None = None
    masks: Path | None = None


def read_truth_reference(path: str | Path) -> TruthReference:
    """A truth folder (``joints.csv`` [+ ``events.csv``, ``parameters.json``, ``masks.h5``], see
    :mod:`gaitcap.io.truth_folder`), a ``truth.h5`` file, or a synthetic session folder holding one.

    Raises:
        InputError: none of these, or a malformed one (the message names the file).
    """
    path = Path(path)
    if is_truth_folder(path):
        folder = read_truth_folder(path)
        return TruthReference(path, folder.trajectory, folder.parameters, folder.masks)
    if path.is_dir() and not (path / TRUTH_FILE).is_file():
        raise InputError(f"{path}: not a truth: holds neither {JOINTS_FILE} (a truth folder) nor {TRUTH_FILE} "
                         "(a synthetic session)")  # fmt: skip
    h5 = path / TRUTH_FILE if path.is_dir() else path
    truth = read_truth(h5)
    return TruthReference(h5, truth.trajectory, None, h5 if truth.cameras else None)


def read_truth_trajectory(path: str | Path) -> Trajectory:
    """The ground-truth trajectory (with its recorded events) of a truth (see :func:`read_truth_reference`)."""
    return read_truth_reference(path).trajectory


def out_masks(path: str | Path) -> Path | None:
    """The ``silhouettes.h5`` of a tracking output (folder, or beside its ``trajectories.h5``), if any."""
    path = Path(path)
    masks = (path if path.is_dir() else path.parent) / SILHOUETTES_FILE
    return masks if masks.is_file() else None


def recorded_session(trajectories: str | Path, record: dict | None) -> str | None:
    """The session folder a tracking run tracked: its trajectories.h5's ``session`` attribute (the absolute path),
    else its track.json's ``session`` (``record``: the path as the command line gave it, relative to wherever
    ``gaitcap track`` ran, so not to be resolved from another working folder); None when neither says."""
    value = read_root_attrs(trajectories, "session").get("session")
    if isinstance(value, str) and value and Path(value).is_absolute():
        return value
    return (record or {}).get("session") or None


def other_session(truth: str | Path, tracked_session: str | None) -> str | None:
    """A note when a truth given to ``gaitcap eval`` belongs to another session than the tracked one
    (``tracked_session``: track.json's ``session``): the truth is a session's folder or a file or
    folder in one (beside its calibration.toml) other than that; None when they match, the run does
    not say, or the truth is in no session (a lab's own export, kept anywhere). A moved session also
    differs: a note, not an error."""
    if not tracked_session:
        return None
    truth, session = Path(truth).resolve(), Path(tracked_session).resolve()
    if session in (truth, truth.parent):
        return None
    if not any((folder / CALIBRATION_FILE).is_file() for folder in (truth, truth.parent)):
        return None  # not a session's truth: nothing to tell it by
    return (f"the truth {truth} is not from the session this run tracked ({session}, track.json): "
            "is it the right truth?")


def other_run_session(reference: str | Path, tracked_session: str | None) -> str | None:
    """A note when a reference run (``gaitcap eval --reference``; its trajectories.h5) tracked another
    session than OUT (``tracked_session``), by their track.json; None when they match or either does
    not say."""
    theirs = recorded_session(reference, read_track_json(Path(reference).parent))
    if not tracked_session or not theirs or Path(theirs).resolve() == Path(tracked_session).resolve():
        return None
    return (f"the reference run tracked another session ({theirs}) than this run ({tracked_session}), by their "
            "track.json: is it the right reference?")


def write_evaluation(path: str | Path, ev: Evaluation, force: bool = False) -> Path:
    """Write ``eval.json`` atomically; an existing file is kept unless ``force``."""
    path = Path(path)
    refuse_existing(path, force)
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
    lines += _bias_lines(ev)
    s = ev.swaps
    lines.append(f"left/right swaps: {s['n_frames']} frames in {len(s['runs'])} runs")
    return lines


def _bias_lines(ev: Evaluation) -> list[str]:
    """The lower limb's mean signed errors (the same offset in every frame), one line per point."""
    shown = [n for n in ev.bias_mm if n in LOWER_LIMB or n in FOOT]
    if not shown:
        return []
    lower = ev.positions.get("lower_limb") or {}
    lines = [f"  lower limb without each point's constant offset: {_f(lower.get('offset_free_mpjpe_mm'))} mm",
             f"  {'systematic part (mm)':<20}{'forward':>8}{'outward':>8}{'up':>8}{'share':>8}   (mean signed error)"]
    for n in shown:
        b = ev.bias_mm[n]
        lines.append(f"  {n:<20}{_f(b['forward']):>8}{_f(b['outward']):>8}{_f(b['up']):>8}{_f(b['share'], 2):>8}")
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


def _parameter_rows(values: dict[str, dict[str, float]], prefix: str = "") -> list[str]:
    lines = []
    for key, v in values.items():
        d = 3 if key.endswith(("_m", "_s", "_m_s")) else 1
        lines.append(f"  {prefix + key:<30}{_f(v['reference'], d):>10}{_f(v['out'], d):>10}{_f(v['diff'], d):>10}"
                     f"{_f(v['diff_pct']):>8}")  # fmt: skip
    return lines


def _parameter_lines(ev: Evaluation) -> list[str]:
    p = ev.parameters
    lines = [f"gait parameters (OUT {p['out_status']}, reference {p['reference_status']})"]
    if not p["values"] and not p.get("sides"):
        return lines
    lines.append(f"  {'':<30}{'reference':>10}{'OUT':>10}{'diff':>10}{'diff %':>8}")
    lines += _parameter_rows({k: p["values"][k] for k in OVERALL_KEYS if k in p["values"]})
    for side, values in p.get("sides", {}).items():
        lines += _parameter_rows(values, f"{side} ")
    return lines


def _silhouette_lines(ev: Evaluation) -> list[str]:
    if not ev.silhouettes:
        return []
    lines = [f"{'silhouette IoU':<22}{'mean':>7}{'median':>8}{'p10':>7}   frames scored (true mask not empty)"]
    for cam, s in ev.silhouettes.items():
        lines.append(f"  {cam:<20}{_f(s['mean'], 3):>7}{_f(s['median'], 3):>8}{_f(s['p10'], 3):>7}   {s['n_frames']} of {s['frames']}")
    return lines


def _length_lines(ev: Evaluation) -> list[str]:
    if not ev.segment_lengths:
        return []
    lines = [f"{'segment lengths (m)':<22}{'tracked':>8}{'ref':>8}{'diff %':>8}"]
    for name, d in ev.segment_lengths.items():
        lines.append(f"  {name:<20}{d['tracked_m']:>8.3f}{d['reference_m']:>8.3f}{d['diff_pct']:>+8.1f}")
    return lines


def format_evaluation(ev: Evaluation) -> str:
    """The readable report of an evaluation (what ``gaitcap eval`` prints)."""
    compared = ev.n_frames - ev.n_flagged - ev.n_reference_missing
    head = [f"{ev.out_source} against {ev.reference_source}",
            f"{compared} of {ev.n_frames} frames compared at {ev.rate_hz:g} Hz ({ev.n_flagged} flagged in OUT, "
            f"{ev.n_reference_missing} missing in the reference), {len(ev.points)} points",
            f"verdict of the run: {format_verdict(ev.verdict, ev.verdict_reasons)}"]  # fmt: skip
    sections = [head, _positions_lines(ev), _angle_lines(ev), _event_lines(ev), _parameter_lines(ev), _silhouette_lines(ev),
                _length_lines(ev)]
    if ev.notes:
        sections.append(["notes:", *(f"  {n}" for n in ev.notes)])
    if ev.failures:
        sections.append(["THRESHOLDS EXCEEDED:", *(f"  {f}" for f in ev.failures)])
    return "\n\n".join("\n".join(s) for s in sections if s)
