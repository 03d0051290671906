"""``gaitcap report``: read a trajectory, analyse it, write every output under ``OUT/gait/``."""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gaitcap.errors import InputError
from gaitcap.gait.analysis import GaitAnalysis, analyse
from gaitcap.gait.angles import PELVIS_MARKER_SETS
from gaitcap.gait.events import WalkingDirection
from gaitcap.gait.options import GaitOptions
from gaitcap.io import gait_outputs
from gaitcap.io.atomic import remove_replaced, write_text_atomic
from gaitcap.io.c3d_export import write_c3d
from gaitcap.io.trajectories_h5 import read_trajectory
from gaitcap.report.fit import FitRecord, angle_bands, load_fit_record, select_frames
from gaitcap.report.html import FitView, render_fit_report, render_report
from gaitcap.report.plots import FLEXION_ANGLES
from gaitcap.report.sheet import contact_sheet
from gaitcap.track_summary import (GAIT_DIR, TRAJECTORIES_H5, Verdict, read_track_json, read_verdict, run_record,
                                   unfinished)  # fmt: skip
from gaitcap.trajectory import LOWER_LIMB, SIDES, GaitEvent, Trajectory, side_suffix

log = logging.getLogger("gaitcap.report")

MOTION_SUFFIXES = (".c3d", ".trc")


@dataclass(frozen=True)
class ReportResult:
    analysis: GaitAnalysis
    out_dir: Path
    files: tuple[Path, ...]
    verdict: Verdict | None = None


def resolve_input(source: Path) -> Path:
    """The trajectory file of ``source``: ``source/trajectories.h5`` for a folder, else the file."""
    if source.is_dir():
        path = source / TRAJECTORIES_H5
        if not path.is_file():
            runs = sorted(p.parent.name for p in source.glob(f"*/{TRAJECTORIES_H5}"))
            if runs:  # a batch's output folder (gaitcap track FOLDER -o OUT)
                listed = ", ".join(runs[:5]) + (", ..." if len(runs) > 5 else "")
                raise InputError(f"{source}: holds the runs of {len(runs)} sessions ({listed}): report each one, "
                                 f"e.g. gaitcap report {source / runs[0]}")  # fmt: skip
            raise InputError(f"{source}: no {TRAJECTORIES_H5} in this folder (run gaitcap track first, or pass a .c3d/.trc)")
        return path
    if not source.exists():
        raise InputError(f"{source}: no such file or folder")
    return source


def _title(path: Path, record: dict | None) -> str:
    """The report's title: a tracking run's session (as its track.json, ``record``, says) and its output
    folder, or the marker file's name."""
    if path.name != TRAJECTORIES_H5:
        return f"Gait report — {path.name}"
    session = (record or {}).get("session")
    run = path.parent.resolve().name
    return f"Gait report — {Path(session).name} ({run})" if session else f"Gait report — {run}"


def load_trajectory(path: Path, mapping: str | Path | None = None, subject: str | None = None,
                    static: Path | None = None) -> Trajectory:  # fmt: skip
    """A trajectories.h5 file, or a .c3d/.trc motion file (joint centres through read_motion, with
    ``mapping``, ``subject`` and ``static`` when given)."""
    suffix = path.suffix.lower()
    if suffix in (".h5", ".hdf5"):
        return read_trajectory(path)
    if suffix in MOTION_SUFFIXES:
        from gaitcap.markers.motion import read_markers, read_motion

        joints = read_motion(path, mapping=mapping, static=static, subject=subject, require=LOWER_LIMB)
        return with_pelvis_markers(joints, read_markers(path, mapping=mapping, subject=subject))
    raise InputError(f"{path}: unknown trajectory file type (expected trajectories.h5, .c3d or .trc)")


def with_pelvis_markers(joints: Trajectory, markers: Trajectory) -> Trajectory:
    """Add the ASIS/PSIS markers of a marker file to its joint centres, under the file's own names
    (the first spelling of :data:`gaitcap.gait.angles.PELVIS_MARKER_SETS` it has: Plug-in-Gait's
    LASI RASI LPSI RPSI, or LASI RASI SACR, CAST's, OpenSim's L.ASIS R.ASIS V.Sacral), so the pelvis
    angles use the anatomical pelvis frame (see gaitcap.gait.angles). A sacral marker stands for the
    two PSIS markers' mid-point; the exported C3D names no marker the file does not have."""
    if markers.n_frames != joints.n_frames:
        return joints
    for spelling in PELVIS_MARKER_SETS:
        names = tuple(dict.fromkeys(spelling))  # a sacral marker once
        if all(markers.has(n) for n in names):
            extra = np.stack([markers.point(n) for n in names], axis=1)
            return replace(joints, names=joints.names + names, points=np.concatenate([joints.points, extra], axis=1))
    return joints


def _fit_record(path: Path, traj: Trajectory) -> FitRecord | None:
    """The tracker's per-frame record of a trajectories.h5 ``path`` (None for another source, or a
    record that does not match the trajectory's frames)."""
    if path.suffix.lower() not in (".h5", ".hdf5"):
        return None
    fit = load_fit_record(path)
    if fit is not None and fit.record.n_frames != traj.n_frames:
        log.warning("%s: the tracker's record has %d frames, the trajectory %d: the fit is not shown",
                    path, fit.record.n_frames, traj.n_frames)  # fmt: skip
        return None
    return fit


def fit_view(path: Path, traj: Trajectory, events: list[GaitEvent], direction: WalkingDirection | None = None,
             session: Path | None = None) -> tuple[FitView, list[int]]:  # fmt: skip
    """What report.html shows of the tracking run behind ``path`` (its verdict, fit, contact sheet,
    and, given the walking ``direction``, the angle bands), and the contact sheet's frames."""
    is_h5 = path.suffix.lower() in (".h5", ".hdf5")
    verdict = read_verdict(read_track_json(path.parent)) if is_h5 else None
    names = tuple(f"{n}{side_suffix(s)}" for n in FLEXION_ANGLES for s in SIDES)
    bands = angle_bands(traj, direction, names) if direction is not None else None
    fit = _fit_record(path, traj)
    if fit is None:
        return FitView(verdict, bands=bands), []
    frames = select_frames(fit, events, traj.t0_s)
    sheet = contact_sheet(fit, frames, session)
    if sheet.omitted:
        log.warning("%s", sheet.omitted)
    return FitView(verdict, fit, sheet, bands, fit.flagged), [f.index for f in frames]


def _fit_only(path: Path, traj: Trajectory, html_path: Path, session: Path | None, error: InputError,
              record: dict | None) -> InputError:  # fmt: skip
    """When the gait analysis of a tracking run fails (a run that lost the subject): write a
    report.html of its verdict and fit, and return the error to raise, saying so (the same error
    when ``path`` is not a tracking run)."""
    view, frames = fit_view(path, traj, [], None, session)
    if view.fit is None:
        return error
    write_text_atomic(html_path, render_fit_report(traj, view, str(error), _title(path, record), frames))
    verdict = f"; {view.verdict.line()}" if view.verdict is not None else ""
    return InputError(f"{error}{verdict}; the tracking's fit is shown in {html_path}")


def run_report(
    source: Path,
    out_dir: Path | None = None,
    options: GaitOptions | None = None,
    mapping: str | Path | None = None,
    subject: str | None = None,
    session: Path | None = None,
    static: Path | None = None,
    recorded_events: bool = False,
) -> ReportResult:
    """Analyse ``source`` and write ``events.csv``, ``parameters.json``/``.csv``, ``strides.csv``,
    ``angles.csv``, ``cycles.h5``, ``trajectories.c3d`` and ``report.html`` into ``out_dir``
    (default: ``<source folder>/gait``); ``mapping``/``subject``/``static`` for a .c3d/.trc source. For a
    tracking run, report.html also shows the verdict of its track.json and how the model fits its
    videos (``session``: the session folder, when not where the run recorded it). ``recorded_events``:
    the events the source holds (a marker file's) instead of those detected."""
    path = resolve_input(Path(source))
    record = run_record(path)  # a tracking run's track.json, read once here
    if warning := unfinished(path, record):
        log.warning("%s", warning)
    traj = load_trajectory(path, mapping, subject, static)
    if recorded_events and not traj.events:
        raise InputError(f"{path}: --recorded-events: the file records no gait event")
    out = Path(out_dir) if out_dir is not None else (Path(source) if Path(source).is_dir() else path.parent) / GAIT_DIR
    files = {
        "events": out / "events.csv", "parameters_json": out / "parameters.json",
        "parameters_csv": out / "parameters.csv", "strides": out / "strides.csv",
        "angles": out / "angles.csv", "cycles": out / "cycles.h5",
        "c3d": out / "trajectories.c3d", "html": out / "report.html",
    }  # fmt: skip
    # an earlier report's files go first: a run that stops half-way (Ctrl-C, an analysis that fails) leaves
    # only its own, not a set of two runs' (report.html, written last, says that the set is complete)
    remove_replaced([p for p in files.values() if p.is_file()])
    try:
        a = analyse(traj, options, recorded=recorded_events)
    except InputError as e:
        raise _fit_only(path, traj, files["html"], session, e, record) from e
    gait_outputs.write_events_csv(files["events"], a.events, traj)
    gait_outputs.write_parameters(files["parameters_json"], files["parameters_csv"], a.parameters, read_verdict(record))
    gait_outputs.write_strides_csv(files["strides"], a.parameters)
    gait_outputs.write_angles_csv(files["angles"], traj, a.angles)
    gait_outputs.write_cycles_h5(files["cycles"], a)
    write_c3d(files["c3d"], traj.with_events(a.events))
    view, sheet_frames = fit_view(path, traj, a.events, a.direction, session)
    write_text_atomic(files["html"], render_report(a, _title(path, record), view, sheet_frames))
    log.info("wrote %d files to %s", len(files), out)
    return ReportResult(a, out, tuple(files.values()), view.verdict)
