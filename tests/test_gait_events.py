"""Event detection and spatio-temporal parameters on a kinematic walker with exact truth."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from gait_walker import Walker

from gaitcap.gait.cycles import N_CYCLE_POINTS, GaitCycle, find_cycles, normalise_cycle
from gaitcap.gait.events import detect_events, estimate_walking_direction
from gaitcap.gait.options import GaitOptions
from gaitcap.gait.parameters import STATUS_NOT_ENOUGH_STEPS, compute_parameters
from gaitcap.trajectory import GaitEvent, Trajectory

# the walker's Zeni extrema are exact: no filter bias, no refinement (its feet land flat and stop
# dead, so the heel's "lowest point" is a plateau that starts at the strike)
EXACT = GaitOptions(lowpass_hz=0.0, refine=False)


def _match(found: list[GaitEvent], truth: list[GaitEvent]) -> list[float]:
    """Error (s) of each truth event to the nearest detection of the same side and kind."""
    errs = []
    for t in truth:
        same = [e.time_s for e in found if (e.side, e.event) == (t.side, t.event)]
        errs.append(min((abs(x - t.time_s) for x in same), default=math.inf))
    return errs


@pytest.mark.parametrize("walker", [Walker(), Walker(heading_deg=-120.0, origin=(3.0, 4.0)), Walker(in_place=True)])
def test_events_match_the_truth_overground_and_in_place(walker: Walker) -> None:
    tr = walker.trajectory()
    events, direction = detect_events(tr, EXACT)
    truth = walker.truth_events()
    assert len(events) == len(truth)
    assert max(_match(events, truth)) <= 0.5 / walker.rate_hz + 1e-9
    h = np.radians(walker.heading_deg)
    assert direction.forward @ [np.cos(h), np.sin(h), 0] == pytest.approx(1.0, abs=1e-3)
    assert direction.in_place == walker.in_place


def test_default_options_keep_events_within_a_few_frames() -> None:
    # the walker's feet land flat and stop dead: the refinement's "heel lowest point" is the start
    # of a plateau, which the low-pass smears late; real heels (tests/test_gait_real.py) do better
    w = Walker()
    events, _ = detect_events(w.trajectory())
    assert len(events) == len(w.truth_events())
    assert max(_match(events, w.truth_events())) <= 4.0 / w.rate_hz


def test_refinement_only_at_rates_that_resolve_the_landing() -> None:
    from gaitcap.gait.events import SOURCE, SOURCE_REFINED

    fast, slow = Walker(), Walker(rate_hz=25.0, duration=5.0)
    assert fast.rate_hz >= GaitOptions().refine_min_rate_hz > slow.rate_hz
    fast_events, _ = detect_events(fast.trajectory())
    assert any(e.source == SOURCE_REFINED for e in fast_events)
    slow_events, _ = detect_events(slow.trajectory())
    assert slow_events and all(e.source == SOURCE for e in slow_events)
    # the threshold is an option: lowered, the 25 fps walk is refined too
    forced, _ = detect_events(slow.trajectory(), GaitOptions(refine_min_rate_hz=20.0))
    assert any(e.source == SOURCE_REFINED for e in forced)


def test_a_tracking_runs_trajectories_keep_their_anchors_at_every_rate(tmp_path) -> None:
    """A tracked heel has no sharp landing: its events keep their anchors at 50 Hz and above too,
    unless refine_tracked; read back from a trajectories.h5, the trajectory is known as a tracking run's."""
    from dataclasses import replace

    from gaitcap.gait.events import SOURCE, SOURCE_REFINED
    from gaitcap.io.trajectories_h5 import read_trajectory, write_trajectory
    from gaitcap.trajectory import TRACKED_FORMAT

    fast = Walker().trajectory()
    assert fast.rate_hz >= GaitOptions().refine_min_rate_hz
    write_trajectory(tmp_path / "trajectories.h5", fast)
    tracked = read_trajectory(tmp_path / "trajectories.h5")
    assert tracked.meta["format"] == TRACKED_FORMAT
    kept, _ = detect_events(tracked)
    assert kept and all(e.source == SOURCE for e in kept)
    anchors, _ = detect_events(fast, GaitOptions(refine=False))
    assert [e.time_s for e in kept] == pytest.approx([e.time_s for e in anchors])
    refined, _ = detect_events(tracked, GaitOptions(refine_tracked=True))
    assert any(e.source == SOURCE_REFINED for e in refined)
    marker, _ = detect_events(replace(tracked, meta={**tracked.meta, "format": "c3d"}))
    assert any(e.source == SOURCE_REFINED for e in marker)


@pytest.mark.parametrize("walker", [Walker(), Walker(in_place=True, heading_deg=200.0), Walker(rate_hz=25.0, duration=5.0)])
def test_parameters_match_the_closed_form_truth(walker: Walker) -> None:
    tr = walker.trajectory()
    events, direction = detect_events(tr, EXACT)
    p = compute_parameters(tr, events, direction)
    assert p.ok
    tol_t = 1.0 / walker.rate_hz
    o = p.overall
    assert o["cadence_steps_per_min"] == pytest.approx(120.0 / walker.stride_time, rel=0.02)
    assert o["speed_m_s"] == pytest.approx(walker.speed, rel=0.02)
    assert o["step_width_m"] == pytest.approx(walker.step_width, abs=1e-3)
    assert o["double_support_pct"] == pytest.approx(200 * (walker.stance - 0.5), abs=100 * 2 * tol_t / walker.stride_time)
    for side in ("left", "right"):
        s = p.sides[side]
        assert s["n_strides"] >= 2
        assert s["stride_length_m"] == pytest.approx(walker.stride_length, abs=0.01)
        # a strike timed within half a frame moves the swinging heel by at most its swing speed x dt/2
        swing_speed = walker.stride_length / ((1 - walker.stance) * walker.stride_time)
        assert s["step_length_m"] == pytest.approx(walker.stride_length / 2, abs=0.5 * tol_t * swing_speed)
        assert s["stride_time_s"] == pytest.approx(walker.stride_time, abs=tol_t)
        assert s["stance_pct"] == pytest.approx(100 * walker.stance, abs=100 * tol_t / walker.stride_time)
        assert s["stance_pct"] + s["swing_pct"] == pytest.approx(100.0)
        assert s["single_support_pct"] == pytest.approx(100 * (1 - walker.stance), abs=100 * tol_t / walker.stride_time)
    assert abs(p.symmetry["step_time_s"]) < 2.0


def test_asymmetric_steps_show_in_the_symmetry_index() -> None:
    w = Walker(asym=0.06)  # left strike late: right step (L->R) shorter in time than the left step
    tr = w.trajectory()
    events, direction = detect_events(tr, EXACT)
    p = compute_parameters(tr, events, direction)
    left_step, right_step = (0.5 + w.asym) * w.stride_time, (0.5 - w.asym) * w.stride_time
    assert p.sides["left"]["step_time_s"] == pytest.approx(left_step, abs=0.01)
    assert p.sides["right"]["step_time_s"] == pytest.approx(right_step, abs=0.01)
    expected = 100 * (left_step - right_step) / (0.5 * (left_step + right_step))
    assert p.symmetry["step_time_s"] == pytest.approx(expected, abs=2.0)


def test_nan_frames_are_bridged_or_skipped() -> None:
    w = Walker(duration=6.0)
    tr = w.trajectory()
    pts = tr.points.copy()
    rng = np.random.default_rng(7)
    pts[rng.choice(tr.n_frames, 40, replace=False)] = np.nan  # isolated flagged frames
    pts[300:360] = np.nan  # a long gap of 0.6 s
    tr2 = Trajectory(tr.names, pts, tr.rate_hz)
    events, direction = detect_events(tr2, EXACT)
    gap = (3.0, 3.6)
    away = [t for t in w.truth_events() if not gap[0] - 0.15 < t.time_s < gap[1] + 0.15]
    assert max(_match(events, away)) <= 1.0 / w.rate_hz  # found everywhere but at the long gap
    truth = w.truth_events()
    found_err = [min(abs(e.time_s - t.time_s) for t in truth if (t.side, t.event) == (e.side, e.event)) for e in events]
    assert max(found_err) <= 1.0 / w.rate_hz  # no spurious event at the gap edges
    p = compute_parameters(tr2, events, direction)
    assert p.ok and p.overall["cadence_steps_per_min"] == pytest.approx(120 / w.stride_time, rel=0.02)


@pytest.mark.parametrize("duration", [0.5, 0.9])
def test_less_than_one_cycle_gives_not_enough_steps(duration: float) -> None:
    w = Walker(duration=duration)
    tr = w.trajectory()
    events, direction = detect_events(tr)
    p = compute_parameters(tr, events, direction)
    assert p.status == STATUS_NOT_ENOUGH_STEPS and not p.ok
    assert "not enough steps" in p.reason
    d = p.to_dict()
    assert d["left"]["stride_length_m"] is None and d["overall"]["speed_m_s"] is None
    assert d["right"]["n_strides"] == 0


def test_partial_steps_at_the_ends_are_not_events() -> None:
    # start mid-swing and end mid-stance: only interior extrema are events
    w = Walker(first_strike_right=0.05, duration=3.0)
    tr = w.trajectory()
    events, _ = detect_events(tr, EXACT)
    truth = w.truth_events()
    found_err = [min(abs(e.time_s - t.time_s) for t in truth if (t.side, t.event) == (e.side, e.event)) for e in events]
    assert max(found_err) <= 0.5 / w.rate_hz + 1e-9  # nothing spurious at the ends
    inner = [t for t in truth if 0.3 < t.time_s < tr.times()[-1] - 0.3]
    assert max(_match(events, inner)) <= 0.5 / w.rate_hz + 1e-9


def test_walking_direction_is_estimated_not_assumed() -> None:
    for heading in (0.0, 90.0, 180.0, 270.0, 33.0):
        d = estimate_walking_direction(replace(Walker(heading_deg=heading)).trajectory())
        h = np.radians(heading)
        assert d.forward @ [np.cos(h), np.sin(h), 0] > 0.999
        assert np.cross(d.forward, d.left)[2] == pytest.approx(1.0)


def test_a_trajectory_of_no_frame_is_an_input_error() -> None:
    """A trajectory with no frame (a slice past its end) made the walking direction raise numpy's ValueError
    "cannot reshape array of size 0" from analyse and estimate_walking_direction: the InputError of too few
    samples, as for a trajectory of NaN."""
    from gaitcap.errors import InputError
    from gaitcap.gait.analysis import analyse

    traj = Walker().trajectory()
    empty = replace(traj, points=traj.points[:0])
    for f in (estimate_walking_direction, analyse):
        with pytest.raises(InputError, match="too few valid pelvis and heel samples"):
            f(empty)


def test_cycles_and_normalisation() -> None:
    ev = [
        GaitEvent(0.1, "right", "foot_strike"), GaitEvent(0.25, "left", "foot_off"),
        GaitEvent(0.6, "left", "foot_strike"), GaitEvent(0.75, "right", "foot_off"),
        GaitEvent(1.1, "right", "foot_strike"),
    ]  # fmt: skip
    (c,) = find_cycles(ev, "right")
    assert (c.start_s, c.end_s, c.foot_off_s, c.contra_off_s, c.contra_strike_s) == (0.1, 1.1, 0.75, 0.25, 0.6)
    assert find_cycles(ev, "left") == []
    t = np.arange(0, 1.3, 0.01)
    curve = normalise_cycle(3 * t, t, c)
    assert curve.shape == (N_CYCLE_POINTS,)
    assert np.allclose(curve, 3 * np.linspace(0.1, 1.1, 101))
    gap = 3 * t
    gap[40:70] = np.nan
    out = normalise_cycle(gap, t, GaitCycle("right", 0.1, 1.1, 0.75))
    assert np.isnan(out).sum() > 0 and np.isfinite(out[:25]).all()


def _jittered(tr: Trajectory, sd_m: float, seed: int) -> Trajectory:
    """The trajectory with independent Gaussian noise on every coordinate (tracker-like jitter)."""
    rng = np.random.default_rng(seed)
    return Trajectory(tr.names, tr.points + rng.normal(0.0, sd_m, tr.points.shape), tr.rate_hz)


def test_belt_velocity_is_a_slope_over_single_support_robust_to_jitter() -> None:
    # 25 fps, 1 cm of Gaussian jitter on every point (20 seeds): the slope over single support
    # (~0.4 s) misses the belt speed by 0.4 % (median), the median of central-difference velocities
    # over 20-50 % of stance that it replaced by 1.7 %
    from gaitcap.gait.cycles import find_cycles
    from gaitcap.gait.parameters import belt_velocity

    w = Walker(in_place=True, rate_hz=25.0, duration=5.0)
    truth = w.truth_events()
    _, direction = detect_events(w.trajectory(), EXACT)
    cycles = find_cycles(truth, "left") + find_cycles(truth, "right")
    assert all(np.isfinite(c.contra_off_s) and np.isfinite(c.contra_strike_s) for c in cycles)
    bare = [GaitCycle(c.side, c.start_s, c.end_s, c.foot_off_s) for c in cycles]
    errors, errors_bare = [], []
    for seed in range(20):
        tr = _jittered(w.trajectory(), 0.01, seed)
        errors.append(abs(belt_velocity(tr, direction, cycles) / -w.speed - 1.0))
        # without the contralateral events, the typical single support (1/6-5/6 of stance) is used
        errors_bare.append(abs(belt_velocity(tr, direction, bare) / -w.speed - 1.0))
    assert np.median(errors) < 0.008 and max(errors) < 0.03
    assert np.median(errors_bare) < 0.008 and max(errors_bare) < 0.03
    # overground the belt is still
    over = Walker(rate_hz=25.0, duration=5.0)
    _, d_over = detect_events(over.trajectory(), EXACT)
    assert belt_velocity(over.trajectory(), d_over, cycles) == 0.0


@pytest.mark.parametrize("edge", ["end", "start"])
def test_an_event_next_to_the_trial_edge_is_found_when_it_keeps_the_rhythm(edge: str) -> None:
    # 25 fps; the right foot strikes at frame 88.25 and 5.75: cut so that the sampled extremum is
    # the next-to-last (second) sample, its turn seen on one sample only
    w = Walker(rate_hz=25.0, duration=3.6)
    tr = w.trajectory()
    if edge == "start":
        tr = Trajectory(tr.names, tr.points[5:], tr.rate_hz, 5 / tr.rate_hz)
    events, _ = detect_events(tr, EXACT)
    strike = 88.25 / w.rate_hz if edge == "end" else 5.75 / w.rate_hz
    near = [e for e in events if (e.side, e.event) == ("right", "foot_strike") and abs(e.time_s - strike) <= 1 / w.rate_hz]
    assert len(near) == 1
    inside = [t for t in w.truth_events() if tr.t0_s <= t.time_s <= tr.times()[-1]]
    assert len(events) == len(inside)


def test_a_turn_on_the_last_sample_that_breaks_the_rhythm_is_not_an_event() -> None:
    # the trial ends mid-swing of the right foot (strike at frame 88.25, swing from 77.8); a
    # mistracked last frame puts the right heel back: a turn on one sample, a swing 40 % short
    w = Walker(rate_hz=25.0, duration=86 / 25.0)
    tr = w.trajectory()
    clean, direction = detect_events(tr, EXACT)
    pts = tr.points.copy()
    heel, toe = tr.names.index("heel_r"), tr.names.index("toe_r")
    for j in (heel, toe):
        pts[-1, j, :2] = pts[-2, j, :2] - 0.1 * direction.forward[:2]
    bad = Trajectory(tr.names, pts, tr.rate_hz)
    events, _ = detect_events(bad, EXACT)
    assert [(e.side, e.event, round(e.time_s, 6)) for e in events] == [(e.side, e.event, round(e.time_s, 6)) for e in clean]
    # it is the rhythm that rejects it: with any tolerance it would be a right foot strike
    loose, _ = detect_events(bad, EXACT.model_copy(update={"edge_rhythm_tolerance": 10.0}))
    assert len(loose) == len(clean) + 1
    assert max(loose).side == "right" and max(loose).event == "foot_strike"


def test_an_edge_event_never_displaces_a_full_one() -> None:
    from gaitcap.gait.events import _alternate, _Extremum

    full = _Extremum(40.0, 0.3, "right", "foot_off")
    edge = _Extremum(52.0, 0.9, "right", "foot_off", edge="end")
    assert _alternate([full, edge]) == [full]
    assert _alternate([_Extremum(40.0, 0.3, "right", "foot_off", edge="start"), edge])[0].prominence == 0.9


def test_a_slow_walk_is_refined_over_windows_as_long_as_its_strides() -> None:
    # the embedded Plug-in-Gait walk slowed three times (the same motion, strides of 3.3 s, still
    # sampled at 100 Hz): its heel lands 110-130 ms after the Zeni anchor, past the 0.12 s window
    # set for a normal cadence, so every foot strike kept its anchor, over 110 ms early
    from gaitcap.data import embedded_walk
    from gaitcap.gait.events import SOURCE_REFINED
    from gaitcap.markers.motion import read_motion

    walk = read_motion(embedded_walk())
    k = 3.0
    t = walk.times()
    slow_t = np.arange(t[0] * k, t[-1] * k, 1.0 / walk.rate_hz) / k
    flat = walk.points.reshape(walk.n_frames, -1)
    points = np.stack([np.interp(slow_t, t, flat[:, j]) for j in range(flat.shape[1])], axis=1)
    slow = replace(walk, points=points.reshape(len(slow_t), -1, 3), t0_s=walk.t0_s * k,
                   events=tuple(replace(e, time_s=e.time_s * k) for e in walk.events))  # fmt: skip
    events, _ = detect_events(slow)
    strikes = [e for e in events if e.event == "foot_strike"]
    assert len(strikes) == 4 and all(e.source == SOURCE_REFINED for e in strikes)
    errors = [e.time_s - min((r for r in slow.events if (r.side, r.event) == (e.side, e.event)),
                             key=lambda r: abs(r.time_s - e.time_s)).time_s for e in strikes]  # fmt: skip
    assert all(-0.04 < x < 0.08 for x in errors), errors
    # at its own pace the walk is refined over the windows as given
    own, _ = detect_events(walk)
    assert [e.time_s for e in own] == [e.time_s for e in detect_events(walk, GaitOptions(window_stride_s=100.0))[0]]


def test_strikes_dropped_for_a_cadence_above_the_plausible_are_warned_about(caplog) -> None:
    """Steps of 0.23 s (261 steps/min, above the plausible 250): most strikes are dropped as closer than
    the shortest plausible step, and the analysis found 'not enough steps' with only an info line saying
    why; a warning now names the cause. A walk of normal cadence drops none and says nothing."""
    import logging

    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        detect_events(Walker(stride_time=1.1, duration=4.0).trajectory())
        assert "dropped as closer" not in caplog.text
        detect_events(Walker(stride_time=0.46, speed=1.8, duration=4.0).trajectory())
    assert "foot strikes dropped as closer than 24.0 frames to the other foot's" in caplog.text
    assert "a cadence above the plausible maximum" in caplog.text
