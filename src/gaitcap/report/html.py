"""The self-contained ``report.html``: parameter tables and embedded PNG figures (base64), no
external resources, so it opens in a browser with no network."""

from __future__ import annotations

import base64
import html
import math
from typing import Any

from gaitcap import __version__
from gaitcap.gait.analysis import GaitAnalysis
from gaitcap.gait.parameters import OVERALL_KEYS, SIDE_KEYS, STATUS_IMPLAUSIBLE, STATUS_NOT_ENOUGH_STEPS
from gaitcap.report import plots

_CSS = """
body{font-family:system-ui,Arial,sans-serif;margin:24px;color:#222;max-width:1200px}
h1{font-size:22px} h2{font-size:18px;margin-top:28px;border-bottom:1px solid #ccc}
table{border-collapse:collapse;font-size:13px} td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}
th{background:#f3f3f3} td:first-child,th:first-child{text-align:left}
.warn{background:#fff3cd;border:1px solid #e0c060;padding:10px;margin:12px 0}
.note{color:#555;font-size:13px} img{max-width:100%}
"""

_LABELS = {
    "cadence_steps_per_min": "Cadence (steps/min)",
    "speed_m_s": "Walking speed (m/s)",
    "stride_length_m": "Stride length (m)",
    "step_length_m": "Step length (m)",
    "step_width_m": "Step width (m)",
    "stride_time_s": "Stride time (s)",
    "step_time_s": "Step time (s)",
    "stance_pct": "Stance (% cycle)",
    "swing_pct": "Swing (% cycle)",
    "single_support_pct": "Single support (% cycle)",
    "double_support_pct": "Double support (% cycle)",
}


def _fmt(values: dict[str, Any], key: str) -> str:
    v, sd, n = values.get(key), values.get(f"{key}_sd"), values.get(f"{key}_n", 0)
    if v is None or not math.isfinite(v):
        return "–"
    digits = 3 if abs(v) < 10 else 1
    s = f"{v:.{digits}f}"
    if sd is not None and math.isfinite(sd):
        s += f" ± {sd:.{digits}f}"
    return f"{s} <span class='note'>(n={n})</span>"


def _img(png: bytes, alt: str) -> str:
    return f"<img alt='{html.escape(alt)}' src='data:image/png;base64,{base64.b64encode(png).decode()}'>"


def parameter_table(analysis: GaitAnalysis) -> str:
    p = analysis.parameters
    rows = ["<tr><th>Parameter</th><th>Overall</th><th>Left</th><th>Right</th><th>Symmetry index (%)</th></tr>"]
    for key in SIDE_KEYS:
        si = p.symmetry.get(key)
        si_s = f"{si:.1f}" if si is not None and math.isfinite(si) else ""
        overall = _fmt(p.overall, key) if key in OVERALL_KEYS else ""
        rows.append(
            f"<tr><td>{_LABELS[key]}</td><td>{overall}</td><td>{_fmt(p.sides['left'], key)}</td>"
            f"<td>{_fmt(p.sides['right'], key)}</td><td>{si_s}</td></tr>"
        )
    rows.append(
        f"<tr><td>Complete gait cycles</td><td>{p.overall['n_strides']}</td><td>{p.sides['left']['n_strides']}</td>"
        f"<td>{p.sides['right']['n_strides']}</td><td></td></tr>"
    )
    return "<table>" + "".join(rows) + "</table>"


def render_report(analysis: GaitAnalysis, title: str = "Gait report") -> str:
    """The whole report as one HTML string."""
    p, traj = analysis.parameters, analysis.trajectory
    info = p.info
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
             f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>"]  # fmt: skip
    parts.append(
        f"<p class='note'>Source: {html.escape(str(traj.meta.get('source', '')))} — {traj.n_frames} frames at "
        f"{traj.rate_hz:g} Hz ({traj.n_frames / traj.rate_hz:.2f} s). Walking direction "
        f"{info.get('walking_direction')} ({html.escape(str(info.get('direction_method')))}"
        f"{', walking in place, belt speed %.2f m/s' % -info['belt_velocity_m_s'] if info.get('in_place') else ''}). "
        f"Events: {len(analysis.events)} detected ({html.escape(str(info.get('event_method')))}), "
        f"{len(analysis.reference_events)} recorded in the file. gaitcap {__version__}.</p>"
    )
    if p.status == STATUS_NOT_ENOUGH_STEPS:
        parts.append(f"<div class='warn'><b>Not enough steps.</b> {html.escape(p.reason)}</div>")
    elif p.status == STATUS_IMPLAUSIBLE:
        parts.append(f"<div class='warn'><b>Implausible values withheld.</b> {html.escape(p.reason)}</div>")
    elif p.reason:
        parts.append(f"<div class='warn'>{html.escape(p.reason)}</div>")
    parts.append("<h2>Spatio-temporal parameters</h2>" + parameter_table(analysis))
    parts.append(
        "<p class='note'>Mean ± SD (n). Symmetry index 100·(L−R)/((L+R)/2). Step values belong to the foot "
        "that lands. Stride length uses the heel displacement in the ground frame (belt-corrected when "
        "walking in place).</p>"
    )
    parts.append("<h2>Event timeline</h2>" + _img(plots.event_timeline(analysis), "event timeline"))
    if any(analysis.cycles[s] for s in ("left", "right")):
        parts.append("<h2>Joint angles over the gait cycle</h2>" + _img(plots.angle_curves(analysis), "joint angles"))
        parts.append(
            f"<p class='note'>Plug-in-Gait order and signs (see gaitcap.gait.angles). Pelvis frame: "
            f"{html.escape(analysis.angle_notes.get('pelvis_frame', ''))}."
            + ("" if "ASIS" in analysis.angle_notes.get("pelvis_frame", "") else
               " Without ASIS/PSIS markers pelvic tilt is not anatomical (see the docs).")
            + " Hip rotation comes from the knee's flexion plane: reliable only while the knee is flexed.</p>"
        )
    parts.append("<h2>Foot trajectories</h2>" + _img(plots.foot_trajectories(analysis), "foot trajectories"))
    parts.append("</body></html>")
    return "\n".join(parts)
