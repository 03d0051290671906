"""The legs' gap (gaitcap.tracking.contact) and the posture prior built on it (Tracker.log_prior)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from gaitcap.config import default_config_path
from gaitcap.errors import ConfigError
from gaitcap.io.calibration_toml import read_calibration
from gaitcap.tracking.base import Tracker
from gaitcap.tracking.config import load_tracking_config
from gaitcap.tracking.contact import LEG_POINTS, leg_gap, segment_distances
from gaitcap.tracking.likelihood import SilhouetteLikelihood
from gaitcap.tracking.observation import tracking_views


def _dense_distance(p0, p1, q0, q1, n: int = 301) -> float:
    """The smallest distance between n points along each segment: an upper bound within the step."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    P, Q = p0 + (p1 - p0) * s, q0 + (q1 - q0) * s
    return float(np.linalg.norm(P[:, None] - Q[None], axis=-1).min())


def test_segment_distances_match_a_dense_search():
    rng = np.random.default_rng(3)
    p0, p1, q0, q1 = (rng.normal(size=(400, 3)) for _ in range(4))
    p1[:40] = p0[:40]  # a point against a segment
    q1[40:80] = q0[40:80]  # a segment against a point
    p1[80:100], q1[80:100] = p0[80:100], q0[80:100]  # two points
    q1[100:140] = q0[100:140] + 0.7 * (p1[100:140] - p0[100:140])  # parallel segments
    q0[140:160], q1[140:160] = p0[140:160] + 2.0 * (p1[140:160] - p0[140:160]), p0[140:160] + 3.0 * (p1[140:160] - p0[140:160])  # collinear, apart
    got = segment_distances(p0, p1, q0, q1)
    dense = np.array([_dense_distance(*(a[i] for a in (p0, p1, q0, q1))) for i in range(len(p0))])
    step = np.maximum(np.linalg.norm(p1 - p0, axis=1), np.linalg.norm(q1 - q0, axis=1)) / 300
    assert np.all(got <= dense + 1e-12)  # never more than a distance actually found
    assert np.all(got >= dense - step)  # and the dense search cannot beat it by more than its step
    assert np.allclose(got, segment_distances(q0, q1, p0, p1))  # symmetric
    assert np.allclose(got[140:160], np.linalg.norm(q0[140:160] - p1[140:160], axis=1))  # end to end
    # two segments crossing at their midpoints
    assert segment_distances(np.array([[-1.0, 0, 0]]), np.array([[1.0, 0, 0]]), np.array([[0, -1.0, 0]]),
                             np.array([[0, 1.0, 0]]))[0] == pytest.approx(0.0, abs=1e-12)  # fmt: skip


def test_leg_gap_is_the_closest_pair_of_leg_segments():
    rng = np.random.default_rng(5)
    legs = rng.normal(size=(50, 6, 3))
    hip_l, knee_l, ankle_l, hip_r, knee_r, ankle_r = (legs[:, k] for k in range(6))
    pairs = [(hip_l, knee_l, hip_r, knee_r), (knee_l, ankle_l, knee_r, ankle_r), (knee_l, ankle_l, hip_r, knee_r),
             (hip_l, knee_l, knee_r, ankle_r)]  # fmt: skip
    assert np.allclose(leg_gap(legs), np.min([segment_distances(*p) for p in pairs], axis=0))
    assert np.allclose(leg_gap(legs), leg_gap(legs[:, [3, 4, 5, 0, 1, 2]]))  # left and right alike


@pytest.fixture(scope="module")
def walk(embedded_session):
    """The embedded walk's truth (the tracker's model fitted to its markers) and a tracker for its rig."""
    rig = read_calibration(embedded_session.session / "calibration.toml")
    views = tracking_views(rig, 0.5)
    model = embedded_session.fit.model
    cfg = load_tracking_config(model=model)
    return embedded_session, model, cfg, SilhouetteLikelihood(views, cfg.beta)


def test_the_walk_never_meets_the_gap_prior(walk):
    """The shipped floor lies below every gap of a real walk: the prior costs a walking pose nothing."""
    synth, model, cfg, lik = walk
    tracker = Tracker(model, lik, cfg, np.random.default_rng(0))
    points = synth.fit.points[:, [model.point_index(p) for p in LEG_POINTS]]
    gap = leg_gap(points) / model.height_m
    assert gap.min() > cfg.leg_gap.min
    assert np.all(tracker.log_leg_gap(synth.fit.poses) == 0.0)


def test_the_gap_prior_penalises_legs_drawn_over_each_other(walk):
    synth, model, cfg, lik = walk
    tracker = Tracker(model, lik, cfg, np.random.default_rng(0))
    q = synth.fit.poses[10]
    # the left leg swung inwards step by step until it lies over the right one
    add = model.dof_index("hip_adduction_l")
    Q = np.repeat(q[None], 30, axis=0)
    Q[:, add] = q[add] + np.radians(np.linspace(0.0, 25.0, 30))
    gap = leg_gap(model.forward(Q)[:, [model.point_index(p) for p in LEG_POINTS]])
    floor, sigma = cfg.leg_gap.min * model.height_m, cfg.leg_gap.sigma * model.height_m
    assert gap[0] > floor and gap.min() < 0.5 * floor  # the sweep crosses the floor
    expected = -0.5 * (np.maximum(floor - gap, 0.0) / sigma) ** 2
    assert np.allclose(tracker.log_leg_gap(Q), expected)
    closer = np.diff(gap) < 0
    assert np.all(np.diff(tracker.log_leg_gap(Q))[closer] <= 1e-12)  # never cheaper as the legs close in
    # part of log_prior where the DOF searched move a leg's axis (hips, knees), not where they do not
    legs_dofs = np.array([add])
    unmoved = np.array([model.dof_index("elbow_flexion_l"), model.dof_index("ankle_dorsiflexion_r")])  # no leg axis
    without = load_tracking_config(model=model)
    without.leg_gap.min = 0.0
    plain = Tracker(model, lik, without, np.random.default_rng(0))
    assert np.allclose(tracker.log_prior(Q, legs_dofs), plain.log_prior(Q, legs_dofs) + expected)
    assert np.allclose(tracker.log_prior(Q), plain.log_prior(Q) + expected)
    assert np.array_equal(tracker.log_prior(Q, unmoved), plain.log_prior(Q, unmoved))


@pytest.mark.parametrize(("key", "value"), [("sigma", 0.0), ("min", -0.01), ("minimum", 0.03)])
def test_the_gap_prior_config_is_checked(tmp_path, key, value):
    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["leg_gap"][key] = value
    path = tmp_path / "tracking.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=rf"leg_gap\.{key}"):
        load_tracking_config(path)
