"""A walk up and down a walkway: its passes, and the gait analysis pass by pass."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from gait_walker import Walker
from scipy.spatial.transform import Rotation

from gaitcap.gait.analysis import analyse, angles_by_pass, parameters_by_pass, within
from gaitcap.gait.events import detect_events
from gaitcap.gait.options import GaitOptions
from gaitcap.gait.passes import paused_at_turns, turns, walk_passes
from gaitcap.trajectory import TOE_RELEASES, GaitEvent, Trajectory

EXACT = GaitOptions(lowpass_hz=0.0, refine=False)  # as test_gait_events: the walker's extrema are exact
RATE = 100.0


def _up_and_down(pivot_s: float = 1.0, drift_m: float = 0.0) -> tuple[Trajectory, list[GaitEvent], int, int]:
    """The walker up the room (4 s at 30 degrees), a pivot of 180 degrees on the spot about the pelvis
    (``pivot_s``; the last pose turned, feet sliding; the whole body drifting ``drift_m`` further up
    the room meanwhile, as a tracked pelvis can), and the walker back from the pivot's end (4 s): the
    trajectory, the true events of both walks, and the pivot's first and last frames."""
    up = Walker(duration=4.0, heading_deg=30.0)
    a = up.trajectory()
    pel = a.points[-1, a.names.index("pelvis")]
    n_pivot = int(round(pivot_s * RATE))
    angles = np.pi * (1 - np.cos(np.linspace(0, np.pi, n_pivot + 1)[1:])) / 2
    centre = pel * [1.0, 1.0, 0.0]
    pivot = (a.points[-1] - centre) @ Rotation.from_euler("z", angles[:, None]).as_matrix().transpose(0, 2, 1) + centre
    heading = np.radians(30.0)
    drift = drift_m * np.linspace(0, 1, n_pivot)[:, None] * [np.cos(heading), np.sin(heading), 0.0]
    pivot = pivot + drift[:, None, :]
    pel = pivot[-1, a.names.index("pelvis")]
    down = Walker(duration=4.0, heading_deg=210.0, origin=(float(pel[0]), float(pel[1])))
    b = down.trajectory()
    shift = (len(a.points) + n_pivot) / RATE
    events = up.truth_events() + [replace(e, time_s=e.time_s + shift) for e in down.truth_events()]
    points = np.concatenate([a.points, pivot, b.points])
    return Trajectory(a.names, points, RATE), sorted(events), len(a.points), len(a.points) + n_pivot - 1


def test_a_straight_walk_is_one_pass_and_a_walk_on_the_spot_too():
    for walker in (Walker(), Walker(in_place=True), Walker(heading_deg=-120.0, origin=(3.0, 4.0))):
        tr = walker.trajectory()
        xy = tr.point("pelvis")[:, :2]
        assert walk_passes(xy, RATE) == [(0, tr.n_frames)]
        assert not paused_at_turns(xy, RATE).any()


def test_a_walk_up_and_down_is_two_passes_without_the_pivot():
    tr, _, first, last = _up_and_down()
    xy = tr.point("pelvis")[:, :2]
    at = turns(xy)
    assert len(at) == 1 and first <= at[0] <= last + 1
    passes = walk_passes(xy, RATE)
    assert len(passes) == 2
    (a0, a1), (b0, b1) = passes
    assert a0 == 0 and b1 == tr.n_frames
    # the pauses: the pivot, less the frames whose 0.4 s span still holds enough walking (up to
    # 0.2 s); the passes end half the span before them
    paused = np.flatnonzero(paused_at_turns(xy, RATE))
    assert first <= paused[0] <= first + 20 and last - 20 <= paused[-1] <= last
    assert (a1, b0) == (paused[0] - 20, paused[-1] + 21)
    # the pauses kept (the tracker's leg order): cut at the turn
    assert walk_passes(xy, RATE, pauses=False) == [(0, at[0]), (at[0], tr.n_frames)]


def test_the_pause_is_found_where_the_turn_falls_at_its_edge():
    """A pelvis drifting 8 mm up the room while it stands (a tracked one can) goes furthest at the
    pivot's end, so the turn falls at the pause's edge: the pause is still the pivot."""
    tr, _, first, last = _up_and_down(drift_m=0.008)
    xy = tr.point("pelvis")[:, :2]
    assert turns(xy)[0] >= last - 2  # the furthest point: the pivot's end
    paused = np.flatnonzero(paused_at_turns(xy, RATE))
    assert first <= paused[0] <= first + 20 and last - 20 <= paused[-1] <= last


def test_a_walk_up_and_down_gets_its_events_and_strides_pass_by_pass():
    """Along one direction for the whole clip, the heel's lead over the pelvis runs the other way
    after the turn, and every foot off on the way back was taken for a foot strike (stance 38 %
    instead of 62 %, the strides' lengths negative and withheld); pass by pass, every true event of
    both walks is found within half a frame and the parameters are the walker's."""
    tr, truth, first, last = _up_and_down()
    one_way, _ = detect_events(tr, EXACT)
    back = [e for e in one_way if e.time_s > last / RATE]
    assert back and sum(_nearest(e, truth) > 0.05 for e in back) > len(back) / 2  # the old way: wrong
    a = analyse(tr, EXACT)
    assert len(a.passes) == 2
    np.testing.assert_allclose(a.passes[0].direction.forward, -a.passes[1].direction.forward, atol=1e-3)
    inside = [e for e in truth if e.time_s < first / RATE - 0.3 or e.time_s > last / RATE + 0.3]
    assert max(_nearest(e, a.events) for e in inside) <= 0.5 / RATE + 1e-9
    assert all(not first <= e.time_s * RATE <= last for e in a.events)  # none in the pivot
    p = a.parameters
    assert p.ok, p.reason
    walker = Walker()
    assert p.overall["stride_length_m"] == pytest.approx(walker.stride_length, abs=0.01)
    assert p.overall["stance_pct"] == pytest.approx(100 * walker.stance, abs=1.0)
    assert p.overall["speed_m_s"] == pytest.approx(walker.speed, rel=0.02)
    assert p.overall["n_strides"] == sum(len(a.cycles[s]) for s in a.cycles) >= 8
    assert len(p.info["walking_directions"]) == 2
    # no cycle spans the turn
    assert all(c.end_s < first / RATE or c.start_s > last / RATE for s in a.cycles for c in a.cycles[s])
    # the events recorded in a file, pass by pass as well (gaitcap eval's reference parameters)
    recorded = parameters_by_pass(tr, truth, a.passes, EXACT.plausible)
    assert recorded.ok and recorded.overall["stance_pct"] == pytest.approx(100 * walker.stance, abs=1.0)


def test_a_walk_up_and_down_keeps_its_pelvis_angles_on_the_way_back():
    """The pelvis angles are taken against each pass's own direction: on the way back the pelvis
    faces the new direction and its rotation stays near 0, not near 180 degrees; the pivot's frames
    belong to no pass (NaN)."""
    tr, _, first, last = _up_and_down()
    a = analyse(tr, EXACT)
    rotation = a.angles["pelvis_rotation_l"]
    assert not np.isfinite(rotation[first : last + 1]).any()
    assert np.nanmax(np.abs(rotation)) < 1e-6  # the walker's pelvis faces the way it walks
    angles, _ = angles_by_pass(tr, a.passes)
    np.testing.assert_array_equal(angles["knee_flexion_r"], a.angles["knee_flexion_r"])


def _nearest(event: GaitEvent, events: list[GaitEvent]) -> float:
    same = [e.time_s for e in events if (e.side, e.event) == (event.side, event.event)]
    return min((abs(t - event.time_s) for t in same), default=np.inf)


def test_a_pass_is_a_slice_on_the_clip_s_time_axis():
    """within: the pass's frames alone (a view: a long clip's passes hold its frames once), its
    times the clip's, its per-frame meta and toe releases (frame indices) cut and shifted alike."""
    tr, _, _, _ = _up_and_down()
    T = tr.n_frames
    sigma = np.arange(T * len(tr.names), dtype=float).reshape(T, len(tr.names))
    tr = replace(tr, t0_s=0.5, meta={"uncertainty": sigma, TOE_RELEASES: {"left": [10.5, 250.0, 700.2]}, "source": "x"})
    part = within(tr, 200, 300)
    assert part.n_frames == 100 and np.shares_memory(part.points, tr.points)
    np.testing.assert_allclose(part.times(), tr.times()[200:300])
    np.testing.assert_array_equal(part.meta["uncertainty"], sigma[200:300])
    assert part.meta[TOE_RELEASES] == {"left": [50.0]} and part.meta["source"] == "x"
    assert within(tr, 0, T) is tr


def _walk_round(radius: float = 0.75) -> tuple[Trajectory, list[GaitEvent], int, int]:
    """The walker bent round a path: 4 s up the room, a half circle of ``radius`` metres to the left,
    and 4 s back (each frame's pose turned about the pelvis by the path's heading where the pelvis has
    come to; the feet slide while the heading turns): the trajectory, the walker's true events, and
    the half circle's first and last frames."""
    walker = Walker(duration=8.0 + np.pi * radius / Walker().speed, heading_deg=0.0, origin=(0.0, 0.0))
    tr = walker.trajectory()
    pelvis = tr.names.index("pelvis")
    s = tr.points[:, pelvis, 0]  # metres walked
    straight = walker.speed * 4.0
    bend = np.clip((s - straight) / radius, 0.0, np.pi)  # the heading
    beyond = np.clip(s - straight - np.pi * radius, 0.0, None)  # walked back after the circle
    c, n = np.cos(bend), np.sin(bend)
    ground = np.stack([np.minimum(s, straight) + radius * n - beyond, radius * (1 - c), np.zeros_like(s)], axis=1)
    rel = tr.points - tr.points[:, pelvis : pelvis + 1] * [1.0, 1.0, 0.0]
    turned = np.stack([c[:, None] * rel[..., 0] - n[:, None] * rel[..., 1],
                       n[:, None] * rel[..., 0] + c[:, None] * rel[..., 1], rel[..., 2]], axis=-1)  # fmt: skip
    on_circle = np.flatnonzero((bend > 0) & (bend < np.pi))
    return replace(tr, points=turned + ground[:, None, :]), walker.truth_events(), on_circle[0], on_circle[-1]


def test_a_turn_walked_round_belongs_to_no_pass(monkeypatch):
    """A half circle walked without a stop: the passes end where the pelvis heads more than 20 degrees
    off their direction, so each pass is a straight walk, with the walk's direction, events, strides
    and step widths. Cut at the turn alone (the circle's frames left in), each pass took a quarter of
    the circle, its direction was pulled off the walk's, and its steps were read along it."""
    tr, truth, first, last = _walk_round()
    xy = tr.point("pelvis")[:, :2]
    passes = walk_passes(xy, RATE)
    assert len(passes) == 2 and passes[0][0] == 0 and passes[1][1] == tr.n_frames
    # each pass ends within the circle's first 20 degrees (and the velocity span's reach, 0.2 s)
    reach = round(20 / 180 * (last - first)) + 20
    assert first - 20 <= passes[0][1] <= first + reach and last - reach <= passes[1][0] <= last + 21
    assert walk_passes(xy, RATE, pauses=False) == passes  # no pause to keep
    a = analyse(tr, EXACT)
    for p, sign in zip(a.passes, (1.0, -1.0), strict=True):
        np.testing.assert_allclose(p.direction.forward[:2], [sign, 0.0], atol=np.radians(0.5))
    kept = [e for e in truth if any(p.start <= e.time_s * RATE < p.stop for p in a.passes)]
    straight = [e for e in kept if not first - 50 <= e.time_s * RATE <= last + 50]
    assert len(straight) >= 20 and max(_nearest(e, a.events) for e in straight) <= 0.5 / RATE + 1e-9
    assert all(any(p.start <= e.time_s * RATE < p.stop for p in a.passes) for e in a.events)
    p = a.parameters
    assert p.ok, p.reason
    walker = Walker()
    # within 1.5 cm: a stride may reach into the circle's first 20 degrees
    np.testing.assert_allclose([s.stride_length_m for s in p.strides], walker.stride_length, atol=0.015)
    # the step widths the walker's, but for a pass's first step, whose other foot came down on the
    # circle's last 20 degrees (and slid there, as this walker's feet do while the heading turns)
    widths = np.array([s.step_width_m for s in p.steps])
    assert np.sum(np.abs(widths - walker.step_width) > 0.01) <= 1 and widths.max() < 0.25
    # cut at the turn alone: steps on the circle read 0.3-0.5 m wide, a stride there 0.2 m short, and
    # every step width off by 3 cm (each pass's direction pulled 2.7 degrees off the walk's)
    monkeypatch.setattr("gaitcap.gait.passes.TURN_HEADING_DEG", 180.0)
    old = analyse(tr, EXACT).parameters
    assert max(s.step_width_m for s in old.steps) > 0.3
    assert min(s.stride_length_m for s in old.strides) < walker.stride_length - 0.1


def test_the_tracker_s_leg_order_takes_a_turn_walked_round_frame_by_frame():
    """``pipeline._passes`` (the leg order's passes): cut at the turn, the circle kept, each frame of
    it with its pelvis's direction of travel (within 2 degrees of the path's), the straight (up to 20
    degrees round the circle, as the gait analysis's pass) with the pass's own; a walk with a pivot
    instead is cut at the turn with one line per pass."""
    from gaitcap import pipeline

    tr, _, first, last = _walk_round()
    (a0, b0, lines0), (a1, b1, lines1) = pipeline._passes(tr.points, tr.names, RATE)
    turn = turns(tr.point("pelvis")[:, :2])[0]
    assert (a0, b0, a1, b1) == (0, turn, turn, tr.n_frames)
    path = np.unwrap(np.arctan2(*np.diff(tr.point("pelvis")[:, :2], axis=0).T[::-1]))  # the heading walked
    straight = walk_passes(tr.point("pelvis")[:, :2], RATE)
    for (a, lines), (p, q) in zip(((a0, lines0), (a1, lines1)), straight, strict=True):
        assert lines is not None
        assert np.ptp(lines[p - a : q - a], axis=0).max() == 0.0  # one line on the straight
        t = np.arange(a, a + len(lines) - 1)
        off = np.degrees(np.abs(np.angle(np.exp(1j * (np.arctan2(lines[:-1, 1], lines[:-1, 0]) - path[t])))))
        on_circle = (t < p) | (t >= q)
        assert on_circle.sum() > 40 and off[on_circle].max() < 2.0 and off.max() < 21.0
    up, _, _, _ = _up_and_down()
    spans = pipeline._passes(up.points, up.names, RATE)
    assert len(spans) == 2 and all(lines is None for _, _, lines in spans)


@pytest.mark.parametrize("recorded", [False, True])
def test_the_stride_across_a_stop_in_a_straight_walk_is_left_out(recorded: bool) -> None:
    # the embedded Plug-in-Gait walk held still for 1 s in double support (its frame at 1.74 s
    # repeated): the stride across the stop was counted as a gait cycle, double support 41.6 % and
    # the stride time's symmetry index -62 %, and nothing said
    from gaitcap.data import embedded_walk
    from gaitcap.markers.motion import read_motion

    walk = read_motion(embedded_walk())
    at, hold = 22, 100  # frame 22 (1.74 s, both feet down), 100 frames at 100 Hz
    points = np.concatenate([walk.points[: at + 1], np.repeat(walk.points[at : at + 1], hold, axis=0), walk.points[at + 1 :]])
    t_at = walk.t0_s + at / walk.rate_hz
    events = tuple(replace(e, time_s=e.time_s + (hold / walk.rate_hz if e.time_s > t_at else 0.0)) for e in walk.events)
    paused = replace(walk, points=points, events=events)
    own, stopped = analyse(walk, recorded=recorded), analyse(paused, recorded=recorded)
    assert "stops_s" not in own.parameters.info
    (a, b), = stopped.parameters.info["stops_s"]
    assert t_at < a < b < t_at + hold / walk.rate_hz
    assert "stood still" in stopped.parameters.reason
    assert len(stopped.events) == len(own.events)  # the events are found as before, on both sides of it
    # no stride holds the stop: each one left is one of the walk at its own pace, times shifted
    assert stopped.parameters.overall["n_strides"] == own.parameters.overall["n_strides"] - 1
    assert all(s.stride_time_s < 1.2 for s in stopped.parameters.strides)
    ds = stopped.parameters.overall["double_support_pct"]
    assert abs(ds - own.parameters.overall["double_support_pct"]) < 2.0
