"""Writers of the gait analysis tables under ``OUT/gait/`` (write only; every file atomic).

- ``events.csv``: ``side,event,frame,time_s`` (frame = nearest frame index, 0-based);
- ``parameters.json``: :meth:`GaitParameters.to_dict` (``status``, ``reason``, ``overall``,
  ``left``, ``right``, ``symmetry_index_pct``, ``info``); missing values are ``null``; for a
  tracking run also ``tracking_verdict`` (its track.json's verdict and reasons);
- ``parameters.csv``: ``scope,parameter,mean,sd,n,unit`` (scope = overall, left, right, symmetry);
- ``strides.csv``: one row per complete gait cycle;
- ``angles.csv``: ``frame,time_s`` and one column per angle (degrees);
- ``cycles.h5``: ``/<side>/<angle>`` (n_cycles, 101) degrees over 0-100 % of the cycle, with
  ``/<side>/cycle_start_s``, ``cycle_end_s``, ``foot_off_pct``; root attribute ``angle_notes``.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from gaitcap import __version__
from gaitcap.gait.analysis import GaitAnalysis
from gaitcap.gait.parameters import OVERALL_KEYS, SIDE_KEYS, GaitParameters
from gaitcap.io.atomic import atomic_path, write_text_atomic
from gaitcap.track_summary import Verdict
from gaitcap.trajectory import SIDES, GaitEvent, Trajectory


def _csv_text(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


def _num(v: float, digits: int = 6) -> str:
    return "" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.{digits}g}"


def write_events_csv(path: Path, events: Sequence[GaitEvent], traj: Trajectory) -> None:
    rows = [(e.side, e.event, traj.frame_of(e.time_s), f"{e.time_s:.4f}") for e in events]
    write_text_atomic(path, _csv_text(("side", "event", "frame", "time_s"), rows))


def write_parameters(json_path: Path, csv_path: Path, params: GaitParameters, verdict: Verdict | None = None) -> None:
    """parameters.json and parameters.csv; with the tracking run's ``verdict`` (track.json), the JSON also
    holds it as ``tracking_verdict`` (``verdict``, ``reasons``): a failed run's parameters must not be used."""
    doc = params.to_dict()
    if verdict is not None:
        doc["tracking_verdict"] = {"verdict": verdict.verdict, "reasons": list(verdict.reasons)}
    write_text_atomic(json_path, json.dumps(doc, indent=2) + "\n")
    rows: list[tuple[Any, ...]] = []
    for scope, keys, values in (("overall", OVERALL_KEYS, params.overall),
                                ("left", SIDE_KEYS, params.sides["left"]),
                                ("right", SIDE_KEYS, params.sides["right"])):  # fmt: skip
        for key, unit in keys.items():
            rows.append((scope, key, _num(values[key]), _num(values[f"{key}_sd"]), values[f"{key}_n"], unit))
    for key, v in params.symmetry.items():
        rows.append(("symmetry", f"{key}_si", _num(v), "", "", "%"))
    write_text_atomic(csv_path, _csv_text(("scope", "parameter", "mean", "sd", "n", "unit"), rows))


def write_strides_csv(path: Path, params: GaitParameters) -> None:
    keys = ("stride_time_s", "stride_length_m", "speed_m_s", "stance_pct", "swing_pct", "single_support_pct", "double_support_pct")
    rows = [(s.side, f"{s.cycle.start_s:.4f}", f"{s.cycle.end_s:.4f}", *(_num(getattr(s, k)) for k in keys)) for s in params.strides]
    write_text_atomic(path, _csv_text(("side", "start_s", "end_s", *keys), rows))


def write_angles_csv(path: Path, traj: Trajectory, angles: dict[str, np.ndarray]) -> None:
    names = list(angles)
    t = traj.times()
    rows = [(i, f"{t[i]:.4f}", *(_num(angles[n][i], 5) for n in names)) for i in range(traj.n_frames)]
    write_text_atomic(path, _csv_text(("frame", "time_s", *names), rows))


def write_cycles_h5(path: Path, analysis: GaitAnalysis) -> None:
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["gaitcap_version"] = __version__
        f.attrs["angle_notes"] = json.dumps(analysis.angle_notes)
        f.attrs["units"] = "degrees; 101 samples over 0-100 % of each gait cycle"
        for side in SIDES:
            g = f.create_group(side)
            cyc = analysis.cycles[side]
            g.create_dataset("cycle_start_s", data=np.array([c.start_s for c in cyc], dtype=np.float64))
            g.create_dataset("cycle_end_s", data=np.array([c.end_s for c in cyc], dtype=np.float64))
            g.create_dataset("foot_off_pct", data=np.array([c.pct(c.foot_off_s) for c in cyc], dtype=np.float64))
            for name, curves in analysis.curves[side].items():
                g.create_dataset(name, data=np.asarray(curves, dtype=np.float64).reshape(-1, 101))
