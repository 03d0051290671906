"""A toe marker lost while standing on the floor: held there while the ankle can reach it, and
its lift-off taken as the foot off (gaitcap.markers.jointcentres.hold_on_floor)."""

from __future__ import annotations

import numpy as np
import pytest
from gait_walker import Walker
from pydantic import ValidationError

from gaitcap.gait.events import detect_events
from gaitcap.markers.jointcentres import hold_on_floor
from gaitcap.markers.mapping import FloorContact, Mapping
from gaitcap.trajectory import TOE_RELEASES, Trajectory

RATE = 50.0
CONTACT = FloorContact(marker="RTOE", reach="RANK")


def _push_off(n: int = 40, lift_at: int = 25) -> tuple[np.ndarray, np.ndarray, float]:
    """A toe standing at the origin until ``lift_at``, then rising; the ankle 0.14 m behind and
    above it, pivoting about the toe (heel rise) and then carried forward with the lifted foot.
    Returns toe (n, 3), ankle (n, 3) and the foot's toe-ankle length."""
    length = 0.14
    toe = np.zeros((n, 3))
    toe[:, 2] = 0.012
    # heel rise: the ankle turns about the toe, to nearly above it at lift-off (70-80 deg)
    angle = np.clip(0.3 + 0.08 * (np.arange(n) - 12), 0.3, 1.45)
    ankle = toe + length * np.stack([-np.cos(angle), np.zeros(n), np.sin(angle)], axis=1)
    after = np.arange(n) > lift_at
    toe[after, 0] = 0.03 * (np.arange(n)[after] - lift_at) ** 1.5  # the toe leaves the floor
    toe[after, 2] += 0.01 * (np.arange(n)[after] - lift_at)
    ankle[after] += toe[after] - toe[0]
    return toe, ankle, length


def test_a_toe_lost_on_the_floor_is_held_until_the_ankle_cannot_reach_it():
    toe, ankle, _ = _push_off()
    seen = toe.copy()
    seen[20:] = np.nan  # the marker drops out at frame 20, in heel rise
    filled, releases = hold_on_floor(seen, ankle, RATE, CONTACT)
    assert len(releases) == 1
    # held exactly where it stood, up to the release; nothing after it
    last = int(np.floor(releases[0]))
    np.testing.assert_array_equal(filled[20 : last + 1], np.repeat(toe[19:20], last - 19, axis=0))
    assert np.isnan(filled[last + 1 :]).all()
    # the ankle leaves the reach (the longest distance seen + tolerance) between these frames
    reach = np.max(np.linalg.norm(toe[:20] - ankle[:20], axis=1)) + CONTACT.tolerance_m
    dist = np.linalg.norm(ankle - toe[19], axis=1)
    assert dist[last] <= reach < dist[last + 1]
    assert 25 <= releases[0] <= 26.5  # the toe lifts after frame 25
    np.testing.assert_array_equal(filled[:20], toe[:20])


def test_a_gap_in_swing_or_without_the_ankle_is_left_alone():
    toe, ankle, _ = _push_off()
    swing = toe.copy()
    swing[:, 2] += np.where(np.arange(len(toe)) < 10, 0.0, 0.1)  # lifted 10 cm when it drops out
    swing[15:25] = np.nan
    filled, releases = hold_on_floor(swing, ankle, RATE, CONTACT)
    assert releases == [] and np.isnan(filled[15:25]).all()
    seen = toe.copy()
    seen[20:] = np.nan
    blind = ankle.copy()
    blind[22:] = np.nan  # the ankle is lost too: held while it was seen, no lift-off claimed
    filled, releases = hold_on_floor(seen, blind, RATE, CONTACT)
    assert releases == [] and np.isfinite(filled[20:22]).all() and np.isnan(filled[22:]).all()


def test_a_moving_marker_is_not_held():
    toe, ankle, _ = _push_off()
    moving = toe.copy()
    moving[:, 0] += 0.02 * np.arange(len(toe))  # 1 m/s along the floor: not standing
    moving[20:] = np.nan
    filled, releases = hold_on_floor(moving, ankle, RATE, CONTACT)
    assert releases == [] and np.isnan(filled[20:]).all()


def _walker_with_lost_toe(release_s: float) -> tuple[Trajectory, float]:
    """A walker (exact events) whose right toe is held until ``release_s`` and lost after it, as
    :func:`hold_floor_contacts` leaves it; returns it (release in meta) and the last right foot off."""
    w = Walker(rate_hz=RATE, duration=3.0, heading_deg=0.0)
    traj = w.trajectory()
    last_off = [e.time_s for e in w.truth_events() if (e.side, e.event) == ("right", "foot_off")][-1]
    points = traj.points.copy()
    release = release_s * RATE
    points[int(np.floor(release)) + 1 :, traj.index("toe_r")] = np.nan
    return Trajectory(traj.names, points, RATE, traj.t0_s, meta={TOE_RELEASES: {"right": [release]}}), last_off


def _right_offs(traj: Trajectory) -> list[float]:
    found, _ = detect_events(traj)
    return [e.time_s for e in found if (e.side, e.event) == ("right", "foot_off")]


def test_the_release_becomes_the_foot_off_of_the_gait_events():
    """The toe's signal ends at the release, so the Zeni minimum is never interior: without the
    release the last foot off is missed; with it, it is found at the release."""
    traj, last_off = _walker_with_lost_toe(0.0)
    release = last_off + 0.3 / RATE
    traj, _ = _walker_with_lost_toe(release)
    offs = _right_offs(traj)
    assert min(abs(t - release) for t in offs) < 1e-9
    without = Trajectory(traj.names, traj.points, RATE, traj.t0_s)
    assert all(abs(t - last_off) > 0.1 for t in _right_offs(without))


def test_a_release_out_of_the_rhythm_is_not_an_event():
    """A release far into the swing (a stance 40 % longer than the others) is dropped by the
    rhythm check that guards every event seen at the end of a run."""
    traj, last_off = _walker_with_lost_toe(0.0)
    late = last_off + 0.4 * 0.62 * 1.1  # 40 % of the walker's stance later
    traj, _ = _walker_with_lost_toe(late)
    assert all(abs(t - late) > 0.05 for t in _right_offs(traj))


def test_a_floor_contact_rejects_unknown_keys_and_out_of_range_values():
    base = {"name": "x", "points": {"hip_l": {"marker": "A"}}}
    with pytest.raises(ValidationError):
        Mapping.model_validate({**base, "floor_contacts": {"right": {"marker": "RTOE", "reach": "RANK", "slack": 1}}})
    with pytest.raises(ValidationError):
        Mapping.model_validate({**base, "floor_contacts": {"right": {"marker": "RTOE", "reach": "RANK", "max_height_m": 0.5}}})
    with pytest.raises(ValidationError):
        Mapping.model_validate({**base, "floor_contacts": {"middle": {"marker": "RTOE", "reach": "RANK"}}})


@pytest.mark.parametrize("ends_before, found", [(1, True), (2, True), (5, False)])
def test_a_toe_point_ending_shortly_before_the_release_still_closes_on_it(ends_before, found):
    """The toe point can end before its marker's hold when another marker it is built from ends
    first (gait-raw.c3d: RKNE, through the knee and ankle centres); within two samples the release
    is still the foot off, further away it is not trusted."""
    traj, last_off = _walker_with_lost_toe(0.0)
    release = last_off + 0.3 / RATE
    traj, _ = _walker_with_lost_toe(release)
    points = traj.points.copy()
    points[int(np.floor(release * RATE)) + 1 - ends_before :, traj.index("toe_r")] = np.nan
    cut = Trajectory(traj.names, points, RATE, traj.t0_s, meta=traj.meta)
    assert any(abs(t - release) < 1e-9 for t in _right_offs(cut)) == found
