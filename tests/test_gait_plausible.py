"""Gait numbers that are never absurd: events alternate, impossible strike intervals, plausible
ranges, and the step-level parameters of a clip without a complete cycle."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner
from gait_walker import Walker

from gaitcap.cli.main import cli
from gaitcap.gait.analysis import analyse
from gaitcap.gait.cycles import find_cycles
from gaitcap.gait.events import detect_events, estimate_walking_direction
from gaitcap.gait.options import GaitOptions, PlausibleRanges
from gaitcap.gait.parameters import (
    SIDE_KEYS,
    STATUS_IMPLAUSIBLE,
    STATUS_NOT_ENOUGH_STEPS,
    compute_parameters,
)
from gaitcap.io.trajectories_h5 import write_trajectory
from gaitcap.trajectory import POINT_NAMES, GaitEvent, Trajectory

EXACT = GaitOptions(lowpass_hz=0.0, refine=False)


def _ev(t: float, side: str, kind: str) -> GaitEvent:
    return GaitEvent(t, side, kind, "test")  # type: ignore[arg-type]


def _strikes(events: list[GaitEvent], side: str) -> np.ndarray:
    return np.array([e.time_s for e in events if e.side == side and e.event == "foot_strike"])


def _all_values(d: dict) -> list[tuple[str, str, float]]:
    """(scope, key, value) of every reported summary value of a parameters.json dict."""
    return [(scope, k, d[scope][k]) for scope in ("overall", "left", "right") for k in SIDE_KEYS if k in d[scope]]


def _assert_in_range(d: dict, ranges: PlausibleRanges) -> None:
    b = ranges.bounds()
    for scope, key, v in _all_values(d):
        assert v is None or b[key][0] <= v <= b[key][1], (scope, key, v)


# --- alternation -------------------------------------------------------------------------------


def test_per_foot_events_alternate_on_a_jittered_walker() -> None:
    w = Walker(duration=6.0)
    tr = w.trajectory()
    rng = np.random.default_rng(3)
    noisy = replace(tr, points=tr.points + rng.normal(0.0, 0.015, tr.points.shape))
    events, _ = detect_events(noisy)
    for side in ("left", "right"):
        kinds = [e.event for e in events if e.side == side]
        assert len(kinds) >= 8
        assert all(a != b for a, b in zip(kinds[:-1], kinds[1:], strict=True)), kinds


def test_a_cycle_holds_exactly_one_strike_of_the_other_foot() -> None:
    # right strikes every 1.1 s; the left strike at 1.65 s was missed, and the left foot off at 2.33 s
    events = [_ev(t, "right", "foot_strike") for t in (0.0, 1.1, 2.2, 3.3)]
    events += [_ev(t, "right", "foot_off") for t in (0.68, 1.78, 2.88)]
    events += [_ev(t, "left", "foot_strike") for t in (0.55, 2.75)]
    events += [_ev(t, "left", "foot_off") for t in (0.13, 1.23)]
    right = find_cycles(events, "right")
    # (1.1, 2.2) has no left strike while the left foot strikes before and after: not a cycle
    assert [(c.start_s, c.end_s) for c in right] == [(0.0, 1.1), (2.2, 3.3)]
    # the left "cycle" 0.55 -> 2.75 holds one left foot off but two right strikes: not a cycle
    assert find_cycles(events, "left") == []


def test_a_cycle_without_a_strike_of_the_other_foot_is_not_complete() -> None:
    events = [_ev(t, "right", "foot_strike") for t in (0.0, 1.1)] + [_ev(0.68, "right", "foot_off")]
    events += [_ev(t, "left", "foot_strike") for t in (1.65, 2.75)]  # the left leg found late
    assert find_cycles(events, "right") == []
    assert len(find_cycles([*events, _ev(0.55, "left", "foot_strike")], "right")) == 1


# --- two strikes within an impossible interval -------------------------------------------------


def _hopping(left_scale: float = 1.0) -> Trajectory:
    """Both feet in phase (each landing with the other in the same frame), the left foot's forward
    excursion about the pelvis scaled by ``left_scale`` (weaker evidence for its strikes)."""
    tr = Walker(asym=-0.5, duration=5.0).trajectory()
    pts = tr.points.copy()
    pel = pts[:, POINT_NAMES.index("pelvis")]
    for name in ("heel_l", "toe_l", "ankle_l"):
        i = POINT_NAMES.index(name)
        pts[:, i] = pel + left_scale * (pts[:, i] - pel)
        pts[:, i, 2] = tr.points[:, i, 2]
    return replace(tr, points=pts)


@pytest.mark.parametrize("left_scale", [1.0, 0.6])
def test_strikes_of_both_feet_in_the_same_frame_are_not_both_kept(left_scale: float) -> None:
    tr = _hopping(left_scale)
    direction = estimate_walking_direction(tr)
    events, _ = detect_events(tr, EXACT, direction)
    left, right = _strikes(events, "left"), _strikes(events, "right")
    assert len(left) + len(right) >= 4
    min_step = EXACT.plausible.min_step_s
    assert min_step == pytest.approx(0.24)
    gaps = np.abs(left[:, None] - right[None, :]) if len(left) and len(right) else np.array([np.inf])
    assert gaps.min() >= min_step
    if left_scale < 1.0:  # the stronger evidence (the right heel's larger excursion) wins
        assert len(right) >= 3 and len(left) == 0
    p = compute_parameters(tr, events, direction)
    _assert_in_range(p.to_dict(), PlausibleRanges())


def test_a_cadence_of_44136_steps_per_min_is_withheld_not_written(tmp_path) -> None:
    # the case: left and right foot strikes detected in the same frame
    w = Walker(duration=4.0)
    tr = w.trajectory()
    truth = w.truth_events()
    rights = [e for e in truth if e.side == "right" and e.event == "foot_strike"]
    events = sorted(truth + [_ev(e.time_s + 60.0 / 44136, "left", "foot_strike") for e in rights])
    p = compute_parameters(tr, events, estimate_walking_direction(tr))
    d = p.to_dict()
    # no cycle is left either: each holds two strikes of the other foot
    assert p.status == STATUS_NOT_ENOUGH_STEPS and d["overall"]["n_strides"] == 0
    assert "cadence_steps_per_min" in d["implausible"] and "30 to 250 steps/min" in d["implausible"]["cadence_steps_per_min"]
    assert "implausible values withheld" in p.reason
    _assert_in_range(d, PlausibleRanges())
    assert "44136" not in json.dumps(d)


# --- every range -------------------------------------------------------------------------------


def _excluding(key: str, truth: float) -> PlausibleRanges:
    """Default ranges but ``key``'s, set to exclude ``truth`` (above it: a highest cadence below
    the truth would also drop the walker's strikes as closer than the shortest step)."""
    return PlausibleRanges(**{key: (truth + 10.0, truth + 20.0) if key.endswith("pct") or key.startswith("cadence")
                              else (truth + 1.0, truth + 2.0)})  # fmt: skip


W = Walker(duration=6.0)
TRUTH = {
    "cadence_steps_per_min": 120.0 / W.stride_time,
    "stride_length_m": W.stride_length,
    "step_length_m": W.stride_length / 2,
    "step_width_m": W.step_width,
    "speed_m_s": W.speed,
    "stance_pct": 100.0 * W.stance,
    "double_support_pct": 200.0 * (W.stance - 0.5),
}
#: the keys withheld with each range (derived ranges: step time <- cadence, swing <- stance ...)
WITHHELD = {
    "cadence_steps_per_min": {"cadence_steps_per_min", "step_time_s", "stride_time_s"},
    "stance_pct": {"stance_pct", "swing_pct", "single_support_pct"},
}


@pytest.mark.parametrize("key", sorted(TRUTH))
def test_each_range_withholds_what_falls_outside(key: str, tmp_path) -> None:
    ranges = _excluding(key, TRUTH[key])
    a = analyse(W.trajectory(), EXACT.model_copy(update={"plausible": ranges}))
    p = a.parameters
    d = p.to_dict()
    expect = WITHHELD.get(key, {key})
    assert p.status == STATUS_IMPLAUSIBLE and not p.ok
    assert set(d["implausible"]) == expect
    for scope in ("overall", "left", "right"):
        for k in SIDE_KEYS:
            assert (d[scope][k] is None) == (k in expect), (scope, k)
    _assert_in_range(d, ranges)


@pytest.mark.parametrize(
    ("walker", "key"),
    [(Walker(step_width=0.8), "step_width_m"), (Walker(speed=2.5, stride_time=1.1), "stride_length_m"),
     (Walker(speed=3.3, stride_time=0.72), "speed_m_s")],
)  # fmt: skip
def test_default_ranges_withhold_a_wide_step_a_long_stride_and_running_speed(walker: Walker, key: str) -> None:
    a = analyse(replace(walker, duration=6.0).trajectory(), EXACT)
    d = a.parameters.to_dict()
    assert key in d["implausible"] and d["overall"][key] is None and d["status"] == STATUS_IMPLAUSIBLE
    _assert_in_range(d, PlausibleRanges())


def test_ranges_are_validated() -> None:
    with pytest.raises(ValueError, match="low end"):
        PlausibleRanges(step_width_m=(0.6, 0.0))
    assert set(PlausibleRanges().bounds()) == set(SIDE_KEYS)


# --- no complete cycle -------------------------------------------------------------------------


def test_without_a_complete_cycle_the_step_level_parameters_are_reported(tmp_path) -> None:
    w = Walker(duration=1.0, first_strike_right=0.1)
    tr = w.trajectory()
    events, direction = detect_events(tr, EXACT)
    p = compute_parameters(tr, events, direction)
    d = p.to_dict()
    assert p.status == STATUS_NOT_ENOUGH_STEPS and d["overall"]["n_strides"] == 0
    assert d["overall"]["n_steps"] >= 1
    assert d["overall"]["step_time_s"] == pytest.approx(w.stride_time / 2, abs=0.01)
    assert d["overall"]["step_length_m"] == pytest.approx(w.stride_length / 2, abs=0.02)
    assert d["overall"]["step_width_m"] == pytest.approx(w.step_width, abs=1e-3)
    assert d["overall"]["cadence_steps_per_min"] == pytest.approx(120 / w.stride_time, rel=0.02)
    for k in ("stride_length_m", "stride_time_s", "speed_m_s", "stance_pct", "double_support_pct"):
        assert d["overall"][k] is None
    assert "stride length, stride time, speed" in p.reason and "need a complete cycle" in p.reason

    out = tmp_path / "OUT"
    write_trajectory(out / "trajectories.h5", tr)
    res = CliRunner().invoke(cli, ["report", str(out)])
    assert res.exit_code == 3
    assert f"step {d['overall']['step_length_m']:.3f} m" in res.output and "not enough steps" in res.output


def test_report_exits_4_and_says_why_when_values_are_withheld(tmp_path) -> None:
    out = tmp_path / "OUT"
    write_trajectory(out / "trajectories.h5", Walker(step_width=0.8, duration=6.0).trajectory())
    res = CliRunner().invoke(cli, ["report", str(out)])
    assert res.exit_code == 4
    assert "implausible values withheld: step_width_m" in res.output
    p = json.loads((out / "gait" / "parameters.json").read_text())
    assert p["status"] == "implausible" and p["overall"]["step_width_m"] is None
    rows = [r.split(",") for r in (out / "gait" / "parameters.csv").read_text().splitlines()]
    assert all(r[2] == "" for r in rows if r[1] == "step_width_m")
    assert "Implausible values withheld" in (out / "gait" / "report.html").read_text()
    assert math.isfinite(json.loads(json.dumps(p["overall"]["cadence_steps_per_min"])))
