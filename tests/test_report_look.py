"""What a reader of report.html sees: the figures' legends, labels and colours (matplotlib objects,
no browser), and the HTML's structure."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
from gait_walker import Walker

from gaitcap.gait.analysis import analyse
from gaitcap.io.track_h5 import TrackRecord
from gaitcap.report import plots
from gaitcap.report.fit import UNCERTAIN_MM, FitRecord


@pytest.fixture(scope="module")
def analysis():
    return analyse(Walker(duration=4.0, rate_hz=25.0).trajectory())


def _fit(T: int) -> FitRecord:
    """A run whose uncertainty rises above the threshold at the end (where a legend in the corner sat)."""
    names = tuple(f"p{k}" for k in range(14)) + ("hip_l", "hip_r", "knee_l", "knee_r", "ankle_l", "ankle_r")
    sigma = np.full((T, len(names)), 0.05)
    sigma[-T // 3 :] = (UNCERTAIN_MM + 20) / 1000
    rec = TrackRecord(names, 25.0, np.zeros((T, len(names), 3)), sigma, np.zeros((T, 31)), tuple("q" * 31),
                      np.full(T, 0.97), np.zeros(T, np.uint8))  # fmt: skip
    return FitRecord(Path("."), rec)


def _figures(analysis) -> dict[str, plt.Figure]:
    traj = analysis.trajectory
    T = traj.n_frames
    bands = {f"{n}_{s}": np.full(T, 5.0) for n in plots.FLEXION_ANGLES for s in "lr"}
    return {
        "fit": plots.fit_timeline_figure(_fit(T), traj.times(), [0, T // 2, T - 1], analysis.events),
        "angles": plots.angle_curves_figure(analysis),
        "angles over time": plots.angle_time_figure(analysis, bands, None),
        "feet": plots.foot_trajectories_figure(analysis),
        "events": plots.event_timeline_figure(analysis),
    }


def test_no_legend_covers_a_plotting_area(analysis) -> None:
    for name, fig in _figures(analysis).items():
        fig.canvas.draw()
        areas = [ax.get_window_extent() for ax in fig.axes if ax.axison]
        legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + list(fig.legends)
        for legend in legends:
            box = legend.get_window_extent()
            assert not any(box.overlaps(a) for a in areas), f"{name}: the legend covers the curves"
        plt.close(fig)


def test_the_event_lines_colours_are_named(analysis) -> None:
    figs = _figures(analysis)
    fit_labels = [t.get_text() for t in figs["fit"].axes[0].get_legend().get_texts()]
    assert "left foot strike" in fit_labels and "right foot strike" in fit_labels
    feet_labels = [t.get_text() for t in figs["feet"].axes[0].get_legend().get_texts()]
    assert {"left foot strike", "left foot off", "right foot strike", "right foot off"} <= set(feet_labels)
    angle_labels = [t.get_text() for ax in figs["angles"].axes if ax.get_legend() for t in ax.get_legend().get_texts()]
    assert "left foot off (mean)" in angle_labels and "right foot off (mean)" in angle_labels
    for fig in figs.values():
        plt.close(fig)


def test_every_column_of_the_angle_panels_has_its_x_label(analysis) -> None:
    fig = plots.angle_curves_figure(analysis)
    shown = [ax for ax in fig.axes if ax.axison]
    columns: dict[float, list] = {}
    for ax in shown:
        columns.setdefault(round(ax.get_position().x0, 3), []).append(ax)
    assert len(columns) == 3
    for col in columns.values():
        lowest = min(col, key=lambda ax: ax.get_position().y0)
        assert lowest.get_xlabel() == "% gait cycle"
    plt.close(fig)


def test_the_warning_box_does_not_repeat_its_heading() -> None:
    from gaitcap.report.html import render_report

    a = analyse(Walker(duration=0.9).trajectory())
    assert a.parameters.status == "not_enough_steps" and a.parameters.reason.startswith("not enough steps: ")
    box = re.search(r"<div class='warn'>(.*?)</div>", render_report(a)).group(1)
    assert box.lower().count("not enough steps") == 1
    assert box.startswith("<b>Not enough steps.</b> No complete gait cycle (found ")


def test_a_printed_report_keeps_headings_with_their_figures_and_the_verdict_on_every_page() -> None:
    from gaitcap.report.html import FitView, render_report
    from gaitcap.track_summary import read_verdict

    a = analyse(Walker(duration=4.0, rate_hz=25.0).trajectory())
    doubtful = FitView(read_verdict({"verdict": "doubtful", "verdict_reasons": ["x"]}))
    page = render_report(a, "Gait report — walk", doubtful)
    css = re.search(r"<style>(.*?)</style>", page, re.S).group(1)
    assert re.search(r"h2\{[^}]*break-after:avoid", css)  # a heading is not left alone at a page's foot
    assert re.search(r"img[^{]*\{[^}]*break-inside:avoid", css)  # nor a figure or a table row cut in two
    assert re.search(r"@media print\{.*\.cell img\{height:\d+px\}", css, re.S)  # two thumbnails per printed row
    # the table's header row repeats on each printed page
    assert re.search(r"<table><thead><tr><th>Parameter</th>.*?</thead><tbody><tr><td>", page)
    # the browser prints the title in every page's header: the verdict is in it
    assert "<title>Gait report — walk — verdict: doubtful</title>" in page
    assert "<title>Gait report — walk</title>" in render_report(a, "Gait report — walk")


def test_the_walking_direction_is_named_in_the_frame_of_its_source() -> None:
    from dataclasses import replace

    from gaitcap.report.html import render_report

    traj = Walker(duration=4.0, rate_hz=25.0).trajectory()
    lab = "the marker file's x axis, z up"
    for source, frame in (("lab/walk.c3d", lab), ("lab/walk.TRC", lab), ("run/trajectories.h5", "the calibration's x axis")):
        page = render_report(analyse(replace(traj, meta={"source": source})))
        assert re.search(rf"Walking direction -?\d+° from {re.escape(frame)} \(nearest to [+-][xy]\)", page), source
    assert "calibration" not in render_report(analyse(replace(traj, meta={"source": "walk.c3d"}))).split("Events:")[0]


def test_a_wide_uncertainty_band_does_not_squash_its_curve(analysis) -> None:
    T = analysis.trajectory.n_frames
    for sd, cut in ((150.0, True), (1.0, False)):
        bands = {f"{n}_{s}": np.full(T, sd) for n in plots.FLEXION_ANGLES for s in "lr"}
        fig = plots.angle_time_figure(analysis, bands, None)
        for ax, name in zip(fig.axes, plots.FLEXION_ANGLES, strict=True):
            curves = np.concatenate([analysis.angles[f"{name}_{s}"] for s in "lr"])
            lo, hi = np.nanmin(curves), np.nanmax(curves)
            bottom, top = ax.get_ylim()
            assert bottom <= lo and top >= hi, name  # the curves are whole
            if cut:  # the curves fill at least half the panel; the band is cut at its edges
                assert (hi - lo) / (top - bottom) >= 0.5 - 1e-9, (name, bottom, top, lo, hi)
            else:  # a narrow band is shown whole
                assert bottom <= lo - 2 * sd and top >= hi + 2 * sd, name
        plt.close(fig)


def test_the_uncertainty_threshold_is_drawn_clear_of_the_panels_edge(analysis) -> None:
    T = analysis.trajectory.n_frames
    fit = _fit(T)
    fit.record.uncertainty[:] = 0.04  # every frame well under the threshold: the line would sit on the top edge
    fig = plots.fit_timeline_figure(fit, analysis.trajectory.times(), [], analysis.events)
    bottom, top = fig.axes[1].get_ylim()
    assert bottom == 0 and top >= 1.1 * fit.uncertain_mm
    plt.close(fig)


def test_a_cycle_without_an_angle_is_not_counted_in_its_panel() -> None:
    """Each side's curves are over its complete cycles, and the legend said 'left (n=2)' for every panel,
    counting a cycle whose angle is missing throughout (gait-pig.c3d's second left cycle has no pelvis or
    hip angle: its ASIS markers are in a gap) as if it had one (found comparing cycles.h5 with the file's
    own angles). Now curve_stats counts the cycles that have the angle, the legend gives each side's
    complete cycles, and a panel with fewer names them in its title."""
    from gaitcap.markers.motion import read_markers, read_motion
    from gaitcap.report.pipeline import with_pelvis_markers

    pig = Path(__file__).resolve().parent / "fixtures" / "walking" / "gait-pig.c3d"
    a = analyse(with_pelvis_markers(read_motion(pig), read_markers(pig)))
    assert len(a.cycles["left"]) == 2
    assert a.curve_stats("left", "hip_flexion")[2] == 1
    assert a.curve_stats("left", "knee_flexion")[2] == 2
    fig = plots.angle_curves_figure(a)
    titles = {ax.get_title() for ax in fig.axes}
    assert "Hip flexion (+) / extension (left n=1)" in titles
    assert "Knee flexion (+) / extension" in titles
    legend = [t.get_text() for t in fig.axes[-1].get_legend().get_texts()]
    assert legend[:2] == ["left (n=2)", "right (n=2)"]
    plt.close(fig)
