"""The self-contained ``report.html``: parameter tables and embedded PNG figures (base64), no
external resources, so it opens in a browser with no network."""

from __future__ import annotations

import base64
import html
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gaitcap import __version__
from gaitcap.gait.analysis import GaitAnalysis
from gaitcap.gait.parameters import OVERALL_KEYS, SIDE_KEYS, STATUS_IMPLAUSIBLE, STATUS_NOT_ENOUGH_STEPS
from gaitcap.quality import feet_off_masks
from gaitcap.report import plots
from gaitcap.report.fit import FitRecord
from gaitcap.report.sheet import ContactSheet, SheetRow
from gaitcap.track_summary import VERDICTS, Verdict
from gaitcap.trajectory import GaitEvent, Trajectory

_CSS = """
body{font-family:system-ui,Arial,sans-serif;margin:24px;color:#222;max-width:1200px}
h1{font-size:22px} h2{font-size:18px;margin-top:28px;border-bottom:1px solid #ccc}
table{border-collapse:collapse;font-size:13px} td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}
th{background:#f3f3f3} td:first-child,th:first-child{text-align:left}
.warn{background:#fff3cd;border:1px solid #e0c060;padding:10px;margin:12px 0}
.note{color:#555;font-size:13px} img{max-width:100%}
.verdict{padding:12px 16px;margin:12px 0;border-radius:4px;font-size:15px;border:2px solid}
.verdict ul{margin:6px 0 0 0} .v-ok{background:#e6f4ea;border-color:#2e7d32}
.v-doubtful{background:#fff3cd;border-color:#c99a06} .v-failed{background:#fdecea;border-color:#c62828}
.sheet{display:flex;flex-wrap:wrap;gap:8px} .cell{border:2px solid #ddd;padding:3px;background:#fafafa}
.cell.att{border-color:#d62728;background:#fdecea} .cell img{height:240px;width:auto;margin-right:2px}
.cap{font-size:12px;color:#333;max-width:420px}
h2{break-after:avoid} img,tr,.cell,.verdict,.warn{break-inside:avoid}
@media print{body{margin:0;max-width:none} .cell img{height:170px}
 .verdict,.warn,.cell.att,th{-webkit-print-color-adjust:exact;print-color-adjust:exact}}
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


def _sentence(text: str, heading: str = "") -> str:
    """``text`` (HTML-escaped) as a sentence after a bold heading that already says ``heading``: without
    that repeated prefix ("Not enough steps. not enough steps: no complete...") and capitalised."""
    if heading and text.lower().startswith(heading):
        text = text[len(heading):]
    return html.escape(text[:1].upper() + text[1:])


def _img(data: bytes, alt: str, mime: str = "image/png") -> str:
    return f"<img alt='{html.escape(alt)}' src='data:{mime};base64,{base64.b64encode(data).decode()}'>"


@dataclass(frozen=True)
class FitView:
    """What the report shows of the tracking, when the source is a tracking run (every part
    optional): the verdict of ``track.json``, the per-frame record, the contact sheet, the angle
    bands (angle -> (T,) SD degrees) and the frames whose angles are missing (T,) bool."""

    verdict: Verdict | None = None
    fit: FitRecord | None = None
    sheet: ContactSheet | None = None
    bands: dict[str, np.ndarray] | None = None
    flagged: np.ndarray | None = None


def verdict_banner(verdict: Verdict) -> str:
    """The banner at the top: the verdict, its reasons, and its notes (in italics, as notes)."""
    kind = verdict.verdict if verdict.verdict in VERDICTS else "doubtful"
    text = {"ok": "the tracking looks reliable", "doubtful": "check the fit below before using these results",
            "failed": "the tracking failed: these results must not be used"}.get(verdict.verdict, "")  # fmt: skip
    reasons = "".join(f"<li>{html.escape(r)}</li>" for r in verdict.reasons)
    reasons += "".join(f"<li><i>note: {html.escape(n)}</i></li>" for n in verdict.notes)
    return (f"<div class='verdict v-{kind}'><b>Verdict: {html.escape(verdict.verdict)}</b>"
            f"{' — ' + text if text else ''}{f'<ul>{reasons}</ul>' if reasons else ''}</div>")  # fmt: skip


def _sheet_cell(row: SheetRow, fit: FitRecord, rate_hz: float) -> str:
    t = row.frame.index
    unc = fit.lower_limb_uncertainty_mm()[t]
    stats = f"fit {fit.record.fit[t]:.2f}" + (f" · σ {unc:.0f} mm" if math.isfinite(unc) else "")
    imgs = "".join(_img(data, f"frame {t}, {cam}", "image/jpeg") for cam, data in row.images)
    cls = "cell att" if row.frame.attention else "cell"
    return (f"<div class='{cls}'><div>{imgs}</div><div class='cap'><b>#{t}</b> · {t / rate_hz:.2f} s · {stats}"
            f"<br>{html.escape('; '.join(row.frame.reasons))}</div></div>")  # fmt: skip


def fit_section(view: FitView, traj: Trajectory, events: list[GaitEvent], sheet_frames: list[int]) -> str:
    """The tracking fit: a summary line, the fit/uncertainty plot (``events`` marked) and the contact sheet."""
    fit = view.fit
    if fit is None:
        return ""
    rec = fit.record
    n_flag, n_unc = int(fit.flagged.sum()), int((fit.uncertain & ~fit.flagged).sum())
    parts = [
        "<h2>How well the model fits the videos</h2>",
        f"<p>{rec.n_frames} frame{'s' if rec.n_frames != 1 else ''} tracked: {n_flag} flagged by the tracker (fit below {fit.min_fit:g}, subject out "
        f"of view or not found), {n_unc} more with a mean lower-limb uncertainty above {fit.uncertain_mm:g} mm; median "
        f"fit {np.nanmedian(rec.fit):.2f}.</p>",
        _img(plots.fit_timeline(fit, traj.times(), sheet_frames, events), "fit and uncertainty"),
    ]  # fmt: skip
    sheet = view.sheet
    if sheet is None:
        return "\n".join(parts)
    parts.append("<h2>Contact sheet</h2>")
    if not sheet.rows:
        parts.append(f"<p class='note'>{html.escape(sheet.omitted)}</p>")
        return "\n".join(parts)
    cams = ", ".join(cam for cam, _ in sheet.rows[0].images)
    parts.append(
        f"<p class='note'>{html.escape(sheet.note)} Cameras left to right: {html.escape(cams)}. Left side red, right "
        "green, trunk and head blue. The detected gait events, and more frames where the tracker flagged the fit "
        f"or the uncertainty is high (framed in red). σ: mean lower-limb uncertainty.</p>"
    )
    parts.append("<div class='sheet'>" + "".join(_sheet_cell(r, fit, traj.rate_hz) for r in sheet.rows) + "</div>")
    return "\n".join(parts)


def angle_time_section(analysis: GaitAnalysis, view: FitView) -> str:
    """Hip, knee and ankle flexion over time with their uncertainty bands, and what the band is."""
    note = ("Band: ± 2 SD of the angle when every point is displaced at random, independently, by its reported "
            "uncertainty (an RMS 3D distance; 32 seeded draws through the same angle computation). Errors shared by "
            "several points or frames, such as a leg swap, are not in it. A band reaching far past its curves is cut "
            "at the panel's edge: there the angle is not known to better than the panel's height."
            if view.bands is not None else
            "No band: this trajectory carries no per-point uncertainty.")  # fmt: skip
    img = _img(plots.angle_time_curves(analysis, view.bands, view.flagged), "flexion angles over time")
    return f"<h2>Flexion angles over time</h2>{img}<p class='note'>{note}</p>"


#: the frame of a marker file's points as the report names it (read z up: gaitcap.markers.axes)
_LAB_FRAME = "the marker file's x axis, z up"


def _direction_text(direction: object, frame: str = "the calibration's x axis") -> str:
    """A walking direction (x, y, z) in the trajectory's frame (``frame`` names its x axis: the
    calibration's for a tracking run, :data:`_LAB_FRAME` for a marker file) as a heading a person
    reads, in degrees from the x axis towards y ("90° from x, along +y"), or as given when it is not
    a vector."""
    try:
        x, y = float(direction[0]), float(direction[1])  # type: ignore[index]
    except (TypeError, ValueError, IndexError):
        return html.escape(str(direction))
    heading = math.degrees(math.atan2(y, x))
    along = max((abs(x), "+x" if x > 0 else "-x"), (abs(y), "+y" if y > 0 else "-y"))[1]
    return f"{heading:.0f}° from {frame} (nearest to {along})"


#: the angle note of a pelvis frame without ASIS/PSIS markers (a tracking run's): what it does to the angles
_NO_PELVIS_MARKERS = (
    " Without ASIS/PSIS markers the pelvis's anatomical anterior tilt (typically about 10°) is not known: pelvic tilt "
    "is then the inclination of the pelvis-thorax line (0 without a thorax point), and hip flexion, measured from "
    "that pelvis, reads lower than Plug-in-Gait's by about as much (5° and 11° on the two Plug-in-Gait walks of "
    "scripts/validate_gait.py); compare the shapes and ranges of motion, not these two angles' values, with "
    "marker-based norms (see gaitcap.gait.angles)."
)


#: the angle note of a tracking run whose verdict notes feet placed off the masks (quality._support_notes)
_FEET_OFF_MASKS = (
    " The ankle angles come from the tracked heel and toe points. This run's verdict notes feet placed where "
    "the masks show little of them, and there the heel and toe follow the legs, not the feet (on the demo's "
    "walk the left ankle read -59 to 31° against Plug-in-Gait's -10 to 20°): look at the feet in the contact "
    "sheet before reading the ankle curves clinically."
)


def _feet_off_masks(view: FitView) -> bool:
    """The run's verdict notes feet placed where the silhouettes have little of them."""
    return view.verdict is not None and feet_off_masks(view.verdict.notes)


def parameter_table(analysis: GaitAnalysis) -> str:
    p = analysis.parameters
    rows = ["<thead><tr><th>Parameter</th><th>Overall</th><th>Left</th><th>Right</th><th>Symmetry index (%)</th></tr>"
            "</thead>"]  # fmt: skip
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
    note = ("<p class='note'>A dash (–): not measured (no complete cycle or step of that side). A blank cell: not "
            "defined (no overall value of a parameter taken side by side, or no symmetry index: it needs both "
            "sides).</p>")  # fmt: skip
    return "<table>" + rows[0] + "<tbody>" + "".join(rows[1:]) + "</tbody></table>" + note


def _head(title: str, view: FitView) -> list[str]:
    """The page's head, its heading and the verdict's banner. The verdict is in the page's title too, so
    that a browser prints it in the header of every page, not on the first only."""
    page_title = f"{title} — verdict: {view.verdict.verdict}" if view.verdict is not None else title
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(page_title)}</title>",
             f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>"]  # fmt: skip
    if view.verdict is not None:
        parts.append(verdict_banner(view.verdict))
    return parts


def render_fit_report(traj: Trajectory, view: FitView, problem: str, title: str = "Gait report",
                      sheet_frames: list[int] | None = None) -> str:  # fmt: skip
    """The report of a tracking run whose gait analysis could not run (``problem`` says why): the
    verdict and how the model fits the videos."""
    parts = _head(title, view)
    if view.verdict is not None and view.verdict.verdict == "failed":  # the cause, before its consequence
        problem = f"the tracking failed (its verdict, above): {problem}"
    parts.append(f"<div class='warn'><b>No gait analysis.</b> {_sentence(problem)}</div>")
    parts.append(fit_section(view, traj, [], sheet_frames or []))
    parts.append("</body></html>")
    return "\n".join(parts)


def _passes_note(analysis: GaitAnalysis) -> str:
    """"; N passes along the walkway (frames ...), each along its own direction" for a walk that
    turns, else nothing."""
    if len(analysis.passes) < 2:
        return ""
    frames = ", ".join(f"{p.start}-{p.stop - 1}" for p in analysis.passes)
    return f"; {len(analysis.passes)} passes along the walkway (frames {frames}), each along its own direction"


def _events_text(analysis: GaitAnalysis) -> str:
    """The source line's sentence on the events: which the parameters and cycles were computed from
    (detected, or the file's recorded ones with ``--recorded-events``) and how many the file records."""
    n_ref = len(analysis.reference_events)
    if analysis.events_recorded:
        return (f"Events: the {len(analysis.events)} recorded in the file (--recorded-events), used for the "
                "parameters and cycles instead of detected ones.")
    method = html.escape(str(analysis.parameters.info.get("event_method")))
    recorded = f"{n_ref} recorded in the file" if n_ref else "none recorded"
    return f"Events: {len(analysis.events)} detected ({method}), {recorded}."


def render_report(analysis: GaitAnalysis, title: str = "Gait report", view: FitView | None = None,
                  sheet_frames: list[int] | None = None) -> str:  # fmt: skip
    """The whole report as one HTML string; ``view`` adds the tracking's verdict and fit, with the
    frames ``sheet_frames`` of its contact sheet marked on the fit plot."""
    p, traj = analysis.parameters, analysis.trajectory
    info = p.info
    view = view or FitView()
    parts = _head(title, view)
    source = str(traj.meta.get("source", ""))
    frame = _LAB_FRAME if source.lower().endswith((".c3d", ".trc")) else "the calibration's x axis"
    parts.append(
        f"<p class='note'>Source: {html.escape(source)} — {traj.n_frames} frames at "
        f"{traj.rate_hz:g} Hz ({traj.n_frames / traj.rate_hz:.2f} s). Walking direction "
        f"{_direction_text(info.get('walking_direction'), frame)} ({html.escape(str(info.get('direction_method')))}"
        f"{', walking in place, belt speed %.2f m/s' % -info['belt_velocity_m_s'] if info.get('in_place') else ''}"
        f"{_passes_note(analysis)}). "
        f"{_events_text(analysis)} gaitcap {__version__}.</p>"
    )
    if p.status == STATUS_NOT_ENOUGH_STEPS:
        parts.append(f"<div class='warn'><b>Not enough steps.</b> {_sentence(p.reason, 'not enough steps: ')}</div>")
    elif p.status == STATUS_IMPLAUSIBLE:
        parts.append(f"<div class='warn'><b>Implausible values withheld.</b> "
                     f"{_sentence(p.reason, 'implausible values withheld: ')}</div>")  # fmt: skip
    elif p.reason:
        parts.append(f"<div class='warn'>{html.escape(p.reason)}</div>")
    parts.append(fit_section(view, traj, analysis.events, sheet_frames or []))
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
            + ("" if "ASIS" in analysis.angle_notes.get("pelvis_frame", "") else _NO_PELVIS_MARKERS)
            + " Hip rotation comes from the knee's flexion plane: reliable only while the knee is flexed."
            + (_FEET_OFF_MASKS if _feet_off_masks(view) else "") + "</p>"
        )
    parts.append(angle_time_section(analysis, view))
    parts.append("<h2>Foot trajectories</h2>" + _img(plots.foot_trajectories(analysis), "foot trajectories"))
    parts.append("</body></html>")
    return "\n".join(parts)
