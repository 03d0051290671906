"""The backward pass: the choice between the two passes, the frame spool, the writer's overwrite."""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import h5py
import numpy as np
import pytest

from gaitcap.errors import ConfigError
from gaitcap.io.spool import FrameSpool
from gaitcap.io.track_h5 import QUALITY_OK, TrackWriter
from gaitcap.tracking.backward import (
    CROSSING_WINDOW_S,
    alternating_stretches,
    choose_backward,
    crossing_frames,
    leg_points,
    mean_pose,
    merge_passes,
    order_legs,
    order_sign,
    step_frames,
)
from gaitcap.tracking.config import load_tracking_config

RNG = np.random.default_rng(11)


def _legs(T: int = 20, K: int = 8) -> np.ndarray:
    return RNG.normal(0.0, 0.2, (T, K, 3))


def test_identical_passes_keep_the_forward_pass() -> None:
    p, fit = _legs(), RNG.uniform(0.6, 0.9, 20)
    assert not choose_backward(p, p.copy(), fit, fit.copy(), 0.03).any()


def test_a_disagreeing_run_goes_whole_to_the_better_summed_fit() -> None:
    T = 20
    fwd = _legs(T)
    bwd = fwd.copy()
    bwd[5:12] += 0.2  # the passes disagree on frames 5-11 (legs 0.35 m apart)
    fit_f, fit_b = np.full(T, 0.8), np.full(T, 0.8)
    fit_b[5:12] = [0.85, 0.85, 0.85, 0.85, 0.85, 0.78, 0.78]  # higher in sum, lower on two frames
    take = choose_backward(fwd, bwd, fit_f, fit_b, 0.03)
    assert take[5:12].all() and not take[:5].any() and not take[12:].any()
    fit_b[5:12] = 0.79  # lower in sum: the whole run stays forward
    assert not choose_backward(fwd, bwd, fit_f, fit_b, 0.03).any()


def test_agreeing_frames_take_the_better_fit_frame_by_frame() -> None:
    T = 10
    fwd = _legs(T)
    bwd = fwd + 0.005  # within 3 cm everywhere
    fit_f = np.full(T, 0.8)
    fit_b = np.where(np.arange(T) % 2 == 0, 0.81, 0.79)
    take = choose_backward(fwd, bwd, fit_f, fit_b, 0.03)
    assert np.array_equal(take, np.arange(T) % 2 == 0)


@dataclass
class _Est:
    q: np.ndarray
    points: np.ndarray
    fit: float


def test_merge_passes_takes_the_second_pass_where_choose_backward_gives_it() -> None:
    """The merged list holds the second pass's estimates (the objects themselves) exactly on the
    frames choose_backward gives it, the first's elsewhere; passes of other lengths are refused."""
    T, legs = 12, np.array([1, 3])
    pts = RNG.normal(0.0, 0.2, (T, 5, 3))
    first = [_Est(np.zeros(3), pts[t], 0.8) for t in range(T)]
    moved = pts.copy()
    moved[3:7, legs] += 0.2  # disagree on frames 3-6, with a better summed fit there
    moved[:, 0] += 1.0  # a point that is not a leg's: not compared
    second = [_Est(np.ones(3), moved[t], 0.85 if 3 <= t < 7 else 0.79) for t in range(T)]
    merged = merge_passes(first, second, legs, 0.03)
    expected = choose_backward(pts[:, legs], moved[:, legs], np.full(T, 0.8), np.array([e.fit for e in second]), 0.03)
    assert [m is b for m, b in zip(merged, second)] == list(expected)
    assert [m is a for m, a in zip(merged, first)] == list(~expected)
    assert expected[3:7].all() and not expected[7:].any() and not expected[:3].any()
    with pytest.raises(ValueError, match="same frames"):
        merge_passes(first, second[:-1], legs, 0.03)


def test_a_run_of_disagreeing_frames_switches_once_where_that_gains_enough() -> None:
    """A subject turning round: over one run where the passes' legs disagree, the first pass fits
    better before the turn and the second after it. The merge switches once, at the turn, when the
    split gains SPLIT_GAIN over the run's better pass; a gain of a few hundredths a frame (legs
    crossing) leaves the run whole, as choose_backward gives it."""
    from gaitcap.tracking import backward

    T, legs = 40, np.array([1, 3])
    pts = RNG.normal(0.0, 0.2, (T, 5, 3))
    first = [_Est(np.zeros(3), pts[t], 0.85 if t < 24 else 0.75) for t in range(T)]
    moved = pts.copy()
    moved[:, legs] += 0.2  # the legs disagree on every frame: one run
    second = [_Est(np.ones(3), moved[t], 0.72 if t < 24 else 0.84) for t in range(T)]
    merged = merge_passes(first, second, legs, 0.03)
    assert [m is b for m, b in zip(merged, second)] == [t >= 24 for t in range(T)]
    # the reverse order: the second pass first
    merged = merge_passes(second, first, legs, 0.03)
    assert [m is b for m, b in zip(merged, first)] == [t < 24 for t in range(T)]
    # a split worth less than SPLIT_GAIN: the run goes whole to the higher summed fit (the first)
    near = [_Est(np.ones(3), moved[t], 0.84 if t < 24 else 0.76) for t in range(T)]
    gain = sum(n.fit - f.fit for n, f in zip(near[24:], first[24:]))
    assert 0 < gain < backward.SPLIT_GAIN
    assert all(m is f for m, f in zip(merge_passes(first, near, legs, 0.03), first))
    assert backward._split_run(np.array([0.1]), backward.SPLIT_GAIN) is None  # one frame: nothing to split


def test_a_frame_missing_from_one_pass_takes_the_other() -> None:
    T = 6
    fwd, bwd = _legs(T), _legs(T)
    fit_f, fit_b = np.full(T, 0.8), np.full(T, 0.7)
    fwd[2], fit_f[2] = np.nan, np.nan
    bwd[4], fit_b[4] = np.nan, np.nan
    take = choose_backward(fwd, bwd, fit_f, fit_b, 0.03)
    assert take[2] and not take[4]


@pytest.mark.parametrize("agree_m", [0.0, -0.01])
def test_choose_backward_rejects_bad_arguments(agree_m: float) -> None:
    p, fit = _legs(5), np.full(5, 0.8)
    with pytest.raises(ValueError, match="agree_m"):
        choose_backward(p, p, fit, fit, agree_m)
    with pytest.raises(ValueError, match="shape|alike"):
        choose_backward(p, p[:, :3], fit, fit, 0.03)


def test_leg_points_are_the_knees_to_toes() -> None:
    names = ("pelvis", "hip_l", "knee_l", "ankle_l", "heel_l", "toe_l", "knee_r", "head")
    assert [names[i] for i in leg_points(names)] == ["knee_l", "ankle_l", "heel_l", "toe_l", "knee_r"]


def test_spool_gives_every_frame_back_bit_for_bit() -> None:
    frames = [[RNG.random((24, 32), dtype=np.float32), (RNG.random((24, 32)) > 0.7).astype(np.float32)]
              for _ in range(7)]  # fmt: skip
    with FrameSpool() as spool:
        for f in frames:
            spool.append(f)
        assert len(spool) == 7
        for t in (6, 0, 3, 3, 5):  # any order, twice
            back = spool.read(t)
            assert all(np.array_equal(a, b) and b.dtype == np.float32 for a, b in zip(frames[t], back))
        with pytest.raises(ValueError, match="frame 7"):
            spool.append([np.zeros((24, 32), np.float32)])


def test_mean_pose_is_halfway_and_takes_the_heading_the_shorter_way_round() -> None:
    wrap = np.array([False, True, False])
    a = np.array([0.1, np.radians(179.0), -0.4])
    b = np.array([0.3, np.radians(-179.0), -0.2])
    m = mean_pose(a, b, wrap)
    assert np.allclose(m[[0, 2]], [0.2, -0.3])
    assert np.isclose(abs(m[1]), np.pi)  # 180 degrees, not the 0 of the plain mean
    r = mean_pose(b, a, wrap)  # the other way round: the same mean
    assert np.allclose(r[[0, 2]], m[[0, 2]]) and np.isclose(abs(r[1]), np.pi)
    assert np.allclose(mean_pose(a, a, wrap), a)
    c = np.array([0.0, np.radians(10.0), 0.0])
    assert np.isclose(mean_pose(c, -c, wrap)[1], 0.0)  # +10 and -10 degrees: 0


def test_agreeing_frames_take_the_mean_of_the_two_passes(tmp_path, monkeypatch) -> None:
    """``backward.average``: a frame whose merged estimate is one pass's and agrees with the other's
    takes their mean pose, its points and fit computed for it and its uncertainty kept; a frame
    where the passes disagree, or whose estimate is neither pass's (the leg order's), is left."""
    from gaitcap import pipeline
    from gaitcap.body.model import load_body_model
    from gaitcap.tracking.base import Estimate
    from gaitcap.tracking.projector import PoseProjector

    model = load_body_model()
    knee = model.dof_index("knee_flexion_l")

    class Tracker:  # what _average_agreeing reads of a tracker; the fit of a pose: its knee flexion
        def __init__(self) -> None:
            self.model, self.projector = model, PoseProjector(model, [])

        def full_fit(self, obs, q):
            return -1.0, float(q[knee])

    monkeypatch.setattr(pipeline.Observation, "from_arrays", staticmethod(lambda arrays: None))
    tracker, T = Tracker(), 4
    forward = np.repeat(model.neutral_pose()[None], T, axis=0)
    forward[:, knee] = 0.4
    backward = forward.copy()
    backward[:, knee] = [0.5, 0.5, 2.0, 0.5]  # frame 2: the knee 1.6 rad apart, the passes disagree
    back = [Estimate(q=q, points=tracker.projector.points(q[None])[0], uncertainty=np.full(model.n_points, 0.02),
                     log_likelihood=0.0, fit=0.0, evaluations=0) for q in backward]  # fmt: skip
    other = Estimate(q=forward[3] + 0.01, points=back[3].points, uncertainty=back[3].uncertainty,
                     log_likelihood=0.0, fit=0.0, evaluations=0)  # fmt: skip
    chosen = {1: back[1], 3: other}  # frame 1 took the backward pass, frame 3 another estimate
    writer = TrackWriter(tmp_path / "t.h5", model.point_names, model.dof_names, 25.0, {})
    for t in range(T):
        est = chosen.get(t)
        q = forward[t] if est is None else est.q
        writer.append(tracker.projector.points(q[None])[0], np.full(model.n_points, 0.01), q, -2.0, 0.7, QUALITY_OK)

    class Spool:
        def read(self, t):
            return []

    cfg = load_tracking_config()
    raw = tracker.projector.points(forward)  # the forward pass's points
    pipeline._average_agreeing(tracker, Spool(), writer, raw, forward, back, chosen, 0, T, cfg)
    poses, fit = writer.read_poses(), writer.read_fit()
    assert np.allclose(poses[[0, 1], knee], 0.45) and np.allclose(fit[[0, 1]], 0.45)  # the mean, its own fit
    written, _ = writer.read_back()
    assert np.allclose(written[0], tracker.projector.points(poses[0][None])[0])
    assert poses[2, knee] == 0.4 and fit[2] == 0.7  # the passes disagree: the forward pass's, as written
    assert np.array_equal(poses[3], other.q) and fit[3] == 0.7  # the leg order's estimate: left as it is
    writer.finish(written, "none")
    with h5py.File(tmp_path / "t.h5") as f:
        assert np.allclose(f["uncertainty"][()], 0.01)  # every frame's uncertainty kept


def test_writer_replace_overwrites_one_frame(tmp_path) -> None:
    names, dofs = ("a", "b"), ("x", "y", "z")
    w = TrackWriter(tmp_path / "t.h5", names, dofs, 25.0, {})
    for t in range(3):
        w.append(np.full((2, 3), t, float), np.full(2, 0.01), np.full(3, t, float), -1.0, 0.5, QUALITY_OK)
    w.replace(1, np.full((2, 3), 9.0), np.full(2, 0.02), np.full(3, 9.0), -0.5, 0.9, QUALITY_OK)
    raw, _ = w.read_back()
    assert np.array_equal(raw[:, 0, 0], [0.0, 9.0, 2.0])
    assert np.array_equal(w.read_poses()[:, 0], [0.0, 9.0, 2.0])
    assert np.array_equal(w.read_fit(), [0.5, 0.9, 0.5])
    with pytest.raises(IndexError, match="frame 3"):
        w.replace(3, raw[0], np.zeros(2), np.zeros(3), 0.0, 0.0, QUALITY_OK)
    w.finish(raw, "none")


def test_backward_config_is_checked(tmp_path) -> None:
    assert load_tracking_config().backward.enabled  # on by default (docs/validation.md: the whole suite, both seeds)
    bad = tmp_path / "t.yaml"
    bad.write_text("backward:\n  agree_m: 0.0\n")
    with pytest.raises(ConfigError, match="agree_m"):
        load_tracking_config(bad)
    bad.write_text("backward:\n  crossing_m: 0.0\n")
    with pytest.raises(ConfigError, match="crossing_m"):
        load_tracking_config(bad)
    bad.write_text("backward:\n  order_fit_tolerance: -0.01\n")
    with pytest.raises(ConfigError, match="order_fit_tolerance"):
        load_tracking_config(bad)
    bad.write_text("backward:\n  enable: false\n")
    with pytest.raises(ConfigError, match="enable"):
        load_tracking_config(bad)


# ---------------------------------------------------------------- the leading leg alternates

RATE = 25.0


def _lead(T: int = 75, stride_hz: float = 1.0, phase: float = 0.3) -> np.ndarray:
    """A walk's fore-aft separation of the ankles, left minus right (T,) metres: the feet pass
    each other twice a stride."""
    return 0.4 * np.sin(2 * np.pi * stride_hz * np.arange(T) / RATE + phase)


def test_crossing_frames_are_where_the_feet_pass() -> None:
    d = _lead()
    found = crossing_frames(np.abs(d), RATE, 0.1)
    passes = np.flatnonzero(np.sign(d[1:]) != np.sign(d[:-1]))  # d changes sign between t and t + 1
    assert len(found) == len(passes) == 6
    assert all(abs(f - (p + 0.5)) <= 0.5 for f, p in zip(found, passes))  # the frame nearer the passing
    assert crossing_frames(np.abs(d) + 0.2, RATE, 0.1) == []  # the feet never come close
    flat = np.full(40, 0.05)  # standing with the feet together: one minimum per window at most
    found = crossing_frames(flat, RATE, 0.1)
    assert all(b - a > round(CROSSING_WINDOW_S * RATE) for a, b in itertools.pairwise(found))


def test_crossing_frames_fill_in_a_passing_the_rhythm_expects() -> None:
    d = _lead()
    strict = crossing_frames(np.abs(d), RATE, 0.1)
    for k in (0, 3, len(strict) - 1):  # a passing where one pass has a leg misplaced: the mean stays above 0.1 m
        sep = np.abs(d)
        t = strict[k]
        sep[t - 3 : t + 4] += 0.07
        assert crossing_frames(sep, RATE, 0.1) == strict, k  # found again, where the rhythm expects it
        sep[t - 3 : t + 4] += 0.15  # the feet never come near: no passing
        assert crossing_frames(sep, RATE, 0.1) == [f for f in strict if f != t], k
    # the feet stop passing (a stop, a step-to gait): no passing made up from the rhythm
    stopped = np.abs(d)
    stopped[40:] = 0.3
    assert crossing_frames(stopped, RATE, 0.1) == [f for f in strict if f < 40]


def test_step_frames_is_half_the_stride_whatever_the_passings_found() -> None:
    for stride_hz in (0.8, 1.0, 1.3):
        d = _lead(75, stride_hz)
        expected = RATE / (2 * stride_hz)
        assert step_frames(np.abs(d), RATE) == pytest.approx(expected, rel=0.02), stride_hz
        strict = crossing_frames(np.abs(d), RATE, 0.1)
        sep = np.abs(d)
        for t in strict[1::2]:  # every other passing blurred by a misplaced leg: the intervals found double
            sep[t - 3 : t + 4] += 0.1
        assert step_frames(sep, RATE) == pytest.approx(expected, rel=0.03), stride_hz
        sep[::4] = np.nan  # frames unknown
        assert step_frames(sep, RATE) == pytest.approx(expected, rel=0.03), stride_hz
    assert step_frames(np.abs(_lead(15)), RATE) is None  # under one stride of the fastest walk
    assert step_frames(np.full(40, np.nan), RATE) is None


def test_crossing_frames_fill_in_passings_the_median_interval_hides() -> None:
    """A passing missed beside few others (the mean distance of the two passes stays between
    ``cross_m`` and twice it there): the interval around it is twice the step, which the median of
    the intervals found, half of them doubled, does not show as long."""
    for T, hidden in ((50, (1,)), (75, (1, 3))):
        d = _lead(T)
        strict = crossing_frames(np.abs(d), RATE, 0.1)
        sep = np.abs(d)
        for k in hidden:
            sep[strict[k] - 3 : strict[k] + 4] += 0.1
        assert min(sep[strict[k]] for k in hidden) > 0.1
        assert crossing_frames(sep, RATE, 0.1) == strict, (T, hidden)


def test_crossing_frames_fill_in_the_rhythm_from_a_single_passing_found() -> None:
    d = _lead(70)  # the last passing 9 frames before the end
    strict = crossing_frames(np.abs(d), RATE, 0.1)
    assert len(strict) == 5
    sep = np.abs(d)
    for t in strict[:2] + strict[3:]:  # all but one passing blurred: no interval between passings found
        sep[t - 3 : t + 4] += 0.1
    assert crossing_frames(sep, RATE, 0.1) == strict


def test_crossing_frames_make_up_no_passing_from_a_spurious_one() -> None:
    """Short steps (the ankles never 0.2 m apart fore and aft, as in a shuffling gait) and one
    spurious dip 8 frames after a passing: the intervals found (8, 6, 16, 15, 16) read as a step of
    8 frames would make up a passing in the middle of each stretch; the stride does not change."""
    d = 0.15 * np.sin(2 * np.pi * 0.8 * np.arange(63) / RATE + 0.3)
    strict = crossing_frames(np.abs(d), RATE, 0.1)
    assert strict == [0, 14, 30, 45, 61]
    sep = np.abs(d)
    sep[strict[0] + 8] = 0.02
    assert crossing_frames(sep, RATE, 0.1) == sorted([*strict, strict[0] + 8])


def test_order_sign_reads_the_leading_ankle() -> None:
    assert order_sign(np.array([0.1, 0.3, 0.2, 0.01]), 0.03) == (1, True)
    assert order_sign(np.array([-0.1, -0.3, 0.2, -0.2]), 0.03) == (-1, False)  # one frame exchanged
    assert order_sign(np.array([0.01, -0.02, np.nan]), 0.03) == (0, False)  # never apart


def test_alternating_stretches_follow_the_passings_and_change_the_fewest_frames() -> None:
    truth = _lead()
    bounced = np.abs(truth) * np.sign(truth[0])  # a pass whose legs bounce off each other: never exchanged order
    crossings = crossing_frames(np.abs(truth), RATE, 0.1)
    stretches = alternating_stretches(bounced, truth, truth, RATE, 0.1, 0.03)
    covered = sorted({t for a, b, _ in stretches for t in range(a, b)} | set(crossings))
    assert covered == list(range(len(truth))) and len(stretches) >= 6  # every frame but the passings
    for a, b, sign in stretches:  # each stretch's sign is the truth's, though the forward pass never alternates
        assert order_sign(truth[a:b], 0.03) == (sign, True)
    # the merged passes follow the truth but in one stretch: the signs are still the truth's ...
    merged = truth.copy()
    a, b, _ = stretches[2]
    merged[a:b] *= -1
    assert alternating_stretches(bounced, truth, merged, RATE, 0.1, 0.03) == stretches
    # ... even when the forward pass started with the legs exchanged
    assert alternating_stretches(-bounced, truth, merged, RATE, 0.1, 0.03) == stretches
    # the merge exchanged everywhere: the fewest frames change with the other sequence of signs
    flipped = alternating_stretches(bounced, truth, -truth, RATE, 0.1, 0.03)
    assert [(a, b, -sign) for a, b, sign in flipped] == stretches
    # a tie (no frame with a leading ankle in the merge) goes to the forward pass's start
    tie = alternating_stretches(-bounced, truth, np.zeros_like(truth), RATE, 0.1, 0.03)
    assert [(a, b, -sign) for a, b, sign in tie] == stretches
    assert alternating_stretches(np.zeros(20), np.zeros(20), np.zeros(20), RATE, 0.1, 0.03) == []  # nobody leads
    with pytest.raises(ValueError, match="alike"):
        alternating_stretches(truth, truth[:-1], truth, RATE, 0.1, 0.03)


NAMES = ("pelvis", "ankle_l", "ankle_r")


def _walk(d: np.ndarray) -> np.ndarray:
    """Points (T, 3, 3) of NAMES for a walk along x at 1.2 m/s whose ankles lead by d (T,)."""
    T = len(d)
    x = 1.2 * np.arange(T) / RATE
    pts = np.zeros((T, 3, 3))
    pts[:, 0, 0] = x
    pts[:, 1, 0], pts[:, 1, 1] = x + d / 2, 0.1
    pts[:, 2, 0], pts[:, 2, 1] = x - d / 2, -0.1
    return pts


def _ests(d: np.ndarray, fit: float, tag: float) -> list[_Est]:
    return [_Est(np.full(2, tag), p, fit) for p in _walk(d)]


def _order(truth_lead: np.ndarray, forward_lead: np.ndarray, back_lead: np.ndarray, redo_lead: np.ndarray,
           fits: tuple[float, float, float], tolerance: float = 0.03, refined: tuple[np.ndarray, float] | None = None,
           refines: list | None = None):  # fmt: skip
    """order_legs over a run; returns the source of each frame ('f', 'b', 'r'; 'x': refined, from the
    leads and fit ``refined``, the (pose, frame) of each refinement appended to ``refines``) and the
    restarts' poses."""
    back = _ests(back_lead, fits[1], 2.0)
    redo = _ests(redo_lead, fits[2], 3.0)
    starts = []

    def again(q0, a, b, backwards):
        starts.append((q0.copy(), a, b))
        assert backwards == (a == 0)  # a first stretch is tracked back from the passing after it
        return redo[a:b]

    def refine(q0, t):
        refines.append((q0.copy(), t))
        return _ests(refined[0], refined[1], 4.0)[t]

    chosen: dict = {}
    cfg = load_tracking_config().backward.model_copy(update={"order_fit_tolerance": tolerance})
    order_legs(chosen, _walk(forward_lead), np.full(len(truth_lead), fits[0]), np.ones((len(truth_lead), 2)), back,
               NAMES, RATE, again, lambda q: -q, cfg, 0.03, refine if refined is not None else None)  # fmt: skip
    tags = {2.0: "b", 3.0: "r", 4.0: "x"}
    source = "".join("f" if t not in chosen else tags[chosen[t].q[0]] for t in range(len(truth_lead)))
    return source, starts


def _exchanged(truth: np.ndarray, k: int) -> np.ndarray:
    """The fore-aft separation with the legs exchanged over the k-th stretch between passings."""
    out = truth.copy()
    a, b, _ = alternating_stretches(truth, truth, truth, RATE, 0.1, 0.03)[k]
    out[a:b] *= -1
    return out


def test_order_legs_takes_the_pass_that_alternates() -> None:
    truth = _lead()
    forward = _exchanged(truth, 1)  # the legs bounced at the first passing and jumped back at the second
    source, starts = _order(truth, forward, truth, forward, (0.80, 0.79, 0.79))
    stretches = alternating_stretches(forward, truth, forward, RATE, 0.1, 0.03)
    for k, (a, b, sign) in enumerate(stretches):
        assert sign == order_sign(truth[a:b], 0.03)[0]
        assert set(source[a:b]) == {"b" if k == 1 else "f"}, (a, b, source)
    assert starts == []  # nothing tracked again where a pass alternates


def test_order_legs_tracks_a_stretch_again_when_neither_pass_alternates() -> None:
    truth = _lead()
    for k in (0, 1):  # the first stretch is tracked back from the passing after it, the others forwards
        forward = _exchanged(truth, k)
        source, starts = _order(truth, forward, forward, truth, (0.80, 0.80, 0.79))
        a, b, _ = alternating_stretches(forward, forward, forward, RATE, 0.1, 0.03)[k]
        assert source == "f" * a + "r" * (b - a) + "f" * (len(truth) - b)
        assert len(starts) == 1 and starts[0][1:] == (a, b) and np.array_equal(starts[0][0], -np.ones(2))


def test_order_legs_exchanges_the_merges_legs_when_the_stretch_tracked_again_does_not_alternate() -> None:
    truth = _lead()
    for k in (0, 1):
        forward = _exchanged(truth, k)  # both passes exchanged, and so is the stretch tracked again ...
        a, b, _ = alternating_stretches(forward, forward, forward, RATE, 0.1, 0.03)[k]
        mid = (a + b) // 2
        forward[mid] = truth[mid]  # ... but for one frame in the middle, which leads as it must
        refines: list = []
        source, starts = _order(truth, forward, forward, forward, (0.80, 0.80, 0.80), refined=(truth, 0.79),
                                refines=refines)  # fmt: skip
        assert source == "f" * a + "x" * (mid - a) + "f" + "x" * (b - mid - 1) + "f" * (len(truth) - b)
        assert len(starts) == 1  # tried first
        # only the frames that lead the wrong way, each searched again from its merged pose with the
        # legs exchanged
        assert [t for _, t in refines] == [t for t in range(a, b) if t != mid]
        assert all(np.array_equal(q, -np.ones(2)) for q, _ in refines)
    # a frame beside the passing that stays exchanged once searched again: it leads so over most of the
    # stretch, and with no other candidate leading so it is taken
    forward = _exchanged(truth, 1)
    a, b, _ = alternating_stretches(forward, forward, forward, RATE, 0.1, 0.03)[1]
    stubborn = truth.copy()
    stubborn[a] *= -1
    source, _ = _order(truth, forward, forward, forward, (0.80, 0.80, 0.80), refined=(stubborn, 0.79), refines=[])
    assert source == "f" * a + "x" * (b - a) + "f" * (len(truth) - b)
    # not taken when it fits worse than the tolerance, nor asked for where the restart alternates
    source, _ = _order(truth, forward, forward, forward, (0.80, 0.80, 0.80), refined=(truth, 0.76), refines=[])
    assert set(source) == {"f"}
    refines = []
    source, _ = _order(truth, forward, forward, truth, (0.80, 0.80, 0.79), refined=(truth, 0.80), refines=refines)
    assert "r" in source and "x" not in source and refines == []


def test_order_legs_leaves_a_stretch_the_silhouettes_prefer() -> None:
    truth = _lead()
    forward = _exchanged(truth, 1)
    source, _ = _order(truth, forward, truth, truth, (0.80, 0.74, 0.74))  # the alternating ones fit 0.06 worse
    assert set(source) == {"f"}
    source, _ = _order(truth, truth, forward, forward, (0.80, 0.80, 0.80))  # the forward pass alternates already
    assert set(source) == {"f"}


class _FakeTracker:
    """What _backward_pass asks of a tracker: start and step (an estimate per frame, fit 0.8)."""

    def __init__(self, n_points: int) -> None:
        names = ("knee_l", "knee_r", "ankle_l", "ankle_r", "toe_l", "toe_r")[:n_points]
        self.model = type("M", (), {"point_names": names})()
        self.n_points = n_points

    def start(self, q0, fresh: bool = True) -> None:
        pass

    def step(self, obs):
        from gaitcap.tracking.base import Estimate

        return Estimate(np.zeros(3), np.zeros((self.n_points, 3)), np.zeros(self.n_points), 0.0, 0.8, 1)


class _FakeWriter:
    """A forward pass of T tracked frames; ``replaced``: frame -> the estimate written over it."""

    def __init__(self, T: int, n_points: int) -> None:
        self.T, self.n_points, self.replaced = T, n_points, {}

    def read_back(self):
        return np.zeros((self.T, self.n_points, 3)), np.full(self.T, QUALITY_OK, np.uint8)

    def read_poses(self):
        return np.arange(self.T * 3, dtype=float).reshape(self.T, 3)

    def read_fit(self):
        return np.full(self.T, 0.8)

    def replace(self, i, points, uncertainty, pose, likelihood, fit, quality) -> None:
        self.replaced[i] = pose


@pytest.mark.parametrize(
    "doubts, second, restarted, kept, paused",
    [([0], True, False, "first", 0), ([4, 3], True, True, "second", 0), ([4, 4], True, True, "second", 0),
     ([4, 5], True, True, "first", 0), ([4], False, True, "first", 0), ([0, 0], True, True, "second", 20),
     ([0, 1], True, True, "first", 20)],
)  # fmt: skip
def test_a_second_hypothesis_only_for_a_run_in_doubt_and_kept_if_no_worse(monkeypatch, doubts, second, restarted,
                                                                          kept, paused):  # fmt: skip
    """backward.restart's gate: the fresh start is asked for only when the merged run's legs are in
    doubt (legs_in_doubt > 0) or it pauses at a turn (pivots > 0), with the forward pass's last pose
    and the run's bounds; its merge replaces the first only if it leaves no more frames in doubt (the
    pauses not counted); none to be had (None) keeps the first."""
    from gaitcap import pipeline
    from gaitcap.tracking.base import Estimate

    T, P = 6, 4
    cfg = load_tracking_config()
    cfg.backward.average = False  # the merge's decisions alone (the mean of agreeing frames: its own test)
    doubt = iter(doubts)
    monkeypatch.setattr(pipeline, "legs_in_doubt", lambda points, names, rate, vcfg: next(doubt))
    monkeypatch.setattr(pipeline, "pivots", lambda points, names, rate: paused)
    marker = {"first": np.full(3, 1.0), "second": np.full(3, 2.0)}
    merges = []

    def merge_run(tracker, spool, raw, poses, fit, back, s, e, cfg_, rate_hz):
        which = "second" if merges else "first"
        merges.append(which)
        return {0: Estimate(marker[which], np.zeros((P, 3)), np.zeros(P), 0.0, 0.8, 1)}

    monkeypatch.setattr(pipeline, "_merge_run", merge_run)
    calls = []

    def restart(spool, q_last, s, e):
        calls.append((q_last.copy(), s, e))
        return [_FakeTracker(P).step(None) for _ in range(e - s)] if second else None

    writer = _FakeWriter(T, P)
    spool = type("Spool", (), {"read": lambda self, t: [np.zeros((2, 2), np.float32)]})()
    pipeline._backward_pass(_FakeTracker(P), spool, writer, cfg, 25.0, restart)
    assert bool(calls) == restarted
    if restarted:
        np.testing.assert_array_equal(calls[0][0], writer.read_poses()[T - 1])
        assert calls[0][1:] == (0, T)
    assert merges == (["first", "second"] if restarted and second else ["first"])
    np.testing.assert_array_equal(writer.replaced[0], marker[kept])



@pytest.mark.parametrize(
    "facing, paused, doubts, begun, used",
    [(30, 0, [4, 3], True, True), (30, 0, [0], True, False), (0, 0, [4, 3], False, True), (0, 0, [0], False, False),
     (0, 20, [0, 0], True, True)],
)  # fmt: skip
def test_a_fresh_start_begun_beside_the_merge_is_used_only_if_the_merged_run_is_in_doubt(monkeypatch, facing, paused,
                                                                                         doubts, begun, used):  # fmt: skip
    """``early``: the fresh start is begun in a worker thread before the merge when the forward pass
    moves against the way it faces (facing_in_doubt > 0) or pauses at a turn (pivots > 0), with the
    arguments a call after the merge gets; its result is taken when the merged run is in doubt
    (legs_in_doubt) or pauses, and it is told to stop otherwise; any other run gets it after the
    merge, as without ``early``."""
    import threading

    from gaitcap import pipeline
    from gaitcap.tracking.base import Estimate

    T, P = 6, 4
    cfg = load_tracking_config()
    cfg.backward.average = False  # the merge's decisions alone (the mean of agreeing frames: its own test)
    doubt = iter(doubts)
    monkeypatch.setattr(pipeline, "legs_in_doubt", lambda points, names, rate, vcfg: next(doubt))
    monkeypatch.setattr(pipeline, "facing_in_doubt", lambda points, names, rate: facing)
    monkeypatch.setattr(pipeline, "pivots", lambda points, names, rate: paused)
    monkeypatch.setattr(pipeline, "_merge_run", lambda *a: {0: Estimate(np.zeros(3), np.zeros((P, 3)), np.zeros(P), 0.0,
                                                                        0.8, 1)})  # fmt: skip
    calls, stops = [], []

    def restart(spool, q_last, s, e, stop=None):
        calls.append((q_last.copy(), s, e, threading.current_thread() is threading.main_thread()))
        if stop is not None:
            stops.append(stop)
        return [_FakeTracker(P).step(None) for _ in range(e - s)]

    merged = []
    monkeypatch.setattr(pipeline, "merge_passes", lambda back, second, legs, agree: merged.append(second) or back)
    writer = _FakeWriter(T, P)
    spool = type("Spool", (), {"read": lambda self, t: [np.zeros((2, 2), np.float32)]})()
    pipeline._backward_pass(_FakeTracker(P), spool, writer, cfg, 25.0, restart, early=True)
    assert len(calls) == (1 if begun or used else 0)
    if calls:
        np.testing.assert_array_equal(calls[0][0], writer.read_poses()[T - 1])
        assert calls[0][1:3] == (0, T)
        assert calls[0][3] == (not begun)  # begun early: in the worker thread
    assert len(merged) == used
    if begun:
        assert len(stops) == 1 and stops[0].is_set()  # told to stop once the run is merged, used or not
    assert next(doubt, None) is None  # every legs_in_doubt answer asked for


def test_tracked_back_ends_once_told_to_stop():
    """_tracked_back tracks frames e-1 down to s and returns them in frame order; once its stop event
    is set no further frame is tracked (a fresh start begun beside the merge and not needed)."""
    import threading

    from gaitcap import pipeline

    class Counting(_FakeTracker):
        def __init__(self, n_points, stop=None, after=None):
            super().__init__(n_points)
            self.steps, self.stop, self.after = 0, stop, after

        def step(self, obs):
            self.steps += 1
            if self.stop is not None and self.steps == self.after:
                self.stop.set()
            return super().step(obs)

    spool = type("Spool", (), {"read": lambda self, t: [np.zeros((2, 2), np.float32)]})()
    whole = Counting(4)
    assert len(pipeline._tracked_back(whole, spool, np.zeros(3), 2, 9)) == 7 and whole.steps == 7
    stop = threading.Event()
    stopped = Counting(4, stop, after=3)
    assert len(pipeline._tracked_back(stopped, spool, np.zeros(3), 2, 9, stop=stop)) == 3 and stopped.steps == 3
    assert pipeline._tracked_back(Counting(4), spool, np.zeros(3), 2, 9, stop=stop) == []  # stopped before the start


def test_tracked_back_steps_on_the_observations_already_read():
    """The frames the fresh start's initialisation read (e - 1, e - 2, ...) are stepped on as those same
    objects, so that the frames its leg check tracked are taken as tracked (Tracker.remember); the
    others are read from the spool."""
    from gaitcap import pipeline

    seen = []

    class Seeing(_FakeTracker):
        def step(self, obs):
            seen.append(obs)
            return super().step(obs)

    spool = type("Spool", (), {"read": lambda self, t: [np.full((2, 2), t, np.float32)]})()
    read = [object(), object(), object()]
    assert len(pipeline._tracked_back(Seeing(4), spool, np.zeros(3), 2, 9, read=read)) == 7
    assert seen[:3] == read
    assert [float(o.silhouettes[0][0, 0]) for o in seen[3:]] == [5.0, 4.0, 3.0, 2.0]


#: the legs of the runs _mirror_run compares: knee_l, knee_r, ankle_l, ankle_r (left at y > 0)
_LEGS = np.array([[0.1, 0.1, 0.5], [-0.1, -0.1, 0.5], [0.1, 0.1, 0.1], [-0.1, -0.1, 0.1]])


class _MirrorTracker(_FakeTracker):
    """A tracker whose leg-swapped mirror of q is q + 100 and whose estimates keep the pose it was
    started from, fitting ``mirror_fit`` when started from a mirror, 0.8 otherwise; its legs are
    :data:`_LEGS`, left and right exchanged when started from a mirror if ``exchanges``."""

    def __init__(self, n_points: int, mirror_fit: float, exchanges: bool = True) -> None:
        super().__init__(n_points)
        self.mirror_fit, self.starts, self.q, self.likelihood = mirror_fit, [], None, None
        self.exchanges = exchanges

    def mirrored(self, q):
        return np.asarray(q, float) + 100.0

    def start(self, q0, fresh: bool = True) -> None:
        self.q = np.asarray(q0, float).copy()
        self.starts.append((self.q.copy(), fresh))

    def step(self, obs):
        from gaitcap.tracking.base import Estimate

        mirror = self.q[0] >= 100.0
        legs = _LEGS[[1, 0, 3, 2]] if mirror and self.exchanges else _LEGS
        return Estimate(self.q.copy(), legs.copy(), np.zeros(self.n_points), 0.0, self.mirror_fit if mirror else 0.8, 1)


@pytest.mark.parametrize("concurrent", [True, False])
@pytest.mark.parametrize("mirror_fit, exchanges, kept", [(0.81, True, True), (0.8, True, False), (0.79, True, False),
                                                         (0.81, False, False)])
def test_the_mirror_run_replaces_the_whole_run_only_if_it_fits_better(monkeypatch, mirror_fit, exchanges, kept,
                                                                      concurrent):  # fmt: skip
    """_mirror_run tracks the run forwards from the mirror of its merged first pose and backwards
    (a tracker of its own, with a random stream apart) from that of its merged last pose (both
    settled starts), merges them as the run was merged, and returns every frame of it if its legs
    are the other way round and its mean fit beats the merged run's, else the merge unchanged (a
    mirror whose legs came back to the run's, however well it fits); the two passes side by side or
    one after the other, as the compiled kernels allow."""
    from gaitcap import pipeline
    from gaitcap.tracking.base import Estimate

    T, P, s, e = 8, 4, 2, 7
    cfg = load_tracking_config()
    merged_args = []

    def merge_run(tracker, spool, raw, poses, fit, back, s_, e_, cfg_, rate_hz):
        merged_args.append((poses[s_:e_].copy(), fit[s_:e_].copy(), [b.q.copy() for b in back]))
        return {}  # the mirror's forward pass throughout

    monkeypatch.setattr(pipeline, "_merge_run", merge_run)
    monkeypatch.setattr(pipeline, "_concurrent_kernels", lambda what: concurrent)
    writer = _FakeWriter(T, P)
    poses, fit = writer.read_poses(), writer.read_fit()
    chosen = {e - s - 1: Estimate(np.full(3, -5.0), _LEGS.copy(), np.zeros(P), 0.0, 0.8, 1)}  # the last frame
    spool = type("Spool", (), {"read": lambda self, t: [np.zeros((2, 2), np.float32)]})()
    tracker, backwards = _MirrorTracker(P, mirror_fit, exchanges), _MirrorTracker(P, mirror_fit, exchanges)
    streams = []
    monkeypatch.setattr(pipeline, "_new_tracker", lambda cfg_, model, lik, stretch=None: streams.append(stretch) or
                        backwards)  # fmt: skip
    raw = np.tile(_LEGS, (T, 1, 1))  # the forward pass's legs, left at y > 0
    out, note = pipeline._mirror_run(tracker, spool, raw, poses, fit, chosen, s, e, cfg, 25.0)
    [(first, fresh1)], [(last, fresh2)] = tracker.starts, backwards.starts
    assert streams == [pipeline._MIRROR_STREAM + s]
    np.testing.assert_array_equal(first, poses[s] + 100.0)  # the mirror of the merged first pose
    np.testing.assert_array_equal(last, np.full(3, 95.0))  # the mirror of the merged last pose (chosen's)
    assert not fresh1 and not fresh2
    forward_poses, forward_fit, back = merged_args[0]
    np.testing.assert_array_equal(forward_poses, np.tile(poses[s] + 100.0, (e - s, 1)))
    np.testing.assert_allclose(forward_fit, mirror_fit)
    assert len(back) == e - s
    if kept:
        assert sorted(out) == list(range(e - s))
        assert all(x.q[0] >= 100.0 and x.fit == mirror_fit for x in out.values())
        assert note is not None and f"frames {s}-{e - 1}" in note and f"{mirror_fit:.4f} against 0.8000" in note
    else:
        assert out is chosen and note is None


@pytest.mark.parametrize("angles, enabled, with_rig, called",
                         [({"cam1": 81.0, "cam2": 3.0}, True, True, True), ({"cam1": 81.0, "cam2": 40.0}, True, True,
                          False), ({"cam1": 81.0, "cam2": 3.0}, False, True, False),
                          ({"cam1": 81.0, "cam2": 3.0}, True, False, False)])  # fmt: skip
def test_a_run_no_camera_views_obliquely_is_tracked_from_its_mirror(monkeypatch, angles, enabled, with_rig, called):
    """backward.mirror_run's gate: only a run whose cameras are all beside or in line with its
    walking line (quality.no_oblique_view of the merged points' view angles), only with the key on
    and the cameras known; what _mirror_run returns is what is written."""
    from gaitcap import pipeline
    from gaitcap.tracking.base import Estimate

    T, P = 6, 4
    cfg = load_tracking_config()
    cfg.backward.average = False  # the merge's decisions alone (the mean of agreeing frames: its own test)
    cfg.backward.mirror_run = enabled
    monkeypatch.setattr(pipeline, "legs_in_doubt", lambda points, names, rate, vcfg: 0)
    monkeypatch.setattr(pipeline, "_merge_run", lambda *a: {})
    monkeypatch.setattr(pipeline, "view_angles", lambda points, names, rig: angles)
    calls = []

    def mirror_run(tracker, spool, raw, poses, fit, chosen, s, e, cfg_, rate_hz):
        calls.append((s, e))
        return {1: Estimate(np.full(3, 7.0), np.zeros((P, 3)), np.zeros(P), 0.0, 0.9, 1)}, "kept"

    monkeypatch.setattr(pipeline, "_mirror_run", mirror_run)
    writer = _FakeWriter(T, P)
    spool = type("Spool", (), {"read": lambda self, t: [np.zeros((2, 2), np.float32)]})()
    rig = object() if with_rig else None
    notes = []
    pipeline._backward_pass(_FakeTracker(P), spool, writer, cfg, 25.0, None, rig=rig, notes=notes)
    assert calls == ([(0, T)] if called else [])
    assert notes == (["kept"] if called else [])
    assert sorted(writer.replaced) == ([1] if called else [])
    if called:
        np.testing.assert_array_equal(writer.replaced[1], np.full(3, 7.0))


def test_exchanged_legs_finds_the_frames_whose_legs_are_the_other_way_round():
    """A run against another: the frames whose leg points lie nearer the other's with left and right
    exchanged; the hips and arms are not compared; a NaN frame is not exchanged."""
    from gaitcap.tracking.backward import exchanged_legs

    names = ("pelvis", "hip_l", "hip_r", "knee_l", "knee_r", "ankle_l", "ankle_r", "toe_l", "toe_r")
    rng = np.random.default_rng(3)
    b = rng.normal(0.0, 0.3, (10, len(names), 3))
    a = b + rng.normal(0.0, 0.005, b.shape)
    swap = [0, 1, 2, 4, 3, 6, 5, 8, 7]  # the legs below the hips exchanged
    a[4:8] = b[4:8][:, swap] + rng.normal(0.0, 0.005, (4, len(names), 3))
    a[8, 1:3] += 5.0  # the hips far off: not a leg point
    a[9, 3] = np.nan
    out = exchanged_legs(a, b, names)
    assert out.dtype == bool and out.shape == (10,)
    np.testing.assert_array_equal(out, [False] * 4 + [True] * 4 + [False] * 2)


def _up_and_back(lead: np.ndarray, T1: int, pause: int) -> np.ndarray:
    """Points (T, 3, 3) of NAMES: T1 frames walking along +x at 1.2 m/s, ``pause`` frames standing
    (feet side by side), then walking back along -x; ``lead`` (T,) the left ankle's lead in the
    direction walked (ignored in the pause)."""
    T = len(lead)
    v = np.r_[np.full(T1, 1.2), np.zeros(pause), np.full(T - T1 - pause, -1.2)]
    x = np.r_[0.0, np.cumsum(v[:-1])] / RATE
    forward = np.sign(v)  # +1, 0, -1: the way walked along x
    pts = np.zeros((T, 3, 3))
    pts[:, 0, 0] = x
    pts[:, 1, 0], pts[:, 1, 1] = x + forward * lead / 2, 0.1
    pts[:, 2, 0], pts[:, 2, 1] = x - forward * lead / 2, -0.1
    return pts


def test_the_leading_leg_is_ordered_pass_by_pass() -> None:
    """Up the room, a pause, and back: along one line for the whole run the left ankle's lead changes
    sign with the walking direction, so one alternation over the run puts one pass's parity wrong.
    Pass by pass (``pipeline._passes``: cut at the turn), a stretch the forward pass exchanged on the
    way up takes the backward pass, which leads as it must; one both passes exchanged on the way back
    is tracked again (on the run's own frames); no other frame changes."""
    from gaitcap import pipeline

    T1, pause, T2 = 70, 40, 110  # the pass back the longer: it outvotes the pass up over the whole run
    T = T1 + pause + T2
    lead = np.r_[_lead(T1), np.zeros(pause), _lead(T2, phase=0.3 + np.pi)]
    truth = _up_and_back(lead, T1, pause)
    a, b, _ = alternating_stretches(lead[:T1], lead[:T1], lead[:T1], RATE, 0.1, 0.03)[2]
    c, d, _ = alternating_stretches(lead[-T2:], lead[-T2:], lead[-T2:], RATE, 0.1, 0.03)[3]
    c, d = c + T - T2, d + T - T2
    wrong = lead.copy()
    wrong[a:b] *= -1  # the forward pass exchanged the legs over a stretch on the way up ...
    wrong[c:d] *= -1  # ... and over one on the way back, where the backward pass did so too
    forward = _up_and_back(wrong, T1, pause)
    back = [_Est(np.full(2, 2.0), p, 0.80) for p in _up_and_back(np.where(np.arange(T) < T1, lead, wrong), T1, pause)]
    calls = []

    class Tracker:
        class model:
            point_names = NAMES

        @staticmethod
        def mirrored(q):
            return -q

    def again(q0, i, j, backwards):  # a stretch tracked again: the truth, on the run's frames i..j-1
        calls.append((i, j))
        return [_Est(np.full(2, 3.0), p, 0.80) for p in truth[i:j]]

    def refine(q0, t):  # a frame searched again fits far worse: never taken
        return _Est(np.full(2, 4.0), forward[t], 0.5)

    cfg = load_tracking_config()
    (s1, e1, lines1), (s2, e2, lines2) = pipeline._passes(forward, NAMES, RATE)
    assert s1 == 0 and T1 <= e1 == s2 <= T1 + pause and e2 == T  # cut at the turn, the pause kept
    assert lines1 is None and lines2 is None  # straight passes: one walking line each
    fit, poses = np.full(T, 0.80), np.ones((T, 2))
    for by_pass in (False, True):
        chosen: dict = {}
        calls.clear()
        spans = pipeline._passes(forward, NAMES, RATE) if by_pass else [(0, T, None)]
        for s, e, lines in spans:
            pipeline._order_pass(chosen, s, e, lines, forward, fit, poses, back, Tracker, RATE, again, refine, cfg)
        if by_pass:
            assert sorted(chosen) == [*range(a, b), *range(c, d)]
            assert all(chosen[t] is back[t] for t in range(a, b))  # the backward pass
            assert all(chosen[t].q[0] == 3.0 for t in range(c, d))  # tracked again, on the run's frames
            # (and so are short stretches of the pause, where no ankle leads: not taken)
            assert (c, d) in calls and all(T1 <= i < j <= T1 + pause for i, j in set(calls) - {(c, d)})
            np.testing.assert_array_equal([chosen[t].points for t in range(c, d)], truth[c:d])
        else:
            assert not set(range(a, b)) <= set(chosen)  # one alternation over the run: left exchanged


def _round(lead: np.ndarray, straight: int, radius: float = 0.75) -> tuple[np.ndarray, np.ndarray]:
    """Points (T, 3, 3) of NAMES walking ``straight`` frames along +x at 1.2 m/s, then round a circle
    of ``radius`` metres to the left, the left ankle leading by ``lead`` (T,) along the way walked;
    and each frame's walking direction (T, 2)."""
    T = len(lead)
    s = 1.2 * np.arange(T) / RATE
    bend = np.clip((s - s[straight]) / radius, 0.0, None)
    c, n = np.cos(bend), np.sin(bend)
    pelvis = np.stack([np.minimum(s, s[straight]) + radius * n, radius * (1 - c)], axis=1)
    heading = np.stack([c, n], axis=1)
    left = np.stack([-n, c], axis=1)
    pts = np.zeros((T, 3, 3))
    pts[:, 0, :2] = pelvis
    pts[:, 1, :2] = pelvis + heading * lead[:, None] / 2 + 0.1 * left
    pts[:, 2, :2] = pelvis - heading * lead[:, None] / 2 - 0.1 * left
    return pts, heading


def test_order_legs_reads_the_order_along_each_frame_s_direction_on_a_turn_walked_round() -> None:
    """Walking round a quarter circle, the order along one line for the pass says nothing on the
    circle (the lead turns across it); along each frame's own direction (``lines``) a stretch the
    forward pass exchanged there takes the backward pass, which leads as it must."""
    straight, T = 50, 80
    lead = _lead(T)
    truth, heading = _round(lead, straight)
    a, b, _ = alternating_stretches(lead, lead, lead, RATE, 0.1, 0.03)[-2]
    assert a > straight + 10  # on the circle, over 25 degrees round
    wrong = lead.copy()
    wrong[a:b] *= -1
    forward, _ = _round(wrong, straight)
    back = [_Est(np.full(2, 2.0), p, 0.80) for p in truth]
    cfg = load_tracking_config().backward

    def again(q0, i, j, backwards):  # tracked again: the forward pass's legs, no help
        return [_Est(np.full(2, 3.0), p, 0.80) for p in forward[i:j]]

    for lines in (None, heading):
        chosen: dict = {}
        order_legs(chosen, forward, np.full(T, 0.80), np.ones((T, 2)), back, NAMES, RATE, again, lambda q: -q, cfg,
                   0.03, None, lines)  # fmt: skip
        if lines is None:
            assert not set(range(a, b)) <= set(chosen)  # one line: left exchanged
        else:
            assert sorted(chosen) == list(range(a, b)) and all(chosen[t] is back[t] for t in chosen)
