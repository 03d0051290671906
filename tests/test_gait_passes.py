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
