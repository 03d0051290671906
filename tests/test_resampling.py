from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitcap.tracking.resampling import SCHEMES, ess, normalise_log_weights, resampler


@pytest.mark.parametrize("name", sorted(SCHEMES))
def test_expected_copies_equal_n_times_weight(name):
    """E[copies of n] = M W_n: the mean over many draws converges to it."""
    rng = np.random.default_rng(7)
    W = rng.dirichlet(np.full(20, 0.5))
    M, runs = 200, 2000
    counts = np.zeros(20)
    for _ in range(runs):
        counts += np.bincount(resampler(name)(W, M, rng), minlength=20)
    mean = counts / runs
    # standard error of the mean copies is below sqrt(M W (1 - W) / runs)
    tol = 5 * np.sqrt(M * W * (1 - W) / runs) + 1e-9
    assert np.all(np.abs(mean - M * W) <= tol)


@pytest.mark.parametrize("name", ["systematic", "stratified", "residual"])
def test_low_variance_schemes_stay_within_one_copy(name):
    rng = np.random.default_rng(3)
    W = rng.dirichlet(np.ones(50))
    copies = np.bincount(resampler(name)(W, 500, rng), minlength=50)
    assert np.all(np.abs(copies - 500 * W) < 1 + 1e-9) if name == "systematic" else np.all(copies >= np.floor(500 * W) - (name != "residual"))


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-50, 50, allow_nan=False), min_size=1, max_size=40))
def test_normalised_weights_sum_to_one_and_ess_is_bounded(logw):
    W = normalise_log_weights(np.asarray(logw))
    assert W.sum() == pytest.approx(1.0)
    assert np.all(W >= 0)
    assert 1.0 - 1e-9 <= ess(W) <= len(W) + 1e-9


def test_non_finite_log_weights_get_zero_weight():
    W = normalise_log_weights(np.array([0.0, -np.inf, np.nan, 1.0]))
    assert W[1] == 0 and W[2] == 0 and W.sum() == pytest.approx(1.0)


def test_unknown_scheme_is_named():
    with pytest.raises(ValueError, match="unknown resampling scheme 'magic'"):
        resampler("magic")
