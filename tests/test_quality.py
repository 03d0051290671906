"""The run's verdict (each rule: a run built to trip it, one that must not) and the calibrated
uncertainty's invariants (gaitcap.quality)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from gaitcap.body.model import load_body_model
from gaitcap.camera import Camera, CameraRig
from gaitcap.config import load_yaml_model
from gaitcap import quality
from gaitcap.gait import passes
from gaitcap.errors import ConfigError
from gaitcap.io.track_h5 import QUALITY_OK, QUALITY_OUT_OF_VIEW, QUALITY_POOR_FIT
from gaitcap.quality import (
    FOOT_SEGMENTS,
    assess,
    calibrated_uncertainty,
    crossed_ankles,
    judge,
    legs_in_doubt,
    no_oblique_view,
    out_of_rhythm,
    run_signals,
    stride_frequency,
    turns,
    unsupported_legs,
)
from gaitcap.tracking.config import TrackingConfig, UncertaintyConfig, VerdictConfig, load_tracking_config
from gaitcap.trajectory import LOWER_LIMB

HEIGHT = 1.7
T = 50
RATE = 25.0


def _walking(phase: np.ndarray, exchanged: slice = slice(0)) -> tuple[np.ndarray, tuple[str, ...]]:
    """The body model walking: (T, P, 3) points and names for the stride phase (T,) (radians); the
    legs swing in opposition (hip flexion +-20 degrees) while the pelvis moves forward at 1.2 m/s,
    the feet near the floor. In the ``exchanged`` frames the legs take each other's flexion: legs
    exchanged fore and aft, each on its own side, as the tracker can get them."""
    model = load_body_model(height_m=HEIGHT)
    Q = np.repeat(model.neutral_pose()[None], len(phase), axis=0)
    Q[:, model.dof_index("pelvis_tx")] = 1.2 * np.arange(len(phase)) / RATE
    left, right = model.dof_index("hip_flexion_l"), model.dof_index("hip_flexion_r")
    Q[:, left] = np.radians(20) * np.sin(phase)
    Q[:, right] = -Q[:, left]
    Q[exchanged, left], Q[exchanged, right] = Q[exchanged, right].copy(), Q[exchanged, left].copy()
    return model.forward(Q), model.point_names


@pytest.fixture(scope="module")
def walk() -> tuple[np.ndarray, tuple[str, ...]]:
    """A plausible walk of two strides (1 Hz at 25 frames per second)."""
    return _walking(2 * np.pi * np.arange(T) / 25.0)


def _judge(points, names, quality=None, height=HEIGHT, rig=None, cfg: VerdictConfig | None = None):
    cfg = cfg or VerdictConfig()
    quality = np.zeros(len(points), np.uint8) if quality is None else quality
    return judge(run_signals(points, names, quality, height, rig, cfg.crossed_margin_m, rate_hz=RATE,
                             exchanged_margin_m=cfg.exchanged_margin_m), cfg)  # fmt: skip


def test_a_plausible_walk_is_ok(walk):
    points, names = walk
    v = _judge(points, names)
    assert v.verdict == "ok" and v.reasons == ()
    assert v.to_dict() == {"verdict": "ok", "verdict_reasons": [], "verdict_notes": []}


def test_poor_fit_for_most_frames_is_doubtful_and_nearly_all_failed(walk):
    points, names = walk
    q = np.zeros(T, np.uint8)
    q[: int(0.4 * T)] = QUALITY_POOR_FIT
    assert _judge(points, names, q).verdict == "ok"  # 40 % flagged: under max_flagged_fraction 0.5
    q[: int(0.6 * T)] = QUALITY_POOR_FIT
    v = _judge(points, names, q)
    assert v.verdict == "doubtful" and v.reasons == (f"a poor fit for 30 of {T} frames",)
    q[:] = QUALITY_POOR_FIT
    q[:3] = QUALITY_OK  # 3 of 50 unflagged: under min_ok_fraction 0.1
    v = _judge(points, names, q)
    assert v.verdict == "failed" and "only 3 of 50 frames" in v.reasons[0]
    q[:] = QUALITY_OUT_OF_VIEW
    v = _judge(points, names, q)
    assert v.verdict == "failed" and v.reasons[0].startswith("none of the 50 frames fits")


def _cross(points: np.ndarray, names, frames: slice, by_m: float) -> np.ndarray:
    """The ankles moved so that the left one lies ``by_m`` to the right of the right one."""
    out = points.copy()
    hips = out[:, names.index("hip_l")] - out[:, names.index("hip_r")]
    lateral = hips / np.linalg.norm(hips, axis=1, keepdims=True)
    mid = 0.5 * (out[:, names.index("ankle_l")] + out[:, names.index("ankle_r")])
    out[frames, names.index("ankle_l")] = mid[frames] - lateral[frames] * by_m / 2
    out[frames, names.index("ankle_r")] = mid[frames] + lateral[frames] * by_m / 2
    return out


def test_crossed_ankles_are_a_suspected_leg_swap(walk):
    points, names = walk
    crossed = _cross(points, names, slice(0, 15), 0.08)  # 30 % of the frames, by 8 cm
    assert crossed_ankles(crossed, names, 0.02).sum() == 15
    v = _judge(crossed, names)
    assert v.verdict == "doubtful" and v.reasons == ("the ankles cross in 15 of 50 frames: a suspected leg swap",)
    # crossed by less than the margin (the points' jitter), or in fewer frames than the threshold: ok
    assert _judge(_cross(points, names, slice(None), 0.01), names).verdict == "ok"
    assert _judge(_cross(points, names, slice(0, 4), 0.08), names).verdict == "ok"


def test_a_model_off_the_floor_is_doubtful(walk):
    points, names = walk
    v = _judge(points + [0, 0, 0.25], names)
    assert v.verdict == "doubtful" and "the feet stay 25 cm above the floor" in v.reasons[0]
    assert "below the floor" in _judge(points - [0, 0, 0.2], names).reasons[0]
    assert _judge(points + [0, 0, 0.05], names).verdict == "ok"  # within max_floor_offset_m 0.1


def test_a_body_outside_anthropometric_ranges_is_doubtful(walk):
    points, names = walk
    # the same body said to be 2.5 m tall: its legs are 0.68 of the usual length for that height
    v = _judge(points, names, height=2.5)
    assert v.verdict == "doubtful" and "a body outside anthropometric ranges" in v.reasons[0]
    assert "thigh_l 0.68" in v.reasons[0]
    assert _judge(points, names, height=1.9).verdict == "ok"  # 0.89: within [0.75, 1.33]


def _rig(*degrees: float, distance_m: float = 4.0) -> CameraRig:
    """Cameras ``distance_m`` from the middle of the walk (along x, 0-2.4 m), each looking at it
    with its line of sight at one of ``degrees`` from the walking line."""
    eyes = [(1.2 - distance_m * np.cos(a), -distance_m * np.sin(a), 1.0) for a in np.radians(degrees)]
    return CameraRig([Camera.look_at(f"cam{i + 1}", eye, (1.2, 0.0, 1.0)) for i, eye in enumerate(eyes)])


def _camera_at(distance_m: float) -> CameraRig:
    return _rig(45.0, distance_m=distance_m)


def test_a_subject_too_small_in_the_image_is_doubtful(walk):
    points, names = walk
    far = _judge(points, names, rig=_camera_at(20.0))  # 1.6 m at 20 m with f = 600 px: about 50 px
    assert far.verdict == "doubtful" and "too small in the image" in far.reasons[0] and "cam1" in far.reasons[0]
    assert _judge(points, names, rig=_camera_at(5.0)).verdict == "ok"


@pytest.mark.parametrize(("degrees", "oblique"), [((90.0, 0.0), False), ((80.0, 8.0), False), ((90.0, 30.0), True),
                                                 ((90.0, 0.0, 60.0), True), ((14.0,), False), ((16.0,), True)])
def test_cameras_only_beside_and_in_line_with_the_walk_are_noted(walk, degrees, oblique):
    """Without a camera 15 degrees or more from both the walking line and its perpendicular, which
    leg is ahead is ambiguous: a note naming the angles, the verdict left ok (the legs' fore-aft
    rhythm tells whether they were exchanged); one oblique camera is enough."""
    points, names = walk
    v = _judge(points, names, rig=_rig(*degrees))
    assert v.verdict == "ok" and v.reasons == (), v.reasons
    assert (v.notes == ()) == oblique, v.notes
    if not oblique:
        assert "obliquely" in v.notes[0] and f"cam1 {degrees[0]:.0f}" in v.notes[0], v.notes


@pytest.mark.parametrize(("angles", "expected"), [({"cam1": 81.0, "cam2": 0.0}, True), ({"cam1": 89.0, "cam2": 81.0,
                                                   "cam3": 14.0}, True), ({"cam1": 81.0, "cam2": 15.0}, False),
                                                   ({"cam1": 75.0}, False), ({"cam1": 76.0}, True), ({}, False)])
def test_no_oblique_view_needs_every_camera_near_the_line_or_its_perpendicular(angles, expected):
    """The backward pass's trigger for tracking a run from its legs' mirror (pipeline._mirror_run) and
    the verdict's note share this rule: 15 degrees from both is oblique; no angles (no walking line
    or no cameras) is not a layout to act on."""
    assert no_oblique_view(angles, 15.0) is expected


def test_a_walk_on_the_spot_takes_its_line_from_the_way_the_hips_face(walk):
    """On a treadmill the pelvis stays put: the walking line is the hips' perpendicular (here x,
    as for the walk), so the same cameras get the same angles."""
    points, names = walk
    on_the_spot = points.copy()
    on_the_spot[..., 0] -= points[:, :1, 0] - points[:, 0, 0].mean()  # every frame's pelvis at the walk's middle
    rig = _rig(80.0, 30.0)
    walking = run_signals(points, names, np.zeros(T, np.uint8), HEIGHT, rig, rate_hz=RATE).view_angles_deg
    still = run_signals(on_the_spot, names, np.zeros(T, np.uint8), HEIGHT, rig, rate_hz=RATE).view_angles_deg
    assert still.keys() == walking.keys() == {"cam1", "cam2"}
    assert abs(walking["cam1"] - 80.0) < 3 and abs(walking["cam2"] - 30.0) < 3, walking
    assert all(abs(still[k] - walking[k]) < 3 for k in still), (still, walking)


def test_a_body_moving_against_the_way_it_faces_is_noted(walk):
    """The walk played backwards (a subject walking backwards, or a forward walker tracked facing the
    wrong way) gets a note naming the frames, the verdict left ok; the walk itself and a walk on the
    spot get none."""
    points, names = walk
    forwards = _judge(points, names)
    assert forwards.verdict == "ok" and forwards.notes == (), forwards.notes
    backwards = _judge(points[::-1].copy(), names)
    assert backwards.verdict == "ok", backwards.reasons
    assert len(backwards.notes) == 1 and "moves backwards" in backwards.notes[0], backwards.notes
    half = round(passes.SPEED_SPAN_S * RATE / 2)
    assert f"in {T - 2 * half} of the {T - 2 * half} frames where it moves in frames 0-{T - 1}" in backwards.notes[0]
    on_the_spot = points.copy()
    on_the_spot[..., 0] -= points[:, :1, 0] - points[:, 0, 0].mean()
    assert quality.moving_backwards(on_the_spot, names, RATE) == (0, 0, 0, 0)
    swaying = on_the_spot.copy()  # 10 cm back and forth in 0.4 s (0.25 m/s): on the spot all the same
    swaying[..., 0] += 0.05 * np.sign(np.sin(2 * np.pi * np.arange(T) / 20.0))[:, None]
    assert quality.moving_backwards(swaying, names, RATE) == (0, 0, 0, 0)
    # frames without a pose count as neither
    flagged = np.zeros(T, np.uint8)
    flagged[:10] = QUALITY_OUT_OF_VIEW
    signals = run_signals(points[::-1].copy(), names, flagged, HEIGHT, rate_hz=RATE)
    n = T - 10 - 2 * half  # frames whose span holds no flagged frame
    assert signals.moving_backwards == (n, n, 0, T - 1)
    flagged[:20] = QUALITY_OUT_OF_VIEW  # moving in less than MIN_STRETCH_S: not judged
    assert run_signals(points[::-1].copy(), names, flagged, HEIGHT, rate_hz=RATE).moving_backwards == (0, 0, 0, 0)


def test_a_turn_the_model_did_not_follow_is_noted_after_it(walk):
    """The walk, then the same poses walked back to the start still facing the first way (a subject
    who turned round, the model not): over the whole clip half the moving frames go backwards, but
    the stretch after the turn does so in all of its own, and the note names it."""
    points, names = walk
    back = points[::-1].copy()
    both = np.concatenate([points, back])
    v = _judge(both, names)
    turn = int(quality.turns(both, names)[0])
    assert abs(turn - T) <= 2, turn
    against, moving, first, last = quality.moving_backwards(both, names, RATE)
    assert (first, last) == (turn, 2 * T - 1) and against == moving > RATE
    assert len(v.notes) == 1 and f"in frames {turn}-{2 * T - 1}" in v.notes[0], v.notes
    # the backward pass's gate for a fresh start counts those frames: the walk alone, none; and begins
    # the fresh start beside the merge for them (facing_in_doubt), on them alone
    assert legs_in_doubt(both, names, RATE, VerdictConfig()) == against
    assert legs_in_doubt(points, names, RATE, VerdictConfig()) == 0
    assert quality.facing_in_doubt(both, names, RATE) == against
    assert quality.facing_in_doubt(points, names, RATE) == 0


def test_legs_exchanged_fore_and_aft_are_doubtful():
    """Legs exchanged fore and aft for a stretch (each foot on its own side: the ankles do not cross)
    go against the stride's rhythm in the frames where the legs are well apart: 60 degrees of phase
    either side of the peak at frame 18.75, frames 15-22."""
    phase = 2 * np.pi * np.arange(T) / 25.0
    points, names = _walking(phase, slice(14, 24))
    v = _judge(points, names)
    assert v.verdict == "doubtful" and v.reasons == (
        ("legs possibly exchanged fore and aft in 8 frames: there the ankles' fore-aft order goes against the "
         "stride's rhythm"),
    )
    exchanged = out_of_rhythm(points, names, np.ones(T, bool), RATE, 0.05)
    assert np.flatnonzero(exchanged).tolist() == list(range(15, 23))
    # where no pose was tracked, no frame counts
    assert not out_of_rhythm(points, names, np.arange(T) < 14, RATE, 0.05).any()


@pytest.mark.parametrize("exchanged", [slice(0), slice(18, 20), slice(10, 15)])
def test_a_walk_in_rhythm_is_not_exchanged(exchanged):
    """Not doubtful: a clean walk with the points shaken by 2 cm (seeded), an exchange of 2 frames
    (under min_exchanged_frames 3), an exchange while the legs pass each other (frames 10-14 around
    the crossing at 12.5: the fore-aft order is not judged where the legs are close)."""
    points, names = _walking(2 * np.pi * np.arange(T) / 25.0, exchanged)
    shaken = points + np.random.default_rng(0).normal(0, 0.02, points.shape)
    v = _judge(shaken, names)
    assert v.verdict == "ok", v.reasons


@pytest.mark.parametrize(
    "exchanged, crossed, expected",
    [(slice(0), slice(0), 0), (slice(18, 20), slice(0), 0), (slice(14, 24), slice(0), 8),
     (slice(0), slice(0, 5), 5), (slice(0), slice(0, 4), 0), (slice(14, 24), slice(0, 5), 13)],
)  # fmt: skip
def test_legs_in_doubt_counts_the_frames_the_verdict_doubts(exchanged, crossed, expected):
    """legs_in_doubt (the backward pass's gate for a second hypothesis) is 0 exactly when the
    verdict has no leg reason, else the frames it counts: out of rhythm (at least 3 needed) plus
    ankles crossed (at least a tenth of the 50 frames, 5)."""
    points, names = _walking(2 * np.pi * np.arange(T) / 25.0, exchanged)
    points = _cross(points, names, crossed, 0.08)
    cfg = VerdictConfig()
    v = _judge(points, names, cfg=cfg)
    assert legs_in_doubt(points, names, RATE, cfg) == expected
    leg_reasons = [r for r in v.reasons if "ankles" in r]
    assert bool(leg_reasons) == (expected > 0)


def test_a_long_walk_is_judged_in_pieces():
    """Cadence drifting from 0.8 to 1.1 strides per second over 30 s: no frame is out of rhythm
    (each piece of about 3 strides has its own); a stretch exchanged in the middle is found."""
    t = np.arange(750) / RATE
    phase = 2 * np.pi * (0.8 * t + 0.3 * t**2 / (2 * t[-1]))
    points, names = _walking(phase)
    tracked = np.ones(len(t), bool)
    assert not out_of_rhythm(points, names, tracked, RATE, 0.05).any()
    assert abs(stride_frequency(t[:50], (points[:50, names.index("ankle_l"), 0] - points[:50, names.index("ankle_r"), 0]))
               - 0.8) < 0.02  # fmt: skip
    exchanged = out_of_rhythm(*_walking(phase, slice(400, 410)), tracked, RATE, 0.05)
    assert 4 <= exchanged.sum() <= 10 and set(np.flatnonzero(exchanged)) <= set(range(400, 410))


def test_a_stop_in_the_middle_of_a_walk_is_not_out_of_rhythm():
    """A subject who stands still for 1.2 s in double support, then walks on: the feet keep the last
    step's order while still, and the stride's phase starts afresh after; the stop's frames were judged
    against a rhythm carried across it (10 frames 'exchanged' on this walk; a tracked walk of the
    Plug-in-Gait subject held still 1 s was doubtful with no leg swapped). Neither is judged now, and a
    stretch exchanged after the stop is still found."""
    from gait_walker import Walker

    from gaitcap.gait.analysis import analyse

    traj = Walker(duration=6.0, rate_hz=RATE).trajectory()
    strikes = [e for e in analyse(traj).events if e.event == "foot_strike"]
    k = int(round(strikes[3].time_s * RATE)) + 1
    held = np.concatenate([traj.points[:k], np.repeat(traj.points[k : k + 1], 30, axis=0), traj.points[k:]])
    names = tuple(traj.names)
    still = quality.standing_still(held, names, RATE)
    assert still[k + 8 : k + 22].all() and not still[: k - 5].any() and not still[k + 36 :].any()
    tracked = np.ones(len(held), bool)
    assert not out_of_rhythm(traj.points, names, np.ones(traj.n_frames, bool), RATE, 0.0).any()
    assert not out_of_rhythm(held, names, tracked, RATE, 0.0).any()
    swapped = held.copy()
    for a, b in (("ankle_l", "ankle_r"), ("heel_l", "heel_r"), ("toe_l", "toe_r")):
        i, j = names.index(a), names.index(b)
        swapped[130:140, [i, j]] = swapped[130:140, [j, i]]
    exchanged = out_of_rhythm(swapped, names, tracked, RATE, 0.0)
    assert exchanged.any() and set(np.flatnonzero(exchanged)) <= set(range(130, 140))


@pytest.mark.parametrize("index", [0, 15, 16, 17, 130, 255, 260])
def test_stride_frequency_is_found_anywhere_in_its_range(index: int):
    """A noisy separation whose stride frequency is the index-th of the search's grid (the first,
    the last, and either side of the frequencies searched together) is given that frequency:
    the search's pieces are put back together in order."""
    hz = quality.STRIDE_HZ[0] + index * quality.STRIDE_HZ_STEP
    t = np.arange(1500) / RATE
    d = 0.4 * np.sin(2 * np.pi * hz * t + 0.7) + np.random.default_rng(index).normal(0, 0.1, len(t))
    assert stride_frequency(t, d) == pytest.approx(hz, abs=1e-9)


def _turned_back(points: np.ndarray, names: tuple[str, ...], at: int) -> np.ndarray:
    """points (T, P, 3) of a walk along +x with frames ``at`` onwards turned half round about the
    vertical through frame ``at - 1``'s pelvis: the subject turns there and walks back the way it came."""
    out = points.copy()
    x0 = points[at - 1, names.index("pelvis"), 0]
    out[at:, :, 0] = 2 * x0 - points[at:, :, 0]
    out[at:, :, 1] = -points[at:, :, 1]
    return out


def test_a_walk_that_turns_back_is_judged_apart_on_each_side_of_the_turn(monkeypatch):
    """Up the room for 2 strides, turned, back for 2: along the fixed walking line the left ankle's
    lead flips sign at the turn (the rhythm's phase jumps by half a stride), which a single rhythm
    over the 4 strides would call out of it; judged apart on each side of the turn, no frame is. A
    stretch exchanged after the turn is still found."""
    n, at = 100, 50
    phase = 2 * np.pi * np.arange(n) / 25.0
    points, names = _walking(phase)
    turned = _turned_back(points, names, at)
    assert turns(turned, names).tolist() == [at]
    tracked = np.ones(n, bool)
    assert not out_of_rhythm(turned, names, tracked, RATE, 0.05).any()
    # the same frames judged as one piece (no turn found): many of them against the rhythm
    monkeypatch.setattr(passes, "TURN_M", 1e9)
    assert out_of_rhythm(turned, names, tracked, RATE, 0.05).sum() >= 10
    monkeypatch.undo()
    exchanged = out_of_rhythm(_turned_back(_walking(phase, slice(64, 74))[0], names, at), names, tracked, RATE, 0.05)
    assert 4 <= exchanged.sum() <= 10 and set(np.flatnonzero(exchanged)) <= set(range(64, 74))


def _walk_pivot_walk(exchanged: slice = slice(0)) -> tuple[np.ndarray, tuple[str, ...], int, int]:
    """Two strides up the room (1.2 m/s), a pivot of 180 degrees on the spot in 1 s (the pelvis
    still, the legs apart as the walk left them, the body turning), two strides back: points
    (T, P, 3), names, and the pivot's first and last frames. The legs are exchanged in the
    ``exchanged`` frames (as :func:`_walking`)."""
    model = load_body_model(height_m=HEIGHT)
    walk, pivot = 50, 25
    n = 2 * walk + pivot
    phase = 2 * np.pi * np.r_[np.arange(walk), np.full(pivot, walk - 1), np.arange(walk, 2 * walk)] / 25.0
    Q = np.repeat(model.neutral_pose()[None], n, axis=0)
    x = 1.2 * np.arange(walk) / RATE
    Q[:, model.dof_index("pelvis_tx")] = np.r_[x, np.full(pivot, x[-1]), x[-1] - 1.2 * np.arange(1, walk + 1) / RATE]
    turn = np.r_[np.zeros(walk), np.pi * np.arange(1, pivot + 1) / pivot, np.full(walk, np.pi)]
    Q[:, model.dof_index("pelvis_rotation")] = turn
    left, right = model.dof_index("hip_flexion_l"), model.dof_index("hip_flexion_r")
    Q[:, left] = np.radians(20) * np.sin(phase)
    Q[:, right] = -Q[:, left]
    Q[exchanged, left], Q[exchanged, right] = Q[exchanged, right].copy(), Q[exchanged, left].copy()
    return model.forward(Q), model.point_names, walk, walk + pivot - 1


def test_a_pivot_on_the_spot_is_not_judged_for_the_rhythm(monkeypatch):
    """A walk that stops, pivots half round on the spot and walks back: along the walking line the
    feet's fore-aft order follows the pivot (the legs apart swing round), not a stride's rhythm,
    and the frames where the pelvis pauses at the turn are not judged: no frame out of rhythm and
    the verdict ok (before, frames of the pivot were out of it: the truth of the speed benchmark's
    turning clip was itself doubtful). Legs exchanged after the pivot are still found."""
    points, names, first, last = _walk_pivot_walk()
    n = len(points)
    at = turns(points, names)
    assert len(at) == 1 and first <= at[0] <= last + 1, at
    paused = quality.turning_on_the_spot(points, names, RATE, at)
    assert first + 3 <= np.flatnonzero(paused).min() and np.flatnonzero(paused).max() <= last - 3
    assert paused.sum() >= 15
    # the restart's gate counts those frames (quality.pivots); a straight walk has none
    assert quality.pivots(points, names, RATE) == paused.sum()
    assert quality.pivots(*_walking(2 * np.pi * np.arange(n) / 25.0), RATE) == 0
    # points without a pelvis (a reference that lacks it) have no turn to pause at
    no_pelvis = tuple("x" if p == "pelvis" else p for p in names)
    assert quality.pivots(points, no_pelvis, RATE) == 0
    assert out_of_rhythm(points, no_pelvis, np.ones(n, bool), RATE, 0.05).shape == (n,)  # judged, not raised
    assert not out_of_rhythm(points, names, np.ones(n, bool), RATE, 0.05).any()
    assert _judge(points, names).verdict == "ok"
    # judged over the pivot (its pause not recognised), frames of it go against the rhythm
    monkeypatch.setattr(passes, "MIN_SPEED_M_S", -1.0)
    assert out_of_rhythm(points, names, np.ones(n, bool), RATE, 0.05)[first : last + 1].sum() >= 3
    assert _judge(points, names).verdict == "doubtful"
    monkeypatch.undo()
    points, names, first, last = _walk_pivot_walk(slice(last + 15, last + 25))
    exchanged = out_of_rhythm(points, names, np.ones(n, bool), RATE, 0.05)
    assert 4 <= exchanged.sum() <= 10 and set(np.flatnonzero(exchanged)) <= set(range(last + 15, last + 25))


def test_a_walk_taken_backwards_turns_where_it_reverses():
    """A walk followed by the same frames backwards (as the speed benchmark's clips loop their video)
    turns once, after the last forward frame; a straight walk shaken by 2 cm (seeded) and a walk on
    the spot (its pelvis swaying fore and aft further than a turn's 10 cm) do not turn; frames
    without a pelvis are skipped."""
    points, names = _walking(2 * np.pi * np.arange(T) / 25.0)
    there_and_back = points[np.r_[0:T, T - 2 : -1 : -1]]
    assert turns(there_and_back, names).tolist() == [T]
    assert not out_of_rhythm(there_and_back, names, np.ones(2 * T - 1, bool), RATE, 0.05).any()
    shaken = points + np.random.default_rng(0).normal(0, 0.02, points.shape)
    assert turns(shaken, names).size == 0
    on_the_spot = points.copy()  # on a treadmill, the pelvis swaying 14 cm fore and aft twice a stride
    on_the_spot[..., 0] -= points[:, :1, 0] - 0.07 * np.sin(4 * np.pi * np.arange(T) / 25.0)[:, None]
    assert turns(on_the_spot, names).size == 0
    gaps = there_and_back.copy()
    gaps[T - 3 : T + 2] = np.nan
    assert turns(gaps, names).tolist() == [T - 3]  # just after the last frame seen before the turn


def test_every_failed_check_is_named(walk):
    points, names = walk
    v = _judge(_cross(points, names, slice(0, 25), 0.08) + [0, 0, 0.3], names, height=2.6)
    assert v.verdict == "doubtful" and len(v.reasons) == 3


# ----------------------------------------------------------------------------------- uncertainty
def _uncertainty(points, names, fit=None, quality=None, cfg: UncertaintyConfig | None = None) -> np.ndarray:
    fit = np.full(len(points), 0.8) if fit is None else fit
    quality = np.zeros(len(points), np.uint8) if quality is None else quality
    vcfg = VerdictConfig()
    signals = run_signals(points, names, quality, HEIGHT, None, vcfg.crossed_margin_m, rate_hz=RATE)
    return calibrated_uncertainty(points, names, fit, signals, RATE, cfg or UncertaintyConfig())


def test_uncertainty_shape_and_bounds(walk):
    points, names = walk
    cfg = UncertaintyConfig(min_m=0.01)
    u = _uncertainty(points, names, cfg=cfg)
    assert u.shape == (T, len(names)) and np.all(np.isfinite(u)) and np.all(u >= 0.01)
    holed = points.copy()
    holed[10:15] = np.nan  # frames without a pose: no uncertainty either
    u = _uncertainty(holed, names)
    assert np.all(np.isnan(u[10:15])) and np.all(np.isfinite(u[:10]))
    with pytest.raises(ValueError, match="shape"):
        _uncertainty(points, names, fit=np.ones(T - 1))


def test_uncertainty_grows_with_what_goes_wrong(walk):
    points, names = walk
    base = _uncertainty(points, names)
    # a worse fit: larger everywhere
    assert np.all(_uncertainty(points, names, fit=np.full(T, 0.5)) > base)
    # jitter on one point: larger for that point, the others unchanged
    rng = np.random.default_rng(0)
    shaken = points.copy()
    k = names.index("knee_l")
    shaken[:, k] += rng.normal(0, 0.02, size=(T, 3))
    u = _uncertainty(shaken, names)
    assert np.median(u[:, k]) > 1.5 * np.median(base[:, k])
    others = [i for i in range(len(names)) if i != k]
    np.testing.assert_allclose(u[:, others], base[:, others])
    # crossed ankles: larger, most in the crossed frames
    crossed = _uncertainty(_cross(points, names, slice(0, 15), 0.08), names)
    a = names.index("hip_l")
    assert np.all(crossed[15:, a] > base[15:, a]) and np.all(crossed[:15, a] > crossed[15:, a].max())
    # off the floor: larger
    assert np.all(_uncertainty(points + [0, 0, 0.3], names) > base)


def test_point_scale_multiplies_its_points_only(walk):
    points, names = walk
    base = _uncertainty(points, names, cfg=UncertaintyConfig(min_m=0.0))
    u = _uncertainty(points, names, cfg=UncertaintyConfig(min_m=0.0, point_scale={"knee_[lr]": 2.0}))
    k = [names.index("knee_l"), names.index("knee_r")]
    np.testing.assert_allclose(u[:, k], 2 * base[:, k])
    others = [i for i in range(len(names)) if i not in k]
    np.testing.assert_allclose(u[:, others], base[:, others])


def test_assess_returns_the_three(walk):
    points, names = walk
    cfg = load_tracking_config()
    a = assess(points, names, np.full(T, 0.8), np.zeros(T, np.uint8), HEIGHT, RATE, cfg.verdict, cfg.uncertainty)
    assert a.verdict.verdict == "ok" and a.signals.n_frames == T and a.uncertainty.shape == (T, len(names))


def test_a_run_uncertain_through_much_of_its_length_is_doubtful(walk, rng):
    """The lower-limb points' mean calibrated uncertainty above ``uncertain_mm`` in more than
    ``max_uncertain_fraction`` of the tracked frames makes a run doubtful (the baseline trackers, a wrong
    height: tens of millimetres off where no other check sees it); frames not tracked are not counted."""
    points, names = walk
    cfg = load_tracking_config()
    steady = assess(points, names, np.full(T, 0.9), np.zeros(T, np.uint8), HEIGHT, RATE, cfg.verdict, cfg.uncertainty)
    assert steady.signals.n_uncertain == 0 and steady.verdict.verdict == "ok"
    jitter = points + rng.normal(0.0, 0.03, points.shape)  # 3 cm of jitter on every point: u well above 90 mm
    shaky = assess(jitter, names, np.full(T, 0.6), np.zeros(T, np.uint8), HEIGHT, RATE, cfg.verdict, cfg.uncertainty)
    lower = [names.index(p) for p in LOWER_LIMB]
    expected = int(np.sum(shaky.uncertainty[:, lower].mean(axis=1) > 0.090))
    assert expected > 0.25 * T and shaky.signals.n_uncertain == expected
    assert shaky.verdict.verdict == "doubtful"
    assert f"uncertainty is above 90 mm in {expected} of {T} tracked frames" in shaky.verdict.reasons[-1]
    quality = np.full(T, QUALITY_OUT_OF_VIEW, np.uint8)
    quality[:5] = QUALITY_OK  # only 5 frames tracked: the others are not counted, even where u is large
    few = assess(jitter, names, np.full(T, 0.6), quality, HEIGHT, RATE, cfg.verdict, cfg.uncertainty)
    assert few.signals.n_uncertain <= 5
    loose = cfg.verdict.model_copy(update={"uncertain_mm": 1000.0})
    assert assess(jitter, names, np.full(T, 0.6), np.zeros(T, np.uint8), HEIGHT, RATE, loose,
                  cfg.uncertainty).signals.n_uncertain == 0  # fmt: skip


# --------------------------------------------------------------------------------------- config
def test_verdict_and_uncertainty_config_reject_bad_values(tmp_path):
    cfg = load_tracking_config()
    assert cfg.verdict.max_crossed_fraction == 0.1 and cfg.uncertainty.scales(("knee_l",))[0] == 0.76
    doc = cfg.model_dump()
    for section, key, value, message in (("verdict", "max_flagged_fracton", 0.5, "max_flagged_fracton"),
                                         ("verdict", "segment_ratio", [1.1, 1.3], "segment_ratio"),
                                         ("uncertainty", "point_scale", {"(": 1.0}, "regular expression")):  # fmt: skip
        bad = {**doc, section: {**doc[section], key: value}}
        path = tmp_path / "tracking.yaml"
        path.write_text(yaml.safe_dump(bad))
        with pytest.raises(ConfigError, match=message.replace("(", r"\(")):
            load_yaml_model(TrackingConfig, path)


def test_a_rejected_shape_calibration_is_named_and_doubtful(walk):
    """A calibrated body outside shape.ranges was replaced by the shipped proportions: the run is not
    accepted silently, the reason carries the calibration's own sentence."""
    from dataclasses import replace

    from gaitcap.quality import judge, run_signals
    from gaitcap.tracking.config import load_tracking_config

    points, names = walk
    cfg = load_tracking_config().verdict
    signals = run_signals(points, names, np.zeros(len(points), np.uint8), 1.9, rate_hz=RATE)
    assert judge(signals, cfg).verdict == "ok"
    problem = "leg 0.600 m is 0.316 of the height, outside 0.40-0.56"
    v = judge(replace(signals, body_problems=(problem,)), cfg)
    assert v.verdict == "doubtful" and v.reasons == (
        f"the shape calibration gave a body outside anthropometric ranges ({problem}): tracked with body.yaml's proportions",)


def test_legs_the_silhouettes_hold_little_of_in_many_frames_get_a_note_the_verdict_unchanged(walk):
    points, names = walk
    quality = np.zeros(len(points), np.uint8)
    cfg = VerdictConfig()
    held = np.full(T, 0.9)
    lost = held.copy()
    lost[: T // 2] = 0.2  # half the frames: over max_unsupported_fraction (0.25)
    few = held.copy()
    few[: T // 10] = 0.2  # a tenth of them: under it
    unjudged = np.full(T, np.nan)
    unjudged[:4] = 0.2  # the only frames judged (the segment out of view in the others) are all below
    support = {"thigh_l": held, "shank_l": lost, "thigh_r": few, "shank_r": unjudged}
    a = assess(points, names, np.full(T, 0.8), quality, HEIGHT, RATE, cfg, UncertaintyConfig(), leg_support=support)
    assert a.verdict.verdict == "ok" and a.verdict.reasons == ()
    (note,) = [n for n in a.verdict.notes if n.startswith("legs placed where")]
    assert f"shank_l in {T // 2} of {T} frames" in note and "shank_r in 4 of 4 frames" in note
    assert "thigh_l" not in note and "thigh_r" not in note
    quiet = assess(points, names, np.full(T, 0.8), quality, HEIGHT, RATE, cfg, UncertaintyConfig(),
                   leg_support={"shank_l": few})  # fmt: skip
    assert not [n for n in quiet.verdict.notes if n.startswith("legs placed where")]


def test_feet_the_silhouettes_hold_little_of_get_a_note_of_their_own(walk):
    """A foot the masks miss in many frames (a shoe of the floor's colour) gets its own note, which says
    that its heel and toe points and the events follow the leg; it is neither the legs' note nor a
    leg for ``lost_legs`` (:func:`unsupported_legs` reads the legs alone unless told otherwise)."""
    points, names = walk
    quality = np.zeros(len(points), np.uint8)
    cfg = VerdictConfig()
    held = np.full(T, 0.9)
    lost = held.copy()
    lost[: T // 2] = 0.2
    support = {"thigh_l": held, "shank_l": held, "foot_l": lost, "foot_r": held}
    a = assess(points, names, np.full(T, 0.8), quality, HEIGHT, RATE, cfg, UncertaintyConfig(), leg_support=support)
    assert a.verdict.verdict == "ok" and a.verdict.reasons == ()
    (note,) = [n for n in a.verdict.notes if n.startswith("feet placed where")]
    assert f"foot_l in {T // 2} of {T} frames" in note and "foot_r" not in note and "gait events" in note
    assert "or the tracker placed the feet off them" in note  # not only the masks to blame (a baseline tracker)
    assert not [n for n in a.verdict.notes if n.startswith("legs placed where")]
    assert unsupported_legs(support, cfg) == {}
    assert unsupported_legs(support, cfg, FOOT_SEGMENTS) == {"foot_l": (T // 2, T)}


def test_cameras_out_of_step_make_the_verdict_doubtful():
    """The frame sync check's finding (gaitcap.sync_check) is a reason of its own, naming the cameras."""
    from gaitcap.quality import RunSignals, judge
    from gaitcap.tracking.config import VerdictConfig

    base = dict(n_frames=50, n_tracked=50, n_ok=50, n_crossed=0, floor_m=0.0)
    cfg = VerdictConfig()
    assert judge(RunSignals(**base), cfg).verdict == "ok"
    late = judge(RunSignals(**base, out_of_step="cam2's video starts 1.1 frames (45 ms) after cam1's"), cfg)
    assert late.verdict == "doubtful"
    assert late.reasons == ("the cameras' videos look out of step (cam2's video starts 1.1 frames (45 ms) after "
                            "cam1's): views a frame apart put the joints centimetres off (see the note on trimming "
                            "the videos)",)
