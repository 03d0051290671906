"""Matplotlib figures of the gait report (Agg backend, PNG bytes; no display, no network).

Colours follow the clinical convention: left red, right green.
"""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
import numpy as np  # noqa: E402

from gaitcap.gait.analysis import GaitAnalysis, forward_by_frame  # noqa: E402
from gaitcap.gait.angles import ANGLE_NAMES  # noqa: E402
from gaitcap.gait.events import heel_track, pelvis_track, toe_track  # noqa: E402
from gaitcap.evaluation.metrics import runs  # noqa: E402
from gaitcap.report.fit import FitRecord  # noqa: E402
from gaitcap.trajectory import SIDES, side_suffix  # noqa: E402

COLOURS = {"left": "#d62728", "right": "#2ca02c"}
FLEXION_ANGLES = ("hip_flexion", "knee_flexion", "ankle_dorsiflexion")
ANGLE_TITLES = {
    "pelvis_tilt": "Pelvic tilt (+ anterior)",
    "pelvis_obliquity": "Pelvic obliquity (+ up)",
    "pelvis_rotation": "Pelvic rotation (+ forward)",
    "hip_flexion": "Hip flexion (+) / extension",
    "hip_adduction": "Hip adduction (+) / abduction",
    "hip_rotation": "Hip rotation (+ internal)",
    "knee_flexion": "Knee flexion (+) / extension",
    "ankle_dorsiflexion": "Ankle dorsiflexion (+) / plantarflexion",
}


def _png(fig: plt.Figure) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return buf.getvalue()


def _legend_beside(ax: plt.Axes, extra: list[Line2D] | None = None) -> None:
    """The axes' legend (its labelled artists, then ``extra`` entries) to the right of it, outside the
    plotting area: a legend inside it covers the curves where they run high at the end of a walk (and
    the contact sheet's ticks of the fit plot)."""
    handles = ax.get_legend_handles_labels()[0] + list(extra or [])
    if handles:
        ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)


def _event_handles(sides: list[str], styles: dict[str, str]) -> list[Line2D]:
    """Legend entries of the event lines: one per side and event kind (``styles``: event -> linestyle)."""
    return [Line2D([], [], color=COLOURS[side], ls=ls, lw=1, label=f"{side} {event.replace('_', ' ')}")
            for side in SIDES if side in sides for event, ls in styles.items()]  # fmt: skip


def angle_curves(analysis: GaitAnalysis) -> bytes:
    """Joint angles over 0-100 % of the gait cycle: mean +/- SD per side, foot off marked (PNG)."""
    return _png(angle_curves_figure(analysis))


def angle_curves_figure(analysis: GaitAnalysis) -> plt.Figure:
    """The figure of :func:`angle_curves`; its legend fills the ninth, empty, panel."""
    fig, axes = plt.subplots(3, 3, figsize=(12, 9), layout="constrained")
    x = np.linspace(0, 100, 101)
    for ax, name in zip(axes.flat, ANGLE_NAMES, strict=False):
        fewer = []  # the sides whose cycles lack this angle in some of them
        for side in SIDES:
            mean, sd, n = analysis.curve_stats(side, name)
            if n < len(analysis.cycles[side]):
                fewer.append(f"{side} n={n}")
            if n == 0:
                continue
            c = COLOURS[side]
            ax.plot(x, mean, color=c, lw=1.8)
            if n > 1:
                ax.fill_between(x, mean - sd, mean + sd, color=c, alpha=0.2, lw=0)
            fo = [cy.pct(cy.foot_off_s) for cy in analysis.cycles[side]]
            ax.axvline(float(np.mean(fo)), color=c, ls="--", lw=1)
        ax.set_title(ANGLE_TITLES[name] + (f" ({', '.join(fewer)})" if fewer else ""), fontsize=10)
        ax.set_xlim(0, 100)
        ax.axhline(0, color="0.6", lw=0.6)
        ax.grid(alpha=0.3)
    spare = axes.flat[-1]
    spare.axis("off")
    sides = [side for side in SIDES if analysis.cycles[side]]
    handles = [Line2D([], [], color=COLOURS[side], lw=1.8) for side in sides]
    labels = [f"{side} (n={len(analysis.cycles[side])})" for side in sides]
    handles += [Line2D([], [], color=COLOURS[side], ls="--", lw=1) for side in sides]
    labels += [f"{side} foot off (mean)" for side in sides]
    if handles:
        spare.legend(handles, labels, loc="center", fontsize=10)
    for col in range(axes.shape[1]):  # the lowest panel drawn in each column carries the x label
        shown = [ax for ax in axes[:, col] if ax.axison]
        if shown:
            shown[-1].set_xlabel("% gait cycle")
    for ax in axes[:, 0]:
        ax.set_ylabel("degrees")
    fig.suptitle("Joint angles over the gait cycle (mean ± SD; dashed: foot off)")
    return fig


def foot_trajectories(analysis: GaitAnalysis) -> bytes:
    """Heel and toe along the walking direction relative to the pelvis, and heel height, over time (PNG)."""
    return _png(foot_trajectories_figure(analysis))


def foot_trajectories_figure(analysis: GaitAnalysis) -> plt.Figure:
    """The figure of :func:`foot_trajectories`, legends beside the axes."""
    traj = analysis.trajectory
    t = traj.times()
    pel = pelvis_track(traj)
    # each pass's own direction (a walk up and down a walkway), NaN at its turns (pauses, turns walked round)
    forward = forward_by_frame(analysis.passes, traj.n_frames)
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(12, 6), sharex=True, layout="constrained")
    for side in SIDES:
        c = COLOURS[side]
        heel, toe = heel_track(traj, side), toe_track(traj, side)
        a1.plot(t, np.sum((heel - pel) * forward, axis=1), color=c, lw=1.5, label=f"heel {side}")
        a1.plot(t, np.sum((toe - pel) * forward, axis=1), color=c, lw=1, ls=":", label=f"toe {side}")
        a2.plot(t, heel[:, 2], color=c, lw=1.5, label=f"heel {side}")
        a2.plot(t, toe[:, 2], color=c, lw=1, ls=":", label=f"toe {side}")
        for e in analysis.events:
            if e.side == side:
                a1.axvline(e.time_s, color=c, lw=0.6, ls="-" if e.event == "foot_strike" else "--")
    a1.set_ylabel("forward, relative to pelvis (m)")
    a2.set_ylabel("height (m)")
    a2.set_xlabel("time (s)")
    sides = sorted({e.side for e in analysis.events})
    _legend_beside(a1, _event_handles(sides, {"foot_strike": "-", "foot_off": "--"}))
    a1.grid(alpha=0.3)
    a2.grid(alpha=0.3)
    which = "recorded" if analysis.events_recorded else "detected"
    a1.set_title(f"Foot trajectories (lines: {which} foot strike solid, foot off dashed)")
    return fig


def event_timeline(analysis: GaitAnalysis) -> bytes:
    """Stance phases per side as bars, detected events as ticks, reference events as circles (PNG)."""
    return _png(event_timeline_figure(analysis))


def event_timeline_figure(analysis: GaitAnalysis) -> plt.Figure:
    """The figure of :func:`event_timeline`."""
    traj = analysis.trajectory
    t = traj.times()
    fig, ax = plt.subplots(figsize=(12, 2.6))
    for row, side in enumerate(SIDES):
        c = COLOURS[side]
        for cy in analysis.cycles[side]:
            ax.broken_barh([(cy.start_s, cy.foot_off_s - cy.start_s)], (row - 0.3, 0.6), color=c, alpha=0.35)
        for e in analysis.events:
            if e.side == side:
                ax.plot(e.time_s, row, marker="|" if e.event == "foot_strike" else "x", color=c, ms=16, mew=2)
        for e in () if analysis.events_recorded else analysis.reference_events:
            if e.side == side:
                ax.plot(e.time_s, row + 0.38, marker="o", mfc="none", color="k", ms=6)
    ax.set_yticks([0, 1], list(SIDES))
    ax.set_xlim(t[0], t[-1])
    ax.set_ylim(-0.6, 1.7)
    ax.set_xlabel("time (s)")
    which = "recorded (used)" if analysis.events_recorded else "detected"
    circles = "; o recorded in the file" if analysis.reference_events and not analysis.events_recorded else ""
    ax.set_title(f"Event timeline (bars: stance of complete cycles; {which}: | foot strike, x foot off{circles})")
    ax.grid(axis="x", alpha=0.3)
    return fig


def _shade(ax: plt.Axes, t: np.ndarray, mask: np.ndarray, colour: str, label: str) -> None:
    """Shade the frames of ``mask`` (T,) over their frame's duration, one legend entry."""
    half = 0.5 * float(np.median(np.diff(t))) if len(t) > 1 else 0.5
    for k, (a, b) in enumerate(runs(mask)):
        ax.axvspan(t[a] - half, t[b - 1] + half, color=colour, alpha=0.25, lw=0, label=label if k == 0 else None)


def fit_timeline(fit: FitRecord, times: np.ndarray, sheet: list[int], events: list | None = None) -> bytes:
    """The silhouette fit and the lower-limb uncertainty per frame over ``times`` (T,) seconds, the
    flagged (red) and uncertain (orange) frames shaded, the contact sheet's frames ticked, foot
    strikes as dotted lines (PNG)."""
    return _png(fit_timeline_figure(fit, times, sheet, events))


def fit_timeline_figure(fit: FitRecord, times: np.ndarray, sheet: list[int], events: list | None = None) -> plt.Figure:
    """The figure of :func:`fit_timeline`, legends beside the axes (the foot strikes' colours in the first)."""
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(12, 4.6), sharex=True, layout="constrained")
    rec = fit.record
    a1.plot(times, rec.fit, color="k", lw=1.4, marker=".", ms=4, label="fit")
    a1.axhline(fit.min_fit, color="#d62728", ls="--", lw=1, label=f"min_fit {fit.min_fit:g}")
    a2.plot(times, fit.lower_limb_uncertainty_mm(), color="#1f77b4", lw=1.4, marker=".", ms=4,
            label="lower-limb uncertainty (mean)")  # fmt: skip
    a2.axhline(fit.uncertain_mm, color="#ff7f0e", ls="--", lw=1, label=f"{fit.uncertain_mm:g} mm")
    for ax in (a1, a2):
        _shade(ax, times, fit.flagged, "#d62728", "flagged")
        _shade(ax, times, fit.uncertain & ~fit.flagged, "#ff7f0e", "uncertain")
        for e in events or []:
            if e.event == "foot_strike":
                ax.axvline(e.time_s, color=COLOURS[e.side], ls=":", lw=1)
        ax.grid(alpha=0.3)
    strikes = sorted({e.side for e in events or [] if e.event == "foot_strike"})
    _legend_beside(a1, _event_handles(strikes, {"foot_strike": ":"}))
    _legend_beside(a2)
    a1.plot(times[sheet], np.full(len(sheet), 1.02), "v", color="0.3", ms=5, clip_on=False)
    a1.set_ylim(min(0.0, float(np.nanmin(rec.fit, initial=0.0)) - 0.05), 1.05)  # a fit below 0: more XOR than |S|
    a1.set_ylabel("fit (1 − XOR/|S|)")
    a2.set_ylabel("mm")
    a2.set_ylim(0, max(a2.get_ylim()[1], 1.15 * fit.uncertain_mm))  # the threshold's line clear of the top edge
    a2.set_xlabel("time (s)")
    a1.set_title("Silhouette fit and uncertainty per frame (▼ frames on the contact sheet; dotted: foot strikes)")
    return fig


def angle_time_curves(analysis: GaitAnalysis, bands: dict[str, np.ndarray] | None, flagged: np.ndarray | None) -> bytes:
    """Hip, knee and ankle flexion per frame and side over time, with a band of ±2 ``bands`` (T,)
    degrees per angle (when given) and the flagged frames (T,) bool shaded (PNG)."""
    return _png(angle_time_figure(analysis, bands, flagged))


#: a flexion panel shows its curves' range and at most this much of it (and BAND_MARGIN_MIN_DEG) beyond each end
BAND_MARGIN_FRACTION = 0.5
BAND_MARGIN_MIN_DEG = 15.0


def _fit_to_curves(ax: plt.Axes, curves: list[np.ndarray]) -> None:
    """Limit ``ax``'s y range to the ``curves`` (degrees) and a margin (:data:`BAND_MARGIN_FRACTION`
    of their span, at least :data:`BAND_MARGIN_MIN_DEG`), when their bands reach further: a band of
    ±150° (a foot whose points are very uncertain) would otherwise squash its curve into a few pixels.
    A band past the margin is cut at the panel's edge."""
    values = np.concatenate([np.asarray(c, float).ravel() for c in curves])
    values = values[np.isfinite(values)]
    if not len(values):
        return
    lo, hi = float(values.min()), float(values.max())
    margin = max(BAND_MARGIN_MIN_DEG, BAND_MARGIN_FRACTION * (hi - lo))
    bottom, top = ax.get_ylim()
    ax.set_ylim(max(bottom, lo - margin), min(top, hi + margin))


def angle_time_figure(analysis: GaitAnalysis, bands: dict[str, np.ndarray] | None,
                      flagged: np.ndarray | None) -> plt.Figure:  # fmt: skip
    """The figure of :func:`angle_time_curves`, its legend beside the first axes."""
    t = analysis.trajectory.times()
    fig, axes = plt.subplots(3, 1, figsize=(12, 7.5), sharex=True, layout="constrained")
    for ax, name in zip(axes, FLEXION_ANGLES, strict=True):
        for side in SIDES:
            key, c = f"{name}{side_suffix(side)}", COLOURS[side]
            y = analysis.angles[key]
            ax.plot(t, y, color=c, lw=1.6, label=side)
            if bands is not None and key in bands:
                ax.fill_between(t, y - 2 * bands[key], y + 2 * bands[key], color=c, alpha=0.2, lw=0)
        if flagged is not None and flagged.any():
            _shade(ax, t, flagged, "0.5", "flagged (no angle)")
        _fit_to_curves(ax, [analysis.angles[f"{name}{side_suffix(side)}"] for side in SIDES])
        ax.set_title(ANGLE_TITLES[name], fontsize=10)
        ax.set_ylabel("degrees")
        ax.grid(alpha=0.3)
    _legend_beside(axes[0])
    axes[-1].set_xlabel("time (s)")
    band = " (bands: ± 2 SD from the per-point uncertainty)" if bands is not None else ""
    fig.suptitle(f"Flexion angles over time{band}")
    return fig
