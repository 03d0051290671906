"""The backward pass: the choice between the two passes, the frame spool, the writer's overwrite."""

from __future__ import annotations

import numpy as np
import pytest

from gaitcap.errors import ConfigError
from gaitcap.io.spool import FrameSpool
from gaitcap.io.track_h5 import QUALITY_OK, TrackWriter
from gaitcap.tracking.backward import choose_backward, leg_points
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
    bad.write_text("backward:\n  enable: false\n")
    with pytest.raises(ConfigError, match="enable"):
        load_tracking_config(bad)
