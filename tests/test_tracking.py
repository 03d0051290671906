from __future__ import annotations

import csv
import json
import logging
import pickle
import re
import shutil
import time

import h5py
import numpy as np
import pytest
import yaml
from quick_config import quick_tracking

from gaitcap.body.measures import model_lengths
from gaitcap.body.model import load_body_model
from gaitcap.errors import ConfigError, OutputError, TrackingError
from gaitcap.io.calibration_toml import read_calibration, write_calibration
from gaitcap.io.silhouettes_h5 import read_masks
from gaitcap.io.trajectories_h5 import read_trajectory
from gaitcap.markers.motion import read_markers
from gaitcap.pipeline import Stages, run_track
from gaitcap.synth.truth import read_truth
from gaitcap.tracking.chain import subtrees
from gaitcap.tracking.config import load_tracking_config
from gaitcap.tracking.likelihood import SilhouetteLikelihood
from gaitcap.tracking.observation import observe, tracking_views
from gaitcap.tracking.projector import PoseProjector
from gaitcap.trajectory import LOWER_LIMB, POINT_NAMES
from gaitcap.config import default_config_path
from model_truth import model_truth_setup


def _truth_setup(session):
    """Truth poses with masks drawn by the fitted tracker model (mechanism tests; see model_truth)."""
    return model_truth_setup(session)


def test_likelihood_prefers_the_true_pose(embedded_session, rng):
    truth, rig, model = _truth_setup(embedded_session.session)
    views = tracking_views(rig, 0.5)
    lik = SilhouetteLikelihood(views, beta=40.0)
    for frame in (5, 30, 50):
        obs = observe(views, [truth.mask(c, frame) for c in rig.names])
        q = truth.poses[frame]
        Q = np.repeat(q[None], 300, axis=0)
        Q[:, 6:] += rng.normal(0, np.radians(8), size=(300, 25))
        Q[:, :2] += rng.normal(0, 0.03, size=(300, 2))
        A, B, r = model.capsules(np.vstack([q[None], Q]))
        ll = lik.score(obs, lik.projected(A, B, r))
        assert np.all(ll[0] > ll[1:]), f"frame {frame}: {np.sum(ll[1:] >= ll[0])} perturbed poses score as well"
        fit = lik.fit_of(obs, lik.projected(A[:1], B[:1], r))[0]
        assert fit > 0.9


def test_end_to_end_tracking_accuracy(tracked_session):
    synth, out, summary = tracked_session
    assert summary.status == "ok" and summary.n_frames == 20
    traj = read_trajectory(out / "trajectories.h5")
    truth = read_truth(synth.session / "truth.h5").trajectory
    idx = [traj.index(p) for p in LOWER_LIMB]
    tidx = [truth.index(p) for p in LOWER_LIMB]
    err = np.linalg.norm(traj.points[:, idx] - truth.points[:20, tidx], axis=2)
    assert np.isfinite(err).all()
    assert 1000 * err.mean() < 80.0, f"lower-limb MPJPE {1000 * err.mean():.1f} mm"


def test_trajectories_h5_layout(tracked_session):
    _, out, _ = tracked_session
    with h5py.File(out / "trajectories.h5") as f:
        assert f["points"].shape == (20, 20, 3)
        assert list(f["points"].attrs["names"]) == list(POINT_NAMES)
        assert f["points"].attrs["rate_hz"] == 25.0
        assert f["poses"].shape == (20, 31) and len(f["poses"].attrs["dof_names"]) == 31
        units = dict(zip(f["poses"].attrs["dof_names"], f["poses"].attrs["dof_units"], strict=True))
        assert [n for n, u in units.items() if u == "m"] == ["pelvis_tx", "pelvis_ty", "pelvis_tz"]
        assert units["knee_flexion_l"] == "rad" and set(units.values()) == {"m", "rad"}
        for key in ("uncertainty", "spread", "quality", "likelihood", "fit", "times", "points_unfiltered"):
            assert f[key].shape[0] == 20, key
        for key in ("points", "points_unfiltered", "uncertainty", "spread"):
            assert f[key].attrs["units"] == "m", key
        assert f["times"].attrs["units"] == "s"
        assert f["quality"].attrs["codes"] == "0 ok, 1 poor_fit, 2 out_of_view, 3 not_initialised"
        unc, spread = f["uncertainty"][()], f["spread"][()]
        assert np.all(np.isfinite(unc)) and np.all(unc > 0) and unc.shape == spread.shape == (20, 20)
        assert np.all(np.isfinite(spread)) and np.all(spread >= 0) and not np.allclose(unc, spread)
        cfg = yaml.safe_load(f.attrs["config"])
        assert cfg["tracker"] == "factored-ipf"
        assert f.attrs["height_source"] == "session.yaml"
        assert "Butterworth" in f.attrs["filter"]
        assert f.attrs["gaitcap_version"]


def test_joints_csv_layout(tracked_session):
    _, out, _ = tracked_session
    rows = list(csv.reader((out / "joints.csv").open()))
    header = rows[0]
    assert header[:2] == ["frame", "time_s"]
    assert header[2:5] == ["pelvis_x", "pelvis_y", "pelvis_z"]
    assert len(header) == 2 + 3 * 20 and len(rows) == 21
    assert float(rows[2][1]) == pytest.approx(0.04)


def test_joints_trc_follows_opensim_rules(tracked_session):
    _, out, _ = tracked_session
    lines = (out / "joints.trc").read_text().splitlines()
    assert lines[0].split("\t")[:2] == ["PathFileType", "4"]
    keys = lines[1].split("\t")
    values = dict(zip(keys, lines[2].split("\t")))
    assert keys == ["DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units", "OrigDataRate",
                    "OrigDataStartFrame", "OrigNumFrames"]
    assert values["Units"] == "mm" and int(values["NumFrames"]) == 20 and int(values["NumMarkers"]) == 20
    assert lines[3].split("\t")[:3] == ["Frame#", "Time", "pelvis"]
    back = read_markers(out / "joints.trc", up_axis="y")
    traj = read_trajectory(out / "trajectories.h5")
    np.testing.assert_allclose(back.points, traj.points, atol=2e-5)


def test_finished_output_is_not_redone_without_force(tracked_session):
    synth, out, _ = tracked_session
    with pytest.raises(OutputError, match="finished run"):
        run_track(synth.session, out, progress=False, max_frames=2)


def test_tracking_config_rejects_unknown_keys(tmp_path):
    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["factored_ipf"]["particels"] = 10
    path = tmp_path / "tracking.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"factored_ipf\.particels: unknown key \(did you mean 'particles'\?\)"):
        load_tracking_config(path)


def test_a_config_file_of_a_few_keys_is_told_to_start_from_the_shipped_one(tmp_path):
    partial = tmp_path / "mine.yaml"
    partial.write_text("seed: 1\n")
    with pytest.raises(ConfigError, match=r"mine.yaml: factored_ipf: Field required") as e:
        load_tracking_config(partial)
    assert "mine.yaml: a configuration file replaces the shipped one whole" in str(e.value)
    assert f"start from a copy of {default_config_path('tracking.yaml')}" in str(e.value)


def test_a_config_leaving_out_keys_the_shipped_file_sets_otherwise_is_warned_about(tmp_path, caplog):
    """A key left out takes the schema's default: where that is not the shipped value (the particle budget,
    the shape calibration on, the priors), the run would differ from the shipped one without a word."""
    import logging

    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    full = tmp_path / "full.yaml"
    full.write_text(yaml.safe_dump(data))
    shipped = data["factored_ipf"]["particles"]
    del data["factored_ipf"]["particles"], data["shape"]["enabled"], data["prior"], data["smoothing"]["order"]
    mine = tmp_path / "mine.yaml"
    mine.write_text(yaml.safe_dump(data))
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        load_tracking_config(full)
        assert "leaves out" not in caplog.text
        cfg = load_tracking_config(mine)
    assert cfg.factored_ipf.particles != shipped and not cfg.shape.enabled
    line = caplog.text
    assert "mine.yaml leaves out prior, factored_ipf.particles, shape.enabled, which the shipped tracking.yaml" in line
    assert f"factored_ipf.particles: default {cfg.factored_ipf.particles}, shipped {shipped}" in line
    assert "smoothing.order" not in line  # its default is the shipped value
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        load_tracking_config(mine)  # read again (a batch's next session): said once
    assert "leaves out" not in caplog.text


def test_shape_refit_budget_below_two_particles_is_rejected(tmp_path):
    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["shape"]["refit_particles"] = [60, 1]
    path = tmp_path / "tracking.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"shape\.refit_particles: .*at least 2"):
        load_tracking_config(path)


@pytest.mark.parametrize("target", ["thigh_l", "thigh_l.w", "1/thigh_l.z^2", "thigh_l.z^", "thigh_l.z^x"])
def test_shape_target_syntax_is_checked(tmp_path, target):
    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["shape"]["parameters"]["leg"] = ["thigh_r.z", target]
    path = tmp_path / "tracking.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=rf"shape\.parameters: .*leg: '{re.escape(target)}' is not 'segment\.axis'"):
        load_tracking_config(path)


def test_shape_targets_scale_by_a_power_of_the_factor():
    from gaitcap.tracking.shape import scaled_model

    model = load_body_model()
    targets = {"ankle": ["foot_l.z", "shank_l.z^-0.16", "1/torso.y"]}
    out = scaled_model(model, targets, {"ankle": 1.25})
    np.testing.assert_allclose(out.scales["foot_l"], model.scales["foot_l"] * [1, 1, 1.25])
    np.testing.assert_allclose(out.scales["shank_l"], model.scales["shank_l"] * [1, 1, 1.25**-0.16])
    np.testing.assert_allclose(out.scales["torso"], model.scales["torso"] * [1, 1 / 1.25, 1])
    np.testing.assert_array_equal(out.scales["foot_r"], model.scales["foot_r"])
    # the compensating power keeps the knee at its height: shank 0.246 H shortened by what the
    # ankle (0.039 H) gains, to first order
    H = model.height_m
    gain = 0.039 * H * 0.25
    assert 0.246 * H * (1 - 1.25**-0.16) == pytest.approx(gain, rel=0.15)


def test_neck_height_moves_the_shoulders_under_a_still_head_top():
    """The shipped ``neck_height`` parameter scales the trunk by f and the head by a compensating
    power of f: the neck and the shoulders move, the top of the head (the silhouettes' top) stays
    where it was, to first order. Without it, a trunk too long could only shorten with the head
    top sinking, and the coordinate search kept it long and sank the hips instead."""
    from gaitcap.tracking.shape import scaled_model

    model = load_body_model(height_m=1.8)
    parameters = load_tracking_config().shape.parameters
    q = np.zeros(model.n_dofs)
    q[model.dof_index("pelvis_tz")] = 1.0  # the pelvis, hence the lumbar joint, held in place

    def heights(m):
        pts = m.forward(q[None])[0]
        A, B, radii = m.capsules(q[None])
        top = max((A[0, :, 2] + radii[:, 0]).max(), (B[0, :, 2] + radii[:, 1]).max())
        return pts[m.point_index("neck"), 2], pts[m.point_index("shoulder_l"), 2], top

    neck0, shoulder0, top0 = heights(model)
    neck, shoulder, top = heights(scaled_model(model, parameters, {"neck_height": 0.92}))
    assert neck0 - neck > 0.014 and shoulder0 - shoulder > 0.012  # 8 % of 0.19 and 0.165 x 1.8 / 1.75 m
    assert abs(top - top0) < 0.15 * (neck0 - neck)


def test_a_girth_parameter_thickens_the_legs_and_moves_no_joint():
    """A shape parameter on the legs' cross-section axes (x and y of the thighs and shanks, the
    ``leg_girth`` of docs/validation.md) scales their capsule radii by f and nothing else: every
    joint centre and every other capsule stays (BodyModel scales a capsule's thickness by its
    segment's factors across the capsule's axis)."""
    from gaitcap.tracking.shape import scaled_model

    model = load_body_model(height_m=1.7)
    girth = {"leg_girth": [f"{seg}.{axis}" for seg in ("thigh_l", "thigh_r", "shank_l", "shank_r") for axis in "xy"]}
    wider = scaled_model(model, girth, {"leg_girth": 1.15})
    rng = np.random.default_rng(3)
    poses = model.clip(model.neutral_pose()[None] + rng.normal(0.0, 0.2, (4, model.n_dofs)))
    np.testing.assert_allclose(wider.forward(poses), model.forward(poses), atol=1e-12)
    A0, B0, r0 = model.capsules(poses)
    A1, B1, r1 = wider.capsules(poses)
    np.testing.assert_allclose(A1, A0, atol=1e-12)
    np.testing.assert_allclose(B1, B0, atol=1e-12)
    legs = np.isin([model.segments[s].name for s in model.capsule_segment],
                   ["thigh_l", "thigh_r", "shank_l", "shank_r"])  # fmt: skip
    assert legs.sum() >= 4
    np.testing.assert_allclose(r1[legs], 1.15 * r0[legs], rtol=1e-12)
    np.testing.assert_array_equal(r1[~legs], r0[~legs])


def test_planted_poses_keep_the_lowest_point_on_the_floor():
    from gaitcap.tracking.shape import lowest_points, planted_poses, scaled_model

    model = load_body_model()
    rng = np.random.default_rng(4)
    poses = [model.clip(model.neutral_pose()[None] + rng.normal(0.0, 0.15, (1, model.n_dofs)))[0] for _ in range(5)]
    longer = scaled_model(model, {"legs": ["thigh_l.z", "thigh_r.z", "shank_l.z", "shank_r.z"]}, {"legs": 1.1})
    moved = planted_poses(model, longer, poses)
    np.testing.assert_allclose(lowest_points(longer, np.array(moved)), lowest_points(model, np.array(poses)),
                               atol=1e-12)  # fmt: skip
    tz = model.dof_index("pelvis_tz")
    for q, m in zip(poses, moved):
        assert m[tz] > q[tz]  # longer legs: the hips go up
        np.testing.assert_array_equal(np.delete(m, tz), np.delete(q, tz))  # nothing else moves
    # the same model: no move
    same = planted_poses(model, model, poses)
    np.testing.assert_allclose(np.array(same), np.array(poses), atol=1e-12)


def test_averaged_shapes_are_the_geometric_mean_with_the_first_start_planted():
    """Several calibrations averaged: each factor is the geometric mean of theirs (x0.9 and x1.2 ->
    x1.039), the model scaled by it, the fits the means, and the first calibration's start moved
    vertically so that the averaged model's lowest point is where the first model's was."""
    from gaitcap.tracking.shape import ShapeResult, average_shapes, lowest_points, scaled_model

    model = load_body_model()
    parameters = {"legs": ["thigh_l.z", "thigh_r.z", "shank_l.z", "shank_r.z"], "arms": ["upper_arm_l.z"]}
    start = model.neutral_pose()
    results = [ShapeResult(scaled_model(model, parameters, f), start, f, fb, fa)
               for f, fb, fa in [({"legs": 0.9, "arms": 1.0}, 0.80, 0.85), ({"legs": 1.2, "arms": 1.0}, 0.82, 0.89)]]
    avg = average_shapes(model, parameters, results)
    assert avg.factors["legs"] == pytest.approx((0.9 * 1.2) ** 0.5) and avg.factors["arms"] == pytest.approx(1.0)
    assert avg.model.scales["thigh_l"][2] == pytest.approx(model.scales["thigh_l"][2] * (0.9 * 1.2) ** 0.5)
    assert (avg.fit_before, avg.fit_after) == (pytest.approx(0.81), pytest.approx(0.87))
    assert lowest_points(avg.model, avg.start[None])[0] == pytest.approx(lowest_points(results[0].model, start[None])[0])
    assert avg.start[model.dof_index("pelvis_tz")] > start[model.dof_index("pelvis_tz")]  # longer legs than the first


def test_every_dof_has_an_interval():
    cfg = load_tracking_config()
    model = load_body_model()
    widths = cfg.half_widths(model)
    assert widths.shape == (31,) and np.all(widths > 0)
    assert cfg.order_indices(model)[0] == model.segment("pelvis").index


def test_compiled_projection_equals_the_numpy_model(embedded_session, rng):
    truth, rig, model = _truth_setup(embedded_session.session)
    views = tracking_views(rig, 0.5)
    lik = SilhouetteLikelihood(views, beta=40.0)
    Q = model.clip(truth.poses[10] + rng.normal(0, 0.3, size=(50, 31)))
    proj = PoseProjector(model, views).capsules(Q)
    A, B, r = model.capsules(Q)
    ref = lik.projected(A, B, r)
    for got, want in zip((proj.a, proj.b, proj.ra, proj.rb), (ref.a, ref.b, ref.ra, ref.rb)):
        assert got.shape == want.shape
        assert np.allclose(got, want, atol=1e-9)
    caps = np.array([3, 0, 7])
    assert np.allclose(PoseProjector(model, views).capsules(Q, caps).a, ref.a[:, :, caps], atol=1e-9)
    assert np.allclose(PoseProjector(model, views).points(Q), model.forward(Q), atol=1e-12)


def test_capsules_and_points_from_one_pass_equal_each_alone(embedded_session, rng):
    """``capsules_and_points`` (one pass of the kinematics, as a leg node with the legs' gap prior asks
    for it) gives, bit for bit, what ``capsules`` and ``points`` give alone, also where the points'
    segments are not among the capsules' (a left leg's capsules, the right leg's points)."""
    truth, rig, model = _truth_setup(embedded_session.session)
    projector = PoseProjector(model, tracking_views(rig, 0.5))
    Q = model.clip(truth.poses[10] + rng.normal(0, 0.3, size=(20, 31)))
    left = model.segment("thigh_l").index, model.segment("shank_l").index
    caps = np.flatnonzero(np.isin(model.capsule_segment, left))
    pts = np.array([model.point_index(p) for p in ("hip_r", "knee_r", "ankle_r", "knee_l")])
    proj, points = projector.capsules_and_points(Q, caps, pts)
    alone = projector.capsules(Q, caps)
    for got, want in zip((proj.a, proj.b, proj.ra, proj.rb), (alone.a, alone.b, alone.ra, alone.rb)):
        assert got.shape == want.shape and np.array_equal(got, want)
    assert points.shape == (20, 4, 3) and np.array_equal(points, projector.points(Q, pts))
    assert np.allclose(points, model.forward(Q)[:, pts], atol=1e-12)


def test_layer_kernels_equal_the_likelihood_and_prior_they_stand_for(embedded_session, rng):
    """The factored filter's compiled layer steps give, bit for bit, what the numpy expressions they
    replace give: the particles moved, clipped (pelvis heading wrapped) and made into poses; the
    log-weights = SilhouetteLikelihood.score + Tracker.log_prior, with and without the legs' gap, for
    every node's DOF and for the root moving alone (its DOF and the held ones)."""
    from gaitcap.tracking.factored_ipf import FactoredIPF
    from gaitcap.tracking.particles import layer_log_weights, layer_poses

    truth, rig, model = _truth_setup(embedded_session.session)
    views = tracking_views(rig, 0.5)
    lik = SilhouetteLikelihood(views, beta=40.0)
    tracker = FactoredIPF(model, lik, load_tracking_config(model=model), np.random.default_rng(0))
    obs = observe(views, [truth.mask(c, 20) for c in rig.names])
    areas = np.maximum(obs.areas, 1.0)
    selections = [tracker._explored[s] for s in tracker.order]
    selections.append(np.union1d(tracker._explored[tracker._root], tracker._held))
    gaps = 0
    for idx in selections:
        n, k = 60, len(idx)
        q = truth.poses[20] + rng.normal(0, 0.05, model.n_dofs)
        X = q[idx] + rng.normal(0, 1.5, (n, k))  # far enough to leave the limits and wrap the heading
        K = rng.integers(-4, 5, (n, k))
        step = rng.uniform(0.01, 0.2, k)
        best = X[5].copy()
        want = X + K * step
        want[0] = best
        want = model.clip(want, idx)
        want_Q = np.repeat(model.clip(q[None]), n, axis=0)
        want_Q[:, idx] = want
        got, Q = layer_poses(X, K, step, best, idx, model.wrap[idx], model.lower[idx], model.upper[idx],
                             model.clip(q[None])[0])  # fmt: skip
        assert np.array_equal(got, want) and np.array_equal(Q, want_Q)
        caps = np.arange(len(model.capsule_segment))
        proj, legs = tracker.projector.capsules_and_points(Q, caps, tracker.leg_points)
        gap = tracker.needs_leg_gap(idx)
        gaps += gap
        I, M = lik.terms(obs, proj)
        got_w = layer_log_weights(I, M, areas, lik.beta, Q, idx, tracker.prior_sigma,
                                  legs if gap else np.zeros((0, 6, 3)), tracker._gap_min, tracker._gap_sigma)
        want_w = lik.score(obs, proj) + tracker.log_prior(Q, idx, legs if gap else None)
        assert np.isfinite(want_w).all() and np.array_equal(got_w, want_w)
    assert 0 < gaps < len(selections)  # both kinds were compared


def test_free_rows_computed_where_the_kernel_reads_equal_every_row(embedded_session, rng):
    """FreeRows (a further pass's Img_n, computed only on the rows the particles reach) gives the
    kernel's sums of free_prefixes over every row, bit for bit, with the rows it leaves out poisoned
    (NaN): the kernel reads no row that rows_reached does not name."""
    from gaitcap.tracking.likelihood import FreeRows

    truth, rig, model = _truth_setup(embedded_session.session)
    views = tracking_views(rig, 0.5)
    lik = SilhouetteLikelihood(views, beta=40.0)
    projector = PoseProjector(model, views)
    obs = observe(views, [truth.mask(c, 30) for c in rig.names])
    placed = [np.zeros_like(s) for s in obs.silhouettes]
    for c in range(len(views)):  # the trunk and arms placed (a leg node's Img_n)
        lik.fill(c, projector.capsules(truth.poses[30][None], np.arange(6, 17)), placed[c])
    full = lik.free_prefixes(obs, placed)
    shape = (len(views), *obs.silhouettes[0].shape)
    into = (np.full((*shape[:2], shape[2] + 1), np.nan), np.full((*shape[:2], shape[2] + 1), np.nan))
    rows = FreeRows(obs, placed, into)
    for spread in (0.02, 0.3):  # near the pose, then farther: the computed rows grow
        Q = model.clip(truth.poses[30] + rng.normal(0, spread, (40, model.n_dofs)))
        proj = projector.capsules(Q, np.arange(3))
        got = lik.terms(obs, proj, rows.cover(proj))
        want = lik.terms(obs, proj, full)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    assert np.isnan(into[0]).any()  # rows were left out


def test_poses_sharing_their_ancestors_project_as_each_alone(embedded_session, rng):
    """The kinematics reuse the previous pose's frame for a segment whose DOF and ancestors' DOF are
    the same (a node's particles): the batch equals every pose projected alone, also where a parent
    changed and its child did not (fails when a child's frame is reused under a moved parent), and
    where a DOF is 0.0 in one pose and -0.0 in the next (equal values either way)."""
    truth, rig, model = _truth_setup(embedded_session.session)
    projector = PoseProjector(model, tracking_views(rig, 0.5))
    q = model.clip(truth.poses[12][None])[0]
    thigh = model.segment("thigh_l")
    pelvis = model.segment("pelvis")
    Q = np.repeat(q[None], 12, axis=0)
    Q[1:4, thigh.dof_start : thigh.dof_stop] += rng.normal(0, 0.2, (3, thigh.n_dofs))  # a leg node's particles
    Q[5, pelvis.dof_start + 3] += 0.1  # the root turned: every frame below it changes
    Q[7:9, pelvis.dof_start + 4] = 0.0
    Q[8, pelvis.dof_start + 4] = -0.0  # the same number, another sign
    Q[10, model.dof_index("knee_flexion_l")] += 0.3
    everything = np.arange(len(model.capsule_segment))
    proj, points = projector.capsules_and_points(Q, everything, np.arange(model.n_points))
    for n in range(len(Q)):
        one, one_points = projector.capsules_and_points(Q[n : n + 1], everything, np.arange(model.n_points))
        for got, want in zip((proj.a, proj.b, proj.ra, proj.rb), (one.a, one.b, one.ra, one.rb)):
            assert np.array_equal(got[:, n], want[:, 0])
        assert np.array_equal(points[n], one_points[0])
    assert not np.array_equal(proj.a[:, 5], proj.a[:, 4])


def test_posture_prior_and_coupled_dofs_are_validated(tmp_path):
    model = load_body_model()
    cfg = load_tracking_config()
    sigma = cfg.prior_sigmas(model)
    assert np.isinf(sigma[model.dof_index("knee_flexion_l")])  # seen in the image: no prior
    assert np.isclose(sigma[model.dof_index("pelvis_tilt")], np.radians(cfg.prior["pelvis_(tilt|obliquity)"]))
    explored = cfg.explored_dofs(model, subtrees(model))
    thigh = explored[model.segment("thigh_l").index]
    assert model.dof_index("knee_flexion_l") in thigh and model.dof_index("hip_flexion_l") in thigh
    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["factored_ipf"]["coupled"] = {"shank_l": ["hip_flexion_l"]}  # a DOF above the node: refused
    path = tmp_path / "tracking.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"coupled\.shank_l: 'hip_flexion_l' is not a DOF of a segment below"):
        load_tracking_config(path).explored_dofs(model, subtrees(model))
    data["factored_ipf"]["coupled"] = {}
    data["prior"] = {"pelvis_.*": 5, "pelvis_tilt": 3}  # two patterns for one DOF
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"prior: DOF 'pelvis_tilt' matches several patterns"):
        load_tracking_config(path).prior_sigmas(model)


@pytest.mark.parametrize(
    ("anchored", "refine", "message"),
    [
        (["shank_l"], "alone", "'shank_l' must be a child of the root with exactly one child segment"),
        (["torso"], "alone", "'torso' must be a child of the root with exactly one child segment"),
        (["thigh_x"], "alone", "unknown segment 'thigh_x'"),
        (["thigh_l"], "rigid", "needs root_refine 'alone'"),
    ],
)
def test_root_anchored_segments_are_validated(tmp_path, anchored, refine, message):
    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["factored_ipf"]["root_anchored"] = anchored
    data["factored_ipf"]["root_refine"] = refine
    path = tmp_path / "tracking.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=re.escape(f"factored_ipf.root_anchored: {message}")):
        load_tracking_config(path, load_body_model())


def test_subject_absent_from_every_frame_is_one_clear_error(embedded_session, tmp_path):
    import shutil

    import cv2
    from click.testing import CliRunner

    from gaitcap.cli.main import cli
    from gaitcap.io.video_write import AtomicVideoWriter

    session = tmp_path / "empty"
    shutil.copytree(embedded_session.session, session)
    for cam in ("cam1", "cam2"):
        plate = cv2.imread(str(session / "background" / f"{cam}.png"))
        with AtomicVideoWriter(session / "videos" / f"{cam}.mp4", 25.0, (plate.shape[1], plate.shape[0])) as w:
            for _ in range(12):
                w.write(plate)
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["-q", "track", str(session), "-o", str(out)])
    assert result.exit_code == 1
    assert "the subject was not found in any of the 12 frames" in result.output
    assert not (out / "trajectories.h5").exists() and not (out / "track.json").exists()


def test_camera_without_video_creates_no_output(embedded_session, tmp_path):
    import shutil

    from click.testing import CliRunner

    from gaitcap.cli.main import cli

    session = tmp_path / "session"
    shutil.copytree(embedded_session.session, session)
    (session / "videos" / "cam2.mp4").rename(session / "videos" / "camX.mp4")
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["-q", "track", str(session), "-o", str(out)])
    assert result.exit_code == 1
    assert "no video for camera 'cam2' from calibration.toml" in result.output
    assert not out.exists()


def test_config_naming_an_unknown_segment_creates_no_output(embedded_session, tmp_path):
    from click.testing import CliRunner

    from gaitcap.cli.main import cli

    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["factored_ipf"]["coupled"]["thihg_l"] = data["factored_ipf"]["coupled"].pop("thigh_l")
    config = tmp_path / "tracking.yaml"
    config.write_text(yaml.safe_dump(data))
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["-q", "track", str(embedded_session.session), "-o", str(out), "-c", str(config)])
    assert result.exit_code == 1
    assert f"{config}: tracking config: factored_ipf.coupled: unknown segment 'thihg_l'" in result.output
    assert not out.exists()


def _refit_tracker(rig, particles: int, root_particles: int):
    """The views and the one-pass re-fitting tracker factory of the shape calibration, as
    pipeline._calibrate_shape builds them (one pass, no mirrored hypothesis)."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    cfg = load_tracking_config()
    cfg.factored_ipf.passes, cfg.factored_ipf.swap_hypothesis = 1, False
    cfg.factored_ipf.particles, cfg.factored_ipf.root_particles = particles, root_particles
    views = tracking_views(rig, cfg.scale)
    lik = SilhouetteLikelihood(views, cfg.beta)
    return views, lambda m: FactoredIPF(m, lik, cfg, np.random.default_rng(0))


@pytest.mark.parametrize(("short", "max_moves", "at_least", "planted"),
                         [(0.85, 1, 1.0, False), (0.75, 4, 1.08 * 1.08 - 1e-9, False), (0.85, 1, 1.0, True)])
def test_shape_calibration_moves_a_wrong_thigh_towards_the_truth(embedded_session, short, max_moves, at_least,
                                                                 planted):  # fmt: skip
    from gaitcap.tracking.shape import calibrate_shape

    truth, rig, true_model = _truth_setup(embedded_session.session)
    views, make_tracker = _refit_tracker(rig, 60, 150)
    scales = {k: v.copy() for k, v in true_model.scales.items()}
    for side in "lr":
        scales[f"thigh_{side}"][2] *= short  # a thigh too short
    wrong = true_model.with_proportions(scales, true_model.shifts)
    frames = [10, 14, 18]
    obs = [observe(views, [truth.mask(c, t) for c in rig.names]) for t in frames]
    result = calibrate_shape(wrong, make_tracker, obs,
                             [truth.poses[t] for t in frames], {"thigh_length": ["thigh_l.z", "thigh_r.z"]},
                             steps=[0.08, 0.04], bounds=(0.7, 1.4), samples=3, max_moves=max_moves,
                             planted=planted)  # fmt: skip
    assert result.fit_after >= result.fit_before
    # lengthened, towards 1 / short; with several moves per round, beyond the reach of one move (+8 %)
    assert at_least < result.factors["thigh_length"] <= 1.4
    assert result.model.scales["thigh_l"][2] == pytest.approx(scales["thigh_l"][2] * result.factors["thigh_length"])
    assert result.start.shape == (31,)


def test_shape_rounds_after_the_first_start_from_the_window_tracked_again(embedded_session):
    """With ``retrack``, the window is tracked again before each round of steps but the first,
    with the model the rounds so far found (here the first round lengthened a thigh 15 % too
    short by one step of 8 %), from the first frame's re-fitted pose."""
    from gaitcap.tracking.shape import calibrate_shape

    truth, rig, true_model = _truth_setup(embedded_session.session)
    views, make_tracker = _refit_tracker(rig, 60, 150)
    scales = {k: v.copy() for k, v in true_model.scales.items()}
    for side in "lr":
        scales[f"thigh_{side}"][2] *= 0.85
    wrong = true_model.with_proportions(scales, true_model.shifts)
    frames = [10, 14, 18]
    obs = [observe(views, [truth.mask(c, t) for c in rig.names]) for t in frames]
    calls = []

    def retrack(model, q0):
        calls.append((model.scales["thigh_l"][2] / wrong.scales["thigh_l"][2], q0.shape))
        return [truth.poses[t] for t in frames]

    result = calibrate_shape(wrong, make_tracker, obs, [truth.poses[t] for t in frames],
                             {"thigh_length": ["thigh_l.z", "thigh_r.z"]}, steps=[0.08, 0.04, 0.04], bounds=(0.7, 1.4),
                             samples=3, max_moves=1, retrack=retrack)  # fmt: skip
    assert len(calls) == 2 and all(shape == (31,) for _, shape in calls)
    assert calls[0][0] == pytest.approx(1.08)
    assert calls[1][0] in (pytest.approx(1.08 * 0.96), pytest.approx(1.08), pytest.approx(1.08 * 1.04))
    assert result.fit_after >= result.fit_before


def _short_legs_window(embedded_session):
    """A shape calibration problem: the true model with thighs and shanks 12 % too short, the re-fit
    tracker factory, three frames' observations and true poses, and the two leg parameters."""
    truth, rig, true_model = _truth_setup(embedded_session.session)
    views, make_tracker = _refit_tracker(rig, 60, 150)
    scales = {k: v.copy() for k, v in true_model.scales.items()}
    for seg in ("thigh_l", "thigh_r", "shank_l", "shank_r"):
        scales[seg][2] *= 0.88
    wrong = true_model.with_proportions(scales, true_model.shifts)
    frames = [10, 14, 18]
    obs = [observe(views, [truth.mask(c, t) for c in rig.names]) for t in frames]
    parameters = {"thigh_length": ["thigh_l.z", "thigh_r.z"], "shank_length": ["shank_l.z", "shank_r.z"]}
    return wrong, make_tracker, obs, [truth.poses[t] for t in frames], parameters


def test_random_shape_moves_only_ever_raise_the_fit(embedded_session):
    """The random stage after the coordinate search (every parameter moved at once) keeps a move
    only when it fits better: from a leg 12 % too short in both segments it lengthens the leg, it
    is reproducible for a seed, and without candidates nothing moves (so the checks can fail)."""
    from gaitcap.tracking.shape import calibrate_shape

    wrong, make_tracker, obs, starts, parameters = _short_legs_window(embedded_session)

    def run(candidates):
        return calibrate_shape(wrong, make_tracker, obs, starts, parameters, steps=[],
                               bounds=(0.8, 1.25), samples=3, seed=3, random_candidates=candidates,
                               random_sigma=0.05)  # fmt: skip

    still = run(0)
    assert still.factors == {"thigh_length": 1.0, "shank_length": 1.0}
    assert still.fit_after == still.fit_before
    moved, again = run(12), run(12)
    assert moved.fit_after > moved.fit_before
    assert moved.factors["thigh_length"] * moved.factors["shank_length"] > 1.0  # the leg lengthened
    assert all(0.8 <= f <= 1.25 for f in moved.factors.values())
    assert again.factors == moved.factors and again.fit_after == moved.fit_after


def test_shape_candidates_scored_side_by_side_give_the_one_thread_result(embedded_session):
    """With ``workers`` > 1 the candidates' re-fits run on a thread pool (each thread set up by
    ``worker_setup``) and the random moves are scored ``workers`` at a time; those after an accepted
    move are scored again from the new shape, so the result is the one-thread result exactly. The
    extra re-fits show that an accepted move did discard scored candidates here."""
    import threading

    from gaitcap.tracking.shape import calibrate_shape

    wrong, make_tracker, obs, starts, parameters = _short_legs_window(embedded_session)
    threads, setups = [], []

    def counting(m):
        threads.append(threading.current_thread().name)
        return make_tracker(m)

    def run(workers):
        threads.clear()
        result = calibrate_shape(wrong, counting, obs, starts, parameters, steps=[0.08],
                                 bounds=(0.8, 1.25), samples=3, seed=3, planted=True, random_candidates=12,
                                 random_sigma=0.05, workers=workers,
                                 worker_setup=lambda: setups.append(threading.current_thread().name))  # fmt: skip
        return result, list(threads)

    one, one_threads = run(1)
    assert not setups  # one thread: no pool
    two, two_threads = run(2)
    assert two.factors == one.factors and two.fit_after == one.fit_after
    assert np.array_equal(two.start, one.start)
    assert two.fit_after > two.fit_before and two.factors != {"thigh_length": 1.0, "shank_length": 1.0}
    assert set(one_threads) == {threading.current_thread().name}
    assert sum(t.startswith("gaitcap-shape") for t in two_threads) == len(two_threads) - 1  # all but the first
    assert len(set(setups)) == 2 and all(t.startswith("gaitcap-shape") for t in setups)
    assert len(two_threads) > len(one_threads)  # scored candidates discarded after an accepted move


@pytest.mark.parametrize(("parameter", "targets", "twice"),
                         [("arm_length", ["upper_arm_l.z", "upper_arm_r.z"], False),
                          ("trunk_length", ["torso.z"], False), ("thigh_length", ["thigh_l.z", "thigh_r.z"], True)])
def test_planted_refits_only_parameters_that_move_the_soles(embedded_session, parameter, targets, twice):
    """With ``planted``, a candidate is re-fitted a second time from the planted poses only when
    those differ from the unmoved ones: a trunk or arm parameter costs what it costs without
    planting, a leg parameter twice as much (the count can fail both ways)."""
    from gaitcap.tracking.shape import calibrate_shape

    truth, rig, model = _truth_setup(embedded_session.session)
    views, make_tracker = _refit_tracker(rig, 10, 20)
    obs = [observe(views, [truth.mask(c, 12) for c in rig.names])]
    built = {True: 0, False: 0}

    def counting(planted):
        def make(m):
            built[planted] += 1
            return make_tracker(m)
        return make

    for planted in (False, True):
        calibrate_shape(model, counting(planted), obs, [truth.poses[12]], {parameter: targets}, steps=[0.08],
                        bounds=(0.9, 1.1), samples=1, max_moves=1, planted=planted)  # fmt: skip
    assert built[False] == 3  # the start and the two candidates
    assert built[True] == (1 + 2 * 2 if twice else 3)


def _swap_setup(session, **factored_ipf):
    """The set-up of the leg-swap tests: the truth, the calibration, the views, a factored-IPF
    tracker (default config with ``factored_ipf`` overrides, rng 0), the hip-flexion DOF indices
    (left, right) and the degrees between the true hip flexions of each frame (T,)."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(session)
    cfg = load_tracking_config()
    for key, value in factored_ipf.items():
        setattr(cfg.factored_ipf, key, value)
    views = tracking_views(rig, cfg.scale)
    tracker = FactoredIPF(model, SilhouetteLikelihood(views, cfg.beta), cfg, np.random.default_rng(0))
    hips = (model.dof_index("hip_flexion_l"), model.dof_index("hip_flexion_r"))
    apart = np.degrees(np.abs(truth.poses[:, hips[0]] - truth.poses[:, hips[1]]))
    return truth, rig, views, tracker, hips, apart


def _previous_estimate(tracker, truth, views, rig, t: int, q) -> None:
    """Track frame t - 1 from the true pose of t - 2 (so that frame t is not a fresh start's first,
    and the tracker has a fit history of one frame), then make q the previous estimate."""
    tracker.start(truth.poses[t - 2])
    tracker.step(observe(views, [truth.mask(c, t - 1) for c in rig.names]))
    tracker.q = q


def _on_own_sides(q, true_q, hips) -> tuple[bool, bool]:
    """Whether the left and the right hip flexion of pose q are nearer their own side's true value
    than the other side's."""
    hl, hr = hips
    return (bool(abs(q[hl] - true_q[hl]) < abs(q[hl] - true_q[hr])),
            bool(abs(q[hr] - true_q[hr]) < abs(q[hr] - true_q[hl])))  # fmt: skip


@pytest.mark.parametrize(("swap_search", "margin"), [("full", 0.0), ("legs", 0.0), ("legs", 0.01)])
def test_swap_hypothesis_puts_swapped_legs_back(embedded_session, swap_search, margin):
    """From a previous estimate with the legs swapped, the mirrored hypothesis (searched over the
    whole chain, or over the legs only; also when it must fit ``swap_margin`` better) wins and
    the legs come back to their sides. The side check fails on the swapped start, so it can fail.
    (Without the mirror, the plain interval search also brought them back on this session.)"""
    truth, rig, views, tracker, hips, apart = _swap_setup(
        embedded_session.session, swap_hypothesis=True, swap_search=swap_search,
        swap_margin=margin, swap_fit_drop=None)  # the legs' closeness alone calls the mirror
    # close enough for the mirror (swap_within_deg: 25), the widest such gap
    t = max((i for i in range(5, len(apart)) if 15 < apart[i - 1] < 24 and 15 < apart[i] < 24),
            key=lambda i: min(apart[i - 1], apart[i]))
    swapped = tracker.mirrored(truth.poses[t - 1])
    assert not any(_on_own_sides(swapped, truth.poses[t], hips))
    _previous_estimate(tracker, truth, views, rig, t, swapped)  # not a fresh start
    q = tracker.step(observe(views, [truth.mask(c, t) for c in rig.names])).q
    assert all(_on_own_sides(q, truth.poses[t], hips))


@pytest.mark.parametrize("fresh", [True, False, None])  # None: no start, a tracked frame
def test_first_frame_after_a_start_weighs_both_leg_assignments(embedded_session, fresh):
    """Started with the legs swapped and far apart (as a shape calibration's start can be), the
    first frame searches the mirror too and the legs come back to their sides. The same swapped
    pose reached by tracking (no start, no closeness, no fit drop) stays swapped, and so does a
    start declared settled (``fresh=False``), so the check can fail."""
    truth, rig, views, tracker, hips, apart = _swap_setup(embedded_session.session, swap_fit_drop=None)
    t = next(i for i in range(3, len(apart)) if min(apart[i - 2 : i + 1]) > tracker.config.factored_ipf.swap_within_deg + 5)
    swapped = tracker.mirrored(truth.poses[t - 1])
    if fresh is not None:
        tracker.start(swapped, fresh=fresh)
    else:
        _previous_estimate(tracker, truth, views, rig, t, swapped)
    assert not tracker._legs_close(swapped)
    q = tracker.step(observe(views, [truth.mask(c, t) for c in rig.names])).q
    assert all(_on_own_sides(q, truth.poses[t], hips)) == bool(fresh)


def test_refine_searches_from_the_given_pose_alone(embedded_session):
    """Tracker.refine checks a pose chosen elsewhere (the backward pass's leg order): from the legs
    swapped and far apart it keeps them swapped, where a fresh step searches the mirror too and puts
    them back (so the check can fail); from the true pose it keeps the legs on their sides; the tracker
    is left started at the result."""
    truth, rig, views, tracker, hips, apart = _swap_setup(embedded_session.session, swap_fit_drop=None)
    t = next(i for i in range(3, len(apart)) if min(apart[i - 2 : i + 1]) > tracker.config.factored_ipf.swap_within_deg + 5)
    obs = observe(views, [truth.mask(c, t) for c in rig.names])
    swapped = tracker.mirrored(truth.poses[t - 1])
    tracker.start(swapped, fresh=True)
    assert all(_on_own_sides(tracker.step(obs).q, truth.poses[t], hips))
    est = tracker.refine(obs, swapped)
    assert not any(_on_own_sides(est.q, truth.poses[t], hips))
    assert np.array_equal(tracker.q, est.q)
    assert all(_on_own_sides(tracker.refine(obs, truth.poses[t - 1]).q, truth.poses[t], hips))


def test_refine_of_a_tracker_without_hypotheses_is_its_step_from_the_pose(embedded_session):
    """The base Tracker.refine (interval PF: no hypotheses to leave out) is a step from q, the same
    draws as start + step with the same stream, and leaves the tracker started at the result."""
    from gaitcap.tracking.ipf import IntervalPF

    truth, rig, model = _truth_setup(embedded_session.session)
    cfg = load_tracking_config()
    cfg.ipf.particles = 200
    lik = SilhouetteLikelihood(tracking_views(rig, cfg.scale), cfg.beta)
    obs = observe(lik.views, [truth.mask(c, 6) for c in rig.names])
    q = truth.poses[3]  # three frames before: the search moves
    est = IntervalPF(model, lik, cfg, np.random.default_rng(7)).refine(obs, q)
    plain = IntervalPF(model, lik, cfg, np.random.default_rng(7))
    plain.start(q, fresh=False)
    assert np.array_equal(est.q, plain.step(obs).q) and not np.array_equal(est.q, model.clip(q[None])[0])
    tracker = IntervalPF(model, lik, cfg, np.random.default_rng(7))
    assert np.array_equal(tracker.refine(obs, q).q, tracker.q)


@pytest.mark.parametrize("swapped,margin", [(True, 0.0), (False, 0.0), (True, 1.0)])
def test_settle_legs_keeps_the_assignment_the_frames_support(embedded_session, swapped, margin):
    """From a first pose with the legs swapped and apart, tracking the next frames from it and
    from its mirror picks the mirror (the true assignment); from the true pose, it keeps it. With
    a margin no fit difference can exceed (fits are at most 1) the swapped start is kept: the
    re-check after the shape calibration keeps the assignment it was calibrated with on a tie
    (``factored_ipf.swap_margin``). The tracker is left started there, settled (no mirror weighed
    on its next frame)."""
    from gaitcap.tracking.init import settle_legs

    truth, rig, views, tracker, hips, apart = _swap_setup(embedded_session.session, swap_fit_drop=None)
    t = next(i for i in range(len(apart) - 6) if min(apart[i : i + 6]) > tracker.config.factored_ipf.swap_within_deg + 5)
    start = tracker.mirrored(truth.poses[t]) if swapped else truth.poses[t].copy()
    assert all(_on_own_sides(start, truth.poses[t], hips)) == (not swapped)
    frames = [observe(views, [truth.mask(c, f) for c in rig.names]) for f in range(t, t + 6)]
    q = settle_legs(tracker, frames, start, margin)
    overturned = swapped and margin == 0.0
    assert all(_on_own_sides(q, truth.poses[t], hips)) == (overturned or not swapped)
    np.testing.assert_array_equal(q, tracker.mirrored(start) if overturned else start)  # a start, not a tracked pose
    np.testing.assert_allclose(tracker.q, tracker.model.clip(q[None])[0])
    assert not tracker._fresh


@pytest.mark.parametrize("decisive,margin", [(None, 0.0), (1.0, 0.0), (None, 1.0)])
def test_settle_legs_cuts_the_mirror_short_once_one_start_clearly_leads(embedded_session, monkeypatch, decisive,
                                                                      margin):  # fmt: skip
    """From a start with the legs swapped and apart, every frame is tracked from it, then the mirror's
    track stops after ``LEAST_FRAMES`` frames, where one start leads by ``DECISIVE_FIT`` over the same
    frames: the same choice as over every frame, for fewer steps. With a lead no fit can reach (or a
    margin as large) every frame is tracked from both."""
    import gaitcap.tracking.init as init_module

    truth, rig, views, tracker, hips, apart = _swap_setup(embedded_session.session, swap_fit_drop=None)
    t = next(i for i in range(len(apart) - 6) if min(apart[i : i + 6]) > tracker.config.factored_ipf.swap_within_deg + 5)
    start = tracker.mirrored(truth.poses[t])
    frames = [observe(views, [truth.mask(c, f) for c in rig.names]) for f in range(t, t + 6)]
    if decisive is not None:
        monkeypatch.setattr(init_module, "DECISIVE_FIT", decisive)
    steps = []
    step = tracker.step
    monkeypatch.setattr(tracker, "step", lambda obs, *a, **k: steps.append(obs) or step(obs, *a, **k))
    q = init_module.settle_legs(tracker, frames, start, margin)
    cut = decisive is None and margin == 0.0
    n = init_module.LEAST_FRAMES if cut else len(frames)
    assert [id(o) for o in steps] == [id(o) for o in frames + frames[:n]] and (n < len(frames)) == cut
    np.testing.assert_array_equal(q, start if margin else tracker.mirrored(start))


@pytest.mark.parametrize("swapped", [False, True])
def test_settled_frames_are_taken_as_tracked_not_tracked_again(embedded_session, monkeypatch, swapped):
    """settle_legs leaves the tracker remembering the kept start's track: started there again, settled,
    its steps over the same observations take those estimates and states without searching (the
    shape window and the run's first frames, tracked from that start, are not tracked a second
    time); the frame after them is searched from the last one's state. A start elsewhere, a fresh
    start, another observation or widened intervals forget them."""
    import gaitcap.tracking.init as init_module

    truth, rig, views, tracker, hips, apart = _swap_setup(embedded_session.session, swap_fit_drop=None)
    t = next(i for i in range(len(apart) - 6) if min(apart[i : i + 6]) > tracker.config.factored_ipf.swap_within_deg + 5)
    start = tracker.mirrored(truth.poses[t]) if swapped else truth.poses[t].copy()
    frames = [observe(views, [truth.mask(c, f) for c in rig.names]) for f in range(t, t + 6)]
    q = init_module.settle_legs(tracker, frames[:5], start)
    assert np.array_equal(q, tracker.mirrored(start) if swapped else start)
    track = tracker._remembered
    assert track is not None and np.array_equal(track.start, tracker.q)
    n = len(track.estimates)  # the mirror's track stops once one start clearly leads
    assert n == (init_module.LEAST_FRAMES if swapped else 5)
    searched = []
    inner = tracker._step
    monkeypatch.setattr(tracker, "_step", lambda obs, *a: searched.append(obs) or inner(obs, *a))
    tracker.start(q, fresh=False)
    taken = []
    for o in frames[:n]:
        taken.append(tracker.step(o))
        assert tracker.last_step_remembered
    assert searched == []
    for a, b in zip(taken, track.estimates, strict=True):
        assert np.array_equal(a.q, b.q) and a.fit == b.fit and np.array_equal(a.points, b.points)
    assert np.array_equal(tracker.q, track.states[-1]["q"]) and list(tracker._fits) == list(track.states[-1]["_fits"])
    tracker.step(frames[n])
    assert [id(o) for o in searched] == [id(frames[n])] and not tracker.last_step_remembered
    tracker.start(q, fresh=False)  # the track was used up: forgotten
    tracker.step(frames[0])
    assert len(searched) == 2
    for forget in ("elsewhere", "fresh", "other frame", "widened"):
        searched.clear()
        tracker.start(q, fresh=False)
        tracker.remember(track)
        if forget == "elsewhere":
            tracker.start(tracker.mirrored(q), fresh=False)
        elif forget == "fresh":
            tracker.start(q, fresh=True)
        obs = observe(views, [truth.mask(c, t) for c in rig.names]) if forget == "other frame" else frames[0]
        tracker.step(obs, widen=2.0 if forget == "widened" else 1.0)
        tracker.step(frames[1])
        assert len(searched) == 2, forget


@pytest.mark.parametrize("mirror", [False, True])
def test_initialise_reports_the_fit_of_the_pose_it_returns(embedded_session, monkeypatch, mirror):
    """InitResult.fit is the fit of InitResult.q on the first frame, also when settling the legs
    picks the leg-swapped mirror (forced here) of the refined pose."""
    import gaitcap.tracking.init as init_module

    truth, rig, views, tracker, hips, apart = _swap_setup(embedded_session.session)
    frames = [observe(views, [truth.mask(c, f) for c in rig.names]) for f in range(8)]
    monkeypatch.setattr(init_module, "settle_legs",
                        lambda tr, obs, q, own=None: tr.mirrored(q) if mirror else q.copy())  # fmt: skip
    result = init_module.initialise(tracker, tracker.likelihood, views, frames, 15, 1, 2.5, leg_frames=8)
    assert result.legs_settled
    assert result.fit == pytest.approx(tracker.full_fit(frames[0], result.q)[1], abs=1e-12)
    other = tracker.full_fit(frames[0], tracker.mirrored(result.q))[1]
    assert abs(other - result.fit) > 1e-3  # the two assignments fit differently: reporting the wrong one shows


def test_initialise_with_a_known_heading_searches_around_it_on_frames_taken_backwards(embedded_session, monkeypatch):
    """Given the heading (the backward pass's fresh start: the frames run backwards in time, so
    their motion points the other way), the candidates' headings are within 20 degrees of it and
    the pose found faces that way; from the frames' motion alone it would face backwards."""
    import gaitcap.tracking.init as init_module

    truth, rig, views, tracker, _, _ = _swap_setup(embedded_session.session)
    model = tracker.model
    yaw = model.dof_index("pelvis_rotation")
    last = len(truth.poses) - 1
    frames = [observe(views, [truth.mask(c, f) for c in rig.names]) for f in range(last, last - 8, -1)]
    heading = float(truth.poses[last, yaw])
    searched = []
    candidates = init_module._candidate_poses
    monkeypatch.setattr(init_module, "_candidate_poses",
                        lambda m, pos, headings: searched.extend(headings) or candidates(m, pos, headings))  # fmt: skip

    def off(a: float) -> float:  # degrees between a heading and the truth's
        return abs(np.degrees(np.angle(np.exp(1j * (a - heading)))))

    result = init_module.initialise(tracker, tracker.likelihood, views, frames, 15, 2, 2.5, heading_rad=heading)
    assert max(off(h) for h in searched) == pytest.approx(20)
    assert off(result.heading_rad) < 20
    searched.clear()
    init_module.initialise(tracker, tracker.likelihood, views, frames, 15, 2, 2.5)
    assert min(off(h) for h in searched) > 150  # the motion of frames taken backwards: the other way


def test_a_start_facing_backwards_is_turned_round_over_the_first_frames(embedded_session):
    """A subject walking on the spot (a treadmill) gives no walking direction: the first frame
    alone may prefer a pose facing backwards. ``_facing`` tracks it and the best pose facing the
    other way over the first frames and keeps the better mean fit; the tracker's random stream is
    left as the run without the check would have it (before the start settle_legs tracks anew, or
    after the kept pose's track, whose fits settle_legs then reuses)."""
    import gaitcap.tracking.init as init_module

    truth, rig, views, tracker, _, _ = _swap_setup(embedded_session.session)
    model = tracker.model
    yaw = model.dof_index("pelvis_rotation")
    frames = [observe(views, [truth.mask(c, f) for c in rig.names]) for f in range(8)]
    position = init_module.subject_positions(views, frames)[0]
    heading = float(truth.poses[0, yaw])

    def off(q) -> float:  # degrees between a pose's heading and the truth's
        return abs(np.degrees(np.angle(np.exp(1j * (q[yaw] - heading)))))

    turned = [heading + np.pi + np.radians(d) for d in (-10, 0, 10)]
    backwards = init_module._refined(tracker, tracker.likelihood, frames[0],
                                     init_module._candidate_poses(model, position, turned), 3, 2, 2.5)  # fmt: skip
    assert off(backwards[1]) > 150
    stream = tracker.rng.bit_generator.state
    fit, q, own = init_module._facing(tracker, tracker.likelihood, frames, position, backwards, 3, 2, 2.5)
    assert off(q) < 30
    assert own is None  # turned round: settle_legs tracks the new start itself
    assert fit == pytest.approx(tracker.full_fit(frames[0], q)[1], abs=1e-9)
    assert tracker.rng.bit_generator.state == stream
    # with a walking direction the other way must lead by ``decisive`` a frame: here it cannot
    _, kept, own = init_module._facing(tracker, tracker.likelihood, frames, position, backwards, 3, 2, 2.5,
                                       decisive=1.0)  # fmt: skip
    assert np.array_equal(kept, backwards[1]) and own is not None
    tracker.rng.bit_generator.state = stream
    # facing forwards already: kept, with its track over the frames, the stream where that track left it
    fit2, q2, own = init_module._facing(tracker, tracker.likelihood, frames, position, (fit, q), 3, 2, 2.5)
    assert fit2 == fit and np.array_equal(q2, q)
    after = tracker.rng.bit_generator.state
    tracker.rng.bit_generator.state = stream
    again = init_module._tracked(tracker, frames, q)
    assert np.array_equal(init_module._fits(own), init_module._fits(again))
    assert tracker.rng.bit_generator.state == after


@pytest.mark.parametrize("case", ["moving", "on the spot", "heading given"])
def test_which_way_the_subject_faces_is_always_checked(embedded_session, monkeypatch, case):
    """The facing check runs whether the first frames show a walking direction (a subject may walk
    backwards), none (every heading searched), or the caller gives the heading (the backward pass's
    fresh start takes the forward pass's, wrong after a turn the forward pass lost). With a
    direction, the other way's track stops once one way leads decisively."""
    import gaitcap.tracking.init as init_module

    truth, rig, views, tracker, _, _ = _swap_setup(embedded_session.session)
    frames = [observe(views, [truth.mask(c, f) for c in rig.names]) for f in range(8)]
    checked = []
    monkeypatch.setattr(init_module, "_facing",
                        lambda *args, decisive=None: checked.append(decisive) or (*args[4], None))  # fmt: skip
    if case == "on the spot":
        monkeypatch.setattr(init_module, "MIN_MOTION_M", 100.0)  # the motion counts as none
    heading = float(truth.poses[0, tracker.model.dof_index("pelvis_rotation")]) if case == "heading given" else None
    result = init_module.initialise(tracker, tracker.likelihood, views, frames, 30, 1, 2.5, leg_frames=8,
                                    heading_rad=heading)  # fmt: skip
    assert result.walking_direction_known == (case != "on the spot")
    assert len(checked) == 1
    if case != "on the spot":  # the other way is given up once it trails decisively
        assert checked == [init_module.DECISIVE_FIT]
    if case == "on the spot":  # no direction to favour: both ways tracked over every frame
        assert checked == [None]


def test_a_subject_walking_backwards_is_initialised_facing_the_way_it_faces(embedded_session):
    """The first frames taken in reverse order show a subject walking backwards: its motion points
    behind it. Searched around the motion alone, the first pose faces the motion (the way the
    frames move, away from the truth's heading); over the first frames the facing check turns it
    round to the truth's."""
    import gaitcap.tracking.init as init_module

    truth, rig, views, tracker, _, _ = _swap_setup(embedded_session.session)
    yaw = tracker.model.dof_index("pelvis_rotation")
    last = len(truth.poses) - 1
    frames = [observe(views, [truth.mask(c, f) for c in rig.names]) for f in range(last, last - 8, -1)]

    def off(q) -> float:  # degrees between a pose's heading and the truth's at the first frame
        return abs(np.degrees(np.angle(np.exp(1j * (q[yaw] - truth.poses[last, yaw])))))

    facing_motion = init_module.initialise(tracker, tracker.likelihood, views, frames, 15, 2, 2.5)  # no leg frames
    assert off(facing_motion.q) > 150
    result = init_module.initialise(tracker, tracker.likelihood, views, frames, 15, 2, 2.5, leg_frames=8)
    assert result.walking_direction_known
    assert off(result.q) < 30


@pytest.mark.parametrize("mirrored", [False, True])
def test_a_fresh_start_at_the_end_is_tracked_back_only_when_its_legs_disagree(embedded_session, monkeypatch,
                                                                               mirrored):  # fmt: skip
    """The backward pass's second hypothesis: initialised on the run's last frames, taken backwards
    with the forward pass's heading; a start whose legs agree with the forward pass's last pose
    adds nothing (None), one that disagrees is tracked back to the run's first frame."""
    from gaitcap import pipeline
    from gaitcap.io.spool import FrameSpool
    from gaitcap.tracking.init import InitResult

    truth, rig, views, tracker, _, apart = _swap_setup(embedded_session.session)
    t = next(i for i in range(6, len(apart)) if apart[i] > 20)  # the legs apart: the mirror's are far
    s, e = t - 5, t + 1
    q_last = truth.poses[t].copy()
    found = tracker.mirrored(q_last) if mirrored else q_last.copy()
    calls = []

    def initialise(tr, likelihood, views_, frames, *args, heading_rad=None, **kwargs):
        calls.append((frames, heading_rad))
        return InitResult(q=found, heading_rad=heading_rad, walking_direction_known=True, fit=0.8, legs_settled=True)

    monkeypatch.setattr(pipeline, "initialise", initialise)
    cfg = tracker.config
    with FrameSpool() as spool:
        for f in range(e):
            spool.append(observe(views, [truth.mask(c, f) for c in rig.names]).silhouettes)
        second = pipeline._restart_pass(tracker.model, tracker.likelihood, views, cfg, spool, q_last, s, e)
    yaw = tracker.model.dof_index("pelvis_rotation")
    (frames, heading), = calls
    assert heading == pytest.approx(q_last[yaw])
    n = min(cfg.init.frames, e - s)
    assert len(frames) == n  # the run's last frames, the last first
    for k, f in ((0, e - 1), (n - 1, e - n)):
        for got, mask in zip(frames[k].silhouettes, observe(views, [truth.mask(c, f) for c in rig.names]).silhouettes):
            np.testing.assert_array_equal(got, mask)
    if not mirrored:
        assert second is None
        return
    assert len(second) == e - s
    legs = [tracker.model.point_index(n) for n in ("ankle_l", "ankle_r")]
    truth_pts = tracker.projector.points(truth.poses[s:e])[:, legs]
    own = np.linalg.norm(np.array([b.points[legs] for b in second]) - truth_pts, axis=2).mean(axis=1)
    swapped = np.linalg.norm(np.array([b.points[legs][::-1] for b in second]) - truth_pts, axis=2).mean(axis=1)
    assert own[-1] > swapped[-1]  # its last frame tracked from the mirror: the ankles exchanged


@pytest.mark.parametrize("fit_drop", [0.04, None])
def test_fit_drop_searches_the_mirror_with_the_legs_apart(embedded_session, fit_drop):
    """Legs swapped while far apart (no mirror by closeness): a first pass fitting worse than the
    recent frames triggers the mirrored search, which puts them back; without the trigger
    (None) they stay swapped, so the check can fail."""
    truth, rig, views, tracker, hips, apart = _swap_setup(embedded_session.session, swap_fit_drop=fit_drop)
    t = next(i for i in range(8, len(apart)) if min(apart[i - 4 : i + 1]) > tracker.config.factored_ipf.swap_within_deg + 5)
    tracker.start(truth.poses[t - 4])
    for f in range(t - 3, t):  # recent frames tracked with the legs right: the fit history
        tracker.step(observe(views, [truth.mask(c, f) for c in rig.names]))
    tracker.q = tracker.mirrored(tracker.q)
    assert not tracker._legs_close(tracker.q)
    q = tracker.step(observe(views, [truth.mask(c, t) for c in rig.names])).q
    assert _on_own_sides(q, truth.poses[t], hips)[0] == (fit_drop is not None)  # the left leg


def test_track_with_shape_calibration_records_it(embedded_session, tmp_path, monkeypatch):
    import gaitcap.pipeline as pipeline_module

    margins = []  # the legs settled again with the calibrated model: its assignment overturned only by a margin
    real_settle = pipeline_module.settle_legs
    monkeypatch.setattr(pipeline_module, "settle_legs",
                        lambda tr, obs, q, margin=0.0: margins.append(margin) or real_settle(tr, obs, q, margin))  # fmt: skip
    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["shape"].update(enabled=True, frames=6, samples=2, steps=[0.08, 0.04], retrack=True)  # a re-tracked round
    data["shape"]["parameters"] = {"thigh_length": ["thigh_l.z", "thigh_r.z"]}
    data["shape"]["limits"] = {"thigh_length": [0.85, 1.15]}  # limits name parameters only
    data["factored_ipf"].update(particles=60, root_particles=150)
    config = tmp_path / "tracking.yaml"
    config.write_text(yaml.safe_dump(data))
    summary = run_track(embedded_session.session, tmp_path / "out", config=config, progress=False, max_frames=8)
    assert summary.status == "ok" and summary.n_frames == 8
    assert margins == [data["factored_ipf"]["swap_margin"]] and margins[0] > 0
    with h5py.File(tmp_path / "out" / "trajectories.h5") as f:
        note = f.attrs["shape"]
    assert note.startswith("thigh_length x") and "mean fit" in note
    body = json.loads((tmp_path / "out" / "track.json").read_text())["body"]
    assert body["shape"] == note and body["height_source"] == "session.yaml"
    factor = float(note.split(" x")[1].split(";")[0])
    shipped = model_lengths(load_body_model(height_m=body["height_m"]))
    # the note prints the factor to 3 decimals and track.json the length to 4 (metres)
    assert body["segment_lengths_m"]["thigh"] == pytest.approx(shipped["thigh"] * factor,
                                                               abs=shipped["thigh"] * 5e-4 + 5e-5)  # fmt: skip
    assert body["segment_lengths_m"]["shank"] == pytest.approx(shipped["shank"], abs=1e-4)


def test_a_run_whose_legs_lie_off_the_masks_is_tracked_again_with_doubt(embedded_session, tmp_path, caplog,
                                                                        monkeypatch):  # fmt: skip
    """``lost_legs``: a run whose legs the masks hold little of (here forced: every leg segment below
    a support of 1 in more than 1 % of the frames counts) is not written; the session is tracked again with the faint
    pixels outside the masks counted as doubtful, and that run is kept and says so. The masks saved
    are the first run's (the same); no temporary file is left. If that second run fails, the first is
    kept, not tracked again: the session is tracked twice, and the outputs are those of the same
    run with ``retrack: false`` (tracked once)."""
    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["shape"]["enabled"] = False
    data["factored_ipf"].update(particles=40, root_particles=80)
    data["verdict"].update(min_leg_support=1.0, max_unsupported_fraction=0.01)
    config = tmp_path / "tracking.yaml"
    config.write_text(yaml.safe_dump(data))
    out = tmp_path / "out"
    caplog.set_level(logging.INFO, logger="gaitcap")
    summary = run_track(embedded_session.session, out, config=config, progress=False, max_frames=5, save_masks=True,
                        height_m=1.2)  # a height the silhouettes contradict  # fmt: skip
    assert summary.status == "ok" and summary.n_frames == 5
    assert summary.verdict_notes[0].startswith("tracked twice: the first run's legs lay off a camera's masks (")
    assert "tracking again with the faint pixels" in caplog.text
    warned = [r for r in caplog.records if r.levelno == logging.WARNING and "the silhouettes show" in r.getMessage()]
    assert len(warned) == 1  # once, though the session was tracked twice
    assert sum("the silhouettes show" in n for n in summary.verdict_notes) == 1  # and noted by the run kept
    assert re.search(r"tracking the first 5 of the \d+ common frames \(--max-frames\)", caplog.text)
    with h5py.File(out / "trajectories.h5") as f:
        assert yaml.safe_load(f.attrs["config"])["soft_silhouettes"] is True
    assert json.loads((out / "track.json").read_text())["verdict_notes"] == summary.verdict_notes
    assert read_masks(out / "silhouettes.h5", "cam1").shape[0] == 5
    assert not list(out.glob(".*.part*"))

    import gaitcap.pipeline as pipeline_module
    from gaitcap.sync_check import SyncFinding

    real = pipeline_module._track_session
    runs = []

    def failing_with_doubt(*args, **kwargs):
        runs.append(args[4].soft_silhouettes)  # cfg: True for the run with the doubtful pixels
        if runs[-1]:
            raise TrackingError("no pose fits")
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline_module, "_track_session", failing_with_doubt)
    monkeypatch.setattr(pipeline_module, "_sync_note", lambda tops, videos, skipped: SyncFinding(  # no skip_frames to track again with
        "cam2 2 frames late", "cam2's video starts 2.0 frames after", None, 2.0))
    kept = run_track(embedded_session.session, out, config=config, progress=False, max_frames=5, force=True)
    monkeypatch.undo()
    assert runs == [False, True]  # the first run is not tracked again
    assert kept.status == "ok" and kept.verdict_notes[0].startswith("the first run's legs lay off a camera's masks (")
    assert "failed (no pose fits): this is the first run" in kept.verdict_notes[0]
    assert "cam2's video starts 2.0 frames after" in kept.verdict_notes  # the first run's own notes kept with it
    assert json.loads((out / "track.json").read_text())["verdict_notes"] == kept.verdict_notes
    assert not list(out.glob(".*.part*"))
    with h5py.File(out / "trajectories.h5") as f:
        assert yaml.safe_load(f.attrs["config"])["soft_silhouettes"] is False
    first_run = read_trajectory(out / "trajectories.h5").points

    def interrupted_with_doubt(*args, **kwargs):
        if args[4].soft_silhouettes:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline_module, "_track_session", interrupted_with_doubt)
    with pytest.raises(KeyboardInterrupt):
        run_track(embedded_session.session, out, config=config, progress=False, max_frames=5, force=True)
    monkeypatch.undo()
    assert not list(out.glob(".*.part*")) and not (out / "track.json").exists()  # the kept run's file removed too
    data["lost_legs"] = {"retrack": False}
    config.write_text(yaml.safe_dump(data))
    once = run_track(embedded_session.session, out, config=config, progress=False, max_frames=5, force=True)
    assert not any(n.startswith("tracked twice") for n in once.verdict_notes)
    assert any(n.startswith("legs placed where") for n in once.verdict_notes)  # the note stays
    with h5py.File(out / "trajectories.h5") as f:
        assert yaml.safe_load(f.attrs["config"])["soft_silhouettes"] is False
    np.testing.assert_array_equal(read_trajectory(out / "trajectories.h5").points, first_run)  # the kept first run


def test_what_the_session_check_tolerated_is_noted_in_track_json(embedded_session, tmp_path):
    """A calibration whose recorded reprojection error is poor (1.5 px, above ``calibrate check``'s 1 px) is
    tracked, and track.json's notes say so (the session check's notes: also a crop, frame counts that differ)."""
    session = tmp_path / "session"
    shutil.copytree(embedded_session.session, session)
    write_calibration(session / "calibration.toml", read_calibration(session / "calibration.toml"), {"error": 1.5})
    config = quick_tracking(tmp_path)
    summary = run_track(session, tmp_path / "out", config=config, progress=False, max_frames=4)
    assert "records is 1.50 px overall (above 1 px: a poor calibration" in summary.verdict_notes[0]
    assert json.loads((tmp_path / "out" / "track.json").read_text())["verdict_notes"] == summary.verdict_notes


def test_calibrated_body_outside_the_ranges_is_rejected(embedded_session, tmp_path, caplog):
    """A calibrated body whose leg is outside shape.ranges (here a range no body meets) is not
    tracked: the shipped proportions are, the log warns and track.json says why."""
    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["shape"].update(enabled=True, frames=4, samples=2, steps=[0.08], random_candidates=0, repeats=1,
                         ranges={"leg": [0.1, 0.2]})  # fmt: skip
    data["shape"]["parameters"] = {"thigh_length": ["thigh_l.z", "thigh_r.z"]}
    data["shape"]["limits"] = {"thigh_length": [0.85, 1.15]}  # limits name parameters only
    data["factored_ipf"].update(particles=60, root_particles=150)
    config = tmp_path / "tracking.yaml"
    config.write_text(yaml.safe_dump(data))
    run_track(embedded_session.session, tmp_path / "out", config=config, progress=False, max_frames=5)
    body = json.loads((tmp_path / "out" / "track.json").read_text())["body"]
    assert body["shape"].startswith("rejected (leg ") and "outside 0.10-0.20" in body["shape"]
    shipped = model_lengths(load_body_model(height_m=body["height_m"]))
    assert body["segment_lengths_m"]["leg"] == pytest.approx(shipped["leg"], abs=1e-4)
    assert "shape calibration rejected" in caplog.text


def test_kernel_threads_are_set_capped_and_restored(tmp_path):
    import numba

    from gaitcap.pipeline import kernel_threads

    before, most = numba.get_num_threads(), numba.config.NUMBA_NUM_THREADS
    with kernel_threads(1):
        assert numba.get_num_threads() == 1
    assert numba.get_num_threads() == before
    for n in (None, most + 5):
        with kernel_threads(n):
            assert numba.get_num_threads() == most
    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    assert data["threads"] == 1
    data["threads"] = 0
    path = tmp_path / "tracking.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match="threads"):
        load_tracking_config(path)


def test_start_switch_interval_of_overlapping_runs_is_restored_by_the_last_to_end():
    """Two runs' start blocks overlapping on two threads, the first to enter ending first: the
    interval stays short until both have ended, then it is the one in force before either began
    (each block restoring what it found would leave the short interval behind)."""
    import sys
    import threading

    from gaitcap.pipeline import START_SWITCH_S, _switch_interval

    original = sys.getswitchinterval()
    entered, release_second = threading.Event(), threading.Event()
    seen: dict[str, float] = {}

    def second_run() -> None:
        with _switch_interval(START_SWITCH_S):
            entered.set()
            release_second.wait(5)

    try:
        with _switch_interval(START_SWITCH_S):
            other = threading.Thread(target=second_run)
            other.start()
            assert entered.wait(5)
        seen["after the first"] = sys.getswitchinterval()
        release_second.set()
        other.join(5)
        seen["after both"] = sys.getswitchinterval()
    finally:
        release_second.set()
        sys.setswitchinterval(original)
    assert seen["after the first"] == pytest.approx(START_SWITCH_S)
    assert seen["after both"] == pytest.approx(original)
    assert START_SWITCH_S != pytest.approx(original)


def test_root_refined_alone_keeps_the_trunk_and_thighs_still(embedded_session, rng):
    """Moving the root alone re-solves the lumbar and hip angles so that the trunk and thighs keep
    their world orientation: R_pelvis' R_child' = R_pelvis R_child (no thigh anchored at its knee)."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    cfg = load_tracking_config()
    cfg.factored_ipf.root_anchored = []
    lik = SilhouetteLikelihood(tracking_views(rig, cfg.scale), cfg.beta)
    tracker = FactoredIPF(model, lik, cfg, np.random.default_rng(0))
    q = truth.poses[20]
    Q = np.repeat(q[None], 40, axis=0)
    Q[:, 3:6] += rng.normal(0, np.radians(6), size=(40, 3))
    Q[:, tracker._held] = tracker._held_angles(q, Q)
    R0, _ = model.frames(q[None])
    R1, _ = model.frames(Q)
    for name in ("torso", "thigh_l", "thigh_r"):
        s = model.segment(name).index
        np.testing.assert_allclose(R1[:, s], np.broadcast_to(R0[0, s], R1[:, s].shape), atol=1e-9)


def test_root_refined_alone_corrects_a_turned_pelvis(embedded_session):
    """A pelvis turned 12 degrees under legs and trunk that are right (as a first pass leaves it
    when the turn explained a stride): the further passes moving the root alone turn it back
    further than moving the whole body rigidly, which would also turn the legs away (so the check
    can fail). The pelvis rotation's half-width is set to 12 degrees here, whatever the shipped
    one, so that the further passes (0.35 of it) can undo the turn. Alone with the shipped
    ``root_anchored`` thighs and without any."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    errors = {}
    for mode, anchored in (("alone", None), ("alone", []), ("rigid", [])):
        cfg = load_tracking_config()
        cfg.factored_ipf.root_refine = mode
        if anchored is not None:
            cfg.factored_ipf.root_anchored = anchored
        cfg.intervals = {**cfg.intervals, "pelvis_rotation": 12.0}
        views = tracking_views(rig, cfg.scale)
        lik = SilhouetteLikelihood(views, cfg.beta)
        maker = load_tracking_config()
        maker.factored_ipf.root_anchored = []  # the turn leaves the trunk and thighs in their orientation
        err = []
        for t in (9, 24, 39, 54):
            tracker = FactoredIPF(model, lik, cfg, np.random.default_rng(0))
            turned = truth.poses[t][None].copy()
            turned[0, 3] += np.radians(12)
            held = FactoredIPF(model, lik, maker, np.random.default_rng(0))
            turned[0, held._held] = held._held_angles(truth.poses[t], turned)[0]
            est, _ = tracker._search(observe(views, [truth.mask(c, t) for c in rig.names]), turned[0], 1.0, 1, 3)
            err.append(abs(np.degrees(est.q[3] - truth.poses[t][3])))
        errors[mode, anchored is None] = float(np.mean(err))
    for shipped in (True, False):
        assert errors["alone", shipped] < 9.0 and errors["alone", shipped] < errors["rigid", False] - 2.0, errors


def test_root_anchored_thighs_aim_at_the_knees_as_they_were(embedded_session, rng):
    """With ``root_anchored`` thighs, moving the root alone turns each thigh so that it points from
    its new hip centre at the old knee centre (the knee slides along that line only, since the
    thigh keeps its length), and the knee flexion keeps the shank's world orientation as closely as
    one DOF can (0.01 rad more or less flexion turns the shank further from it); the trunk keeps its
    orientation as before."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    cfg = load_tracking_config()
    cfg.factored_ipf.root_anchored = ["thigh_l", "thigh_r"]
    tracker = FactoredIPF(model, SilhouetteLikelihood(tracking_views(rig, cfg.scale), cfg.beta), cfg,
                          np.random.default_rng(0))  # fmt: skip
    q = truth.poses[20]
    Q = np.repeat(q[None], 40, axis=0)
    Q[:, :2] += rng.normal(0, 0.02, size=(40, 2))
    Q[:, 3:6] += rng.normal(0, np.radians(4), size=(40, 3))
    Q[:, tracker._held] = tracker._held_angles(q, Q)
    names = model.point_names
    P0, P1 = model.forward(q[None])[0], model.forward(Q)
    R0, _ = model.frames(q[None])
    R1, _ = model.frames(Q)
    for side in "lr":
        hip, knee = names.index(f"hip_{side}"), names.index(f"knee_{side}")
        aim = P0[knee] - P1[:, hip]
        thigh = P1[:, knee] - P1[:, hip]
        cos = np.sum(aim * thigh, axis=1) / np.linalg.norm(aim, axis=1) / np.linalg.norm(thigh, axis=1)
        assert np.all(cos > 1 - 1e-9)
        length = np.linalg.norm(P0[knee] - P0[hip])
        slid = np.abs(np.linalg.norm(aim, axis=1) - length)  # the knee stays where the thigh's length allows
        np.testing.assert_allclose(np.linalg.norm(P1[:, knee] - P0[knee], axis=1), slid, atol=1e-9)
        s, k = model.segment(f"shank_{side}").index, model.dof_index(f"knee_flexion_{side}")
        turns = []
        for dk in (-0.01, 0.0, 0.01):  # the shank's rotation from its old world orientation
            Qk = Q.copy()
            Qk[:, k] += dk
            Rk, _ = model.frames(Qk)
            turns.append(np.trace(np.swapaxes(Rk[:, s], 1, 2) @ R0[0, s], axis1=1, axis2=2))  # 1 + 2 cos(angle)
        assert np.all(turns[1] > turns[0]) and np.all(turns[1] > turns[2])
    t = model.segment("torso").index
    np.testing.assert_allclose(R1[:, t], np.broadcast_to(R0[0, t], R1[:, t].shape), atol=1e-9)


def test_root_anchored_thighs_bring_back_hips_left_behind(embedded_session):
    """The ridge of the likelihood: hips 20 mm behind the truth with the thighs leaning forward to
    the true knees (more knee flexion) fit almost as well as the truth. Moving the root alone with
    the thighs kept in orientation cannot follow that ridge (the knees would move too); with the
    thighs anchored at the knees the further passes bring the hips back to within a few mm, where
    without they stay about 10 mm behind, for every frame tried (so the check can fail)."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    hips = [model.point_names.index("hip_l"), model.point_names.index("hip_r")]
    behind = {}
    for anchored in ([], ["thigh_l", "thigh_r"]):
        cfg = load_tracking_config()
        cfg.factored_ipf.root_anchored = anchored
        # the ridge without the hip adduction prior, which slopes it on one of the frames (0.3 mm
        # behind without the anchors at frame 12): the anchors are what this test is about
        cfg.prior.pop("hip_adduction_[lr]")
        views = tracking_views(rig, cfg.scale)
        lik = SilhouetteLikelihood(views, cfg.beta)
        maker = load_tracking_config()
        maker.factored_ipf.root_anchored = ["thigh_l", "thigh_r"]
        errors = []
        for t in (12, 30, 48):
            q = truth.poses[t]
            forward = np.array([np.cos(q[3]), np.sin(q[3])])
            start = q[None].copy()
            start[0, :2] -= 0.02 * forward
            ridge = FactoredIPF(model, lik, maker, np.random.default_rng(0))
            start[0, ridge._held] = ridge._held_angles(q, start)[0]
            tracker = FactoredIPF(model, lik, cfg, np.random.default_rng(t))
            est, _ = tracker._search(observe(views, [truth.mask(c, t) for c in rig.names]), start[0], 1.0, 1, 3)
            P, T = model.forward(est.q[None])[0], model.forward(q[None])[0]
            errors.append(1000 * float(np.mean((P[hips, :2] - T[hips, :2]) @ forward)))
        behind[bool(anchored)] = errors
    assert all(abs(e) < 4.0 for e in behind[True]), behind
    assert all(e < -7.0 for e in behind[False]), behind


def test_track_says_where_the_results_are_unless_quiet(embedded_session, tmp_path):
    from click.testing import CliRunner

    from gaitcap.cli.main import cli

    for quiet, out in ((False, tmp_path / "loud"), (True, tmp_path / "quiet")):
        args = (["-q"] if quiet else []) + ["track", str(embedded_session.session), "-o", str(out), "--max-frames", "2"]
        result = CliRunner().invoke(cli, args)
        assert result.exit_code == 0, result.output
        assert (f"results: {out}" in result.stdout) != quiet
        assert (out / "trajectories.h5").is_file()


@pytest.mark.parametrize("challenger", ["mirror", "recovered"])
@pytest.mark.parametrize(("challenger_refined", "winner"), [(0.86, "first"), (0.905, "first"), (0.95, "challenger")])
def test_first_hypothesis_is_replaced_only_by_a_better_refined_fit(embedded_session, challenger,
                                                                   challenger_refined, winner):  # fmt: skip
    """A pose that beats the first hypothesis on the first pass (the leg-swapped mirror while the
    legs are close: 0.83 against 0.80, over the margin; or, after a fit drop, the widened search's
    pose: 0.85) replaces it only if it still fits ``swap_margin`` (0.01) better once both are
    refined (0.90 for the first). The searches are stand-ins with those fits, so that the choice
    alone is checked."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    cfg = load_tracking_config()
    cfg.factored_ipf.swap_hypothesis = challenger == "mirror"
    cfg.factored_ipf.swap_margin, cfg.factored_ipf.keep_previous = 0.01, False  # stand-in searches only
    tracker = FactoredIPF(model, SilhouetteLikelihood(tracking_views(rig, cfg.scale), cfg.beta), cfg,
                          np.random.default_rng(0))  # fmt: skip
    start = truth.poses[9].copy()
    hips = [model.dof_index("hip_flexion_l"), model.dof_index("hip_flexion_r")]
    start[hips] = np.radians(10.0)  # the legs close: the mirror is searched
    first, other = truth.poses[10], truth.poses[11]
    refined_fit = {first.tobytes(): 0.90, other.tobytes(): challenger_refined}

    def search(obs, q0, widen, p0, stop, from_node=0, **kwargs):
        if p0 == 0:
            mirror = from_node > 0 or not np.allclose(q0, start)
            q, fit = (first, 0.80) if widen <= 1.0 and not mirror else (other, 0.83 if mirror else 0.85)
        else:
            q, fit = q0, refined_fit[q0.tobytes()]
        return _stub_estimate(model, q, fit), [np.zeros(model.n_points)] * len(tracker.order)

    tracker._search = search
    tracker.start(start, fresh=False)
    tracker._fits.extend([0.8 if challenger == "mirror" else 0.9] * 5)  # recent fits: 0.80 is a drop after 0.9
    est = tracker.step(None)
    np.testing.assert_array_equal(est.q, first if winner == "first" else other)
    assert est.fit == (0.90 if winner == "first" else challenger_refined)
    assert est.evaluations == 4  # two first passes (first and challenger), two refinements


@pytest.mark.parametrize("keep", [False, True])
def test_keep_previous_lets_the_previous_estimate_compete_unchanged(embedded_session, keep):
    """Started at the true pose of the very frame it observes, the first pass (each node weighted
    against the silhouette the nodes before it left, Img_n) ends a little below the truth's fit
    on most frames (greedy: 0.001-0.01 lower on the embedded walk). With ``keep_previous`` the
    previous estimate competes unchanged with that pass, so the frame's fit is never below it,
    and where it won the pose is the previous estimate itself."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    cfg = load_tracking_config()
    fip = cfg.factored_ipf
    fip.passes, fip.swap_hypothesis, fip.recover_widen, fip.keep_previous = 1, False, None, keep
    views = tracking_views(rig, cfg.scale)
    tracker = FactoredIPF(model, SilhouetteLikelihood(views, cfg.beta), cfg, np.random.default_rng(3))
    below = kept = 0
    frames = range(4, 56, 8)
    for t in frames:
        obs = observe(views, [truth.mask(c, t) for c in rig.names])
        tracker.start(truth.poses[t], fresh=False)
        truth_fit = tracker.full_fit(obs, truth.poses[t])[1]
        est = tracker.step(obs)
        below += est.fit < truth_fit - 1e-12
        if keep:
            assert est.fit >= truth_fit - 1e-12, f"frame {t}: {est.fit:.4f} below the previous estimate's {truth_fit:.4f}"
            kept += bool(np.array_equal(est.q, model.clip(truth.poses[t][None])[0]))
    if not keep:
        assert below > len(frames) // 2  # what keep_previous is for: the greedy pass usually ends lower
    else:
        assert kept > len(frames) // 2  # the same searches (same seed): the truth stood where they fell short


def test_fit_drop_recovers_limbs_out_of_the_usual_reach(embedded_session):
    """Both knees left 60 degrees more flexed than the truth (out of reach of the usual intervals in
    one frame, and the mirror does not help) lower the fit below the recent frames'; the widened
    search (``recover_widen``) brings them nearer the truth than the usual search alone, for every
    one of four tracker seeds (paired: the same seed with and without), and to within 20 degrees on
    average where the usual search stays 70 degrees off; without the widening the two would be
    equal, so the check can fail. (One frame of widened search does not always finish the job:
    on these seeds the worse knee ends 1-30 degrees off.) Without the hip adduction prior this
    test was written with: with it, seed 1 stays 123 degrees off with and without the widening.
    And with the ``swap_margin`` it was written with, 0.015: with the shipped 0.008 the widened
    search of seed 3 ends 123 degrees off (a widened hypothesis winning by less), the usual one
    23 degrees, and seeds 2-3 of the usual search reach 23-25 degrees. And without the legs' gap
    prior (``leg_gap``), which came later and moves these seeds' searches: with it, seed 1's widened
    search ends 123 degrees off (the usual one 22) and seed 0's 18.5 against 17.3."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    knees = [model.dof_index("knee_flexion_l"), model.dof_index("knee_flexion_r")]
    t = 12

    def knee_error(widen, seed):
        cfg = load_tracking_config()
        cfg.factored_ipf.recover_widen, cfg.factored_ipf.swap_margin = widen, 0.015
        cfg.prior.pop("hip_adduction_[lr]")
        cfg.leg_gap.min = 0.0
        views = tracking_views(rig, cfg.scale)
        tracker = FactoredIPF(model, SilhouetteLikelihood(views, cfg.beta), cfg, np.random.default_rng(seed))
        tracker.start(truth.poses[t - 4])
        for f in range(t - 3, t):  # recent frames tracked right: the fit history
            tracker.step(observe(views, [truth.mask(c, f) for c in rig.names]))
        tracker.q[knees] = truth.poses[t - 1, knees] + np.radians(60)
        q = tracker.step(observe(views, [truth.mask(c, t) for c in rig.names])).q
        return np.degrees(np.abs(q[knees] - truth.poses[t, knees])).max()

    widened = np.array([knee_error(3.0, seed) for seed in range(4)])
    usual = np.array([knee_error(None, seed) for seed in range(4)])
    assert np.all(widened < usual), (widened, usual)
    assert widened.mean() < 20 < usual.mean(), (widened, usual)


def _stub_estimate(model, q: np.ndarray, fit: float):
    """A one-evaluation first pass at pose q with a set fit, for stubbing FactoredIPF._search."""
    from gaitcap.tracking.base import Estimate

    return Estimate(q=q.copy(), points=np.zeros((model.n_points, 3)), uncertainty=np.zeros(model.n_points),
                    log_likelihood=0.0, fit=fit, evaluations=1)  # fmt: skip


def _stub_two_first_passes(tracker, model, mirror_fit: float) -> None:
    """Make the tracker's first passes return their start pose, fitting 0.80 (the first hypothesis)
    then ``mirror_fit`` (the mirror), with the legs always close enough for the mirror."""
    fits = iter([0.80, mirror_fit])

    def search(obs, start, *args, **kwargs):
        return _stub_estimate(model, start, next(fits)), []

    tracker._search = search
    tracker._legs_close = lambda q: True


def test_swap_margin_keeps_the_first_hypothesis_unless_the_mirror_fits_clearly_better(embedded_session):
    """The mirrored hypothesis replaces the first only when it fits ``swap_margin`` better, except
    on the first frame after a start, where any better fit wins: the decision rule, on first
    passes whose fits are set."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    views = tracking_views(rig, 0.5)
    obs = observe(views, [truth.mask(c, 10) for c in rig.names])
    cases = [(False, 0.01, 0.805, False), (False, 0.01, 0.815, True), (False, 0.0, 0.805, True),
             (True, 0.01, 0.805, True), (True, 0.01, 0.795, False)]  # fmt: skip
    for fresh, margin, mirror_fit, mirror_wins in cases:
        cfg = load_tracking_config()
        cfg.factored_ipf.swap_margin, cfg.factored_ipf.passes, cfg.factored_ipf.keep_previous = margin, 1, False
        tracker = FactoredIPF(model, SilhouetteLikelihood(views, cfg.beta), cfg, np.random.default_rng(0))
        tracker.start(truth.poses[9])
        tracker._fresh = fresh  # False: as if a frame had been tracked since the start
        _stub_two_first_passes(tracker, model, mirror_fit)
        est = tracker.step(obs)
        assert (est.fit == mirror_fit) == mirror_wins and est.evaluations == 2


@pytest.mark.parametrize(("continuity", "mirror_fit", "mirror_wins"),
                         [(True, 0.795, True), (False, 0.795, False), (True, 0.78, False), (True, 0.82, True)])
def test_swap_continuity_breaks_a_tie_by_the_legs_extrapolated_motion(embedded_session, continuity, mirror_fit,
                                                                       mirror_wins):  # fmt: skip
    """Legs closing in (hip flexions -0.10/+0.10 rad two frames ago, -0.02/+0.02 now): within
    ``swap_margin`` of the first hypothesis (which bounces back, -0.02/+0.02), the mirror (+0.02/-0.02)
    wins with ``swap_continuity`` because it lies nearer the extrapolation +0.06/-0.06; a mirror
    fitting worse than the margin never wins, one fitting better by more always does."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    views = tracking_views(rig, 0.5)
    obs = observe(views, [truth.mask(c, 10) for c in rig.names])
    cfg = load_tracking_config()
    fi = cfg.factored_ipf
    fi.swap_margin, fi.passes, fi.keep_previous, fi.swap_continuity = 0.015, 1, False, continuity
    tracker = FactoredIPF(model, SilhouetteLikelihood(views, cfg.beta), cfg, np.random.default_rng(0))
    hips = [model.dof_index("hip_flexion_l"), model.dof_index("hip_flexion_r")]
    before, previous = truth.poses[9].copy(), truth.poses[9].copy()
    before[hips], previous[hips] = [-0.10, 0.10], [-0.02, 0.02]
    knees = [model.dof_index("knee_flexion_l"), model.dof_index("knee_flexion_r")]
    before[knees] = previous[knees] = 0.3  # the mirror moves the hips only
    tracker.start(previous)
    tracker._fresh, tracker._before = False, before  # as if frames t-2 and t-1 had been tracked
    _stub_two_first_passes(tracker, model, mirror_fit)
    est = tracker.step(obs)
    assert (est.fit == mirror_fit) == mirror_wins
    assert np.allclose(est.q[hips], [0.02, -0.02] if mirror_wins else [-0.02, 0.02])
    assert np.array_equal(tracker._before, previous)  # the next frame extrapolates from this one


@pytest.mark.parametrize(("swap_hypothesis", "searches"), [(True, 4), (False, 2)])
def test_recovery_searches_the_mirror_only_with_the_swap_hypothesis(embedded_session, swap_hypothesis, searches):
    """A dropped fit: the first pass, (the mirror,) then the widened search from the previous
    estimate (and from its mirror): first passes counted with a stubbed search."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    views = tracking_views(rig, 0.5)
    cfg = load_tracking_config()
    cfg.factored_ipf.swap_hypothesis, cfg.factored_ipf.passes = swap_hypothesis, 1
    cfg.factored_ipf.keep_previous = False  # the first passes' fits are the stand-ins' alone
    tracker = FactoredIPF(model, SilhouetteLikelihood(views, cfg.beta), cfg, np.random.default_rng(0))
    tracker.start(truth.poses[9])
    tracker._fits.extend([0.9, 0.9, 0.9])
    widens = []

    def search(obs, start, widen, *args, **kwargs):
        widens.append(widen)
        return _stub_estimate(model, start, 0.7), []

    tracker._search = search
    est = tracker.step(observe(views, [truth.mask(c, 10) for c in rig.names]))
    assert len(widens) == searches and est.evaluations == searches
    assert widens[-1] == cfg.factored_ipf.recover_widen and widens[0] == 1.0


@pytest.mark.parametrize(("moved_deg", "turn_widen", "frames", "turning", "widened"),
                         [(5.0, 2.0, 1, 0, True), (-5.0, 2.0, 1, 0, True), (4.0, 2.0, 1, 0, False),
                          (5.0, None, 1, 0, False), (360.0 - 5.0, 2.0, 1, 0, True), (360.0 - 4.0, 2.0, 1, 0, False),
                          (5.0, 2.0, 2, 1, True), (-5.0, 2.0, 2, -1, True), (5.0, 2.0, 2, 0, False),
                          (5.0, 2.0, 2, -1, False), (4.0, 2.0, 2, 1, False)])  # fmt: skip
def test_turn_widens_the_heading_alone_in_the_first_passes(embedded_session, moved_deg, turn_widen, frames, turning,
                                                           widened):  # fmt: skip
    """The heading moved ``moved_deg`` between the last two frames (its interval 6 deg, the trigger
    0.8 of it: 4.8 deg; 355 deg is a 5 deg move across the wrap), and ``turning`` frames before
    that the same way (negative: the other way): with ``turn_frames`` such frames running the
    frame's first passes (the first hypothesis and the mirror) search the heading on ``turn_widen``
    times its interval and every other DOF on its own; the further passes on the usual intervals."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    views = tracking_views(rig, 0.5)
    cfg = load_tracking_config()
    fi = cfg.factored_ipf
    fi.turn_widen, fi.turn_trigger, fi.turn_frames, fi.keep_previous = turn_widen, 0.8, frames, False
    assert np.isclose(cfg.half_widths(model)[model.dof_index("pelvis_rotation")], np.radians(6.0))
    tracker = FactoredIPF(model, SilhouetteLikelihood(views, cfg.beta), cfg, np.random.default_rng(0))
    previous = truth.poses[9].copy()
    tracker.start(previous)
    before = previous.copy()
    before[model.dof_index("pelvis_rotation")] -= np.radians(moved_deg)
    tracker._fresh, tracker._before, tracker._turning = False, before, turning
    tracker._legs_close = lambda q: True  # the mirror is searched too
    calls = []

    def search(obs, start, widen, first, stop, *args, **kwargs):
        calls.append((first, np.broadcast_to(np.asarray(widen, float), (model.n_dofs,)).copy()))
        return _stub_estimate(model, start, 0.8), []

    tracker._search = search
    tracker.step(observe(views, [truth.mask(c, 10) for c in rig.names]))
    first = [w for p, w in calls if p == 0]
    further = [w for p, w in calls if p > 0]
    assert len(first) == 2 and len(further) == 1
    expected = np.ones(model.n_dofs)
    if widened:
        expected[model.dof_index("pelvis_rotation")] = turn_widen
    assert all(np.array_equal(w, expected) for w in first), first
    assert np.array_equal(further[0], np.ones(model.n_dofs))


def test_turn_widening_follows_a_heading_turned_beyond_the_usual_reach(embedded_session):
    """The previous estimate's heading 14 deg behind the truth's, the frame before that 24 deg
    behind and the one before turning the same way (a pivot turning 10 deg a frame): the usual intervals (6 deg, two layers and a further
    pass: at most 8 deg in a frame) cannot catch up, the widened heading can. For each of four
    tracker seeds (paired), the heading ends nearer the truth with ``turn_widen`` 2 than without;
    and within 5 deg on average where the usual search stays further off."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    views = tracking_views(rig, 0.5)
    yaw, t = model.dof_index("pelvis_rotation"), 20
    obs = observe(views, [truth.mask(c, t) for c in rig.names])

    def heading_error(turn_widen, seed):
        cfg = load_tracking_config()
        cfg.factored_ipf.turn_widen = turn_widen
        tracker = FactoredIPF(model, SilhouetteLikelihood(views, cfg.beta), cfg, np.random.default_rng(seed))
        previous, before = truth.poses[t - 1].copy(), truth.poses[t - 2].copy()
        previous[yaw] = truth.poses[t, yaw] - np.radians(14)
        before[yaw] = truth.poses[t, yaw] - np.radians(24)
        tracker.start(previous)
        tracker._fresh, tracker._before, tracker._turning = False, before, 1
        q = tracker.step(obs).q
        return float(np.degrees(abs(q[yaw] - truth.poses[t, yaw])))

    widened = np.array([heading_error(2.0, seed) for seed in range(4)])
    usual = np.array([heading_error(None, seed) for seed in range(4)])
    assert np.all(widened < usual), (widened, usual)
    assert widened.mean() < 5 < usual.mean(), (widened, usual)


def test_stages_leave_an_inner_stage_out_of_the_outer_one():
    stages = Stages()
    with stages.timed("outer"):
        with stages.timed("inner"):
            time.sleep(0.05)
        time.sleep(0.02)
    with stages.timed("inner"):  # a stage timed twice adds up
        time.sleep(0.01)
    assert list(stages) == ["inner", "outer"]
    assert 0.06 <= stages["inner"] < 0.5
    assert 0.02 <= stages["outer"] < 0.05 + 0.02  # not the 0.07 s it was open


def test_a_run_summary_crosses_to_the_batch_process(tracked_session):
    """``gaitcap track FOLDER --jobs N`` returns each worker's summary to the parent pickled."""
    _, _, summary = tracked_session
    again = pickle.loads(pickle.dumps(summary))
    assert again == summary and "tracking" in again.stages and again.verdict == summary.verdict


def test_track_json_holds_the_verdict(tracked_session):
    _, out, summary = tracked_session
    doc = json.loads((out / "track.json").read_text())
    assert doc["verdict"] == summary.verdict and doc["verdict"] in ("ok", "doubtful", "failed")
    assert doc["verdict_reasons"] == summary.verdict_reasons
    assert (doc["verdict"] == "ok") == (doc["verdict_reasons"] == [])
    assert doc["verdict_notes"] == summary.verdict_notes and isinstance(doc["verdict_notes"], list)


def test_track_json_records_the_options_of_the_run(tracked_session):
    """track.json's options: what a batch compares before skipping a finished session (gaitcap.batch)."""
    from gaitcap.track_summary import changed_options, run_options

    _, out, _ = tracked_session
    recorded = json.loads((out / "track.json").read_text())["options"]
    assert recorded == run_options(max_frames=20)  # the fixture's run: shipped configurations, 20 frames
    assert recorded["tracker"] == "factored-ipf" and recorded["max_frames"] == 20 and recorded["body"] is None
    assert changed_options(recorded, run_options(max_frames=20)) == ""


def test_the_seed_can_be_given_alone_and_draws_another_run(embedded_session, tmp_path):
    """--seed (run_track's ``seed``) overrides the configuration's seed without a whole -c file: recorded in
    track.json's options and the run's configuration, and another seed draws another run."""
    config = quick_tracking(tmp_path)
    poses = {}
    for seed in (None, 5):
        out = tmp_path / f"seed{seed}"
        run_track(embedded_session.session, out, config=config, progress=False, max_frames=3, seed=seed)
        assert json.loads((out / "track.json").read_text())["options"]["seed"] == (seed or 0)
        with h5py.File(out / "trajectories.h5") as f:
            assert yaml.safe_load(f.attrs["config"])["seed"] == (seed or 0)
            poses[seed] = f["poses"][()]
    assert not np.array_equal(poses[None], poses[5])


def test_track_json_records_the_stage_times(tracked_session):
    _, out, summary = tracked_session
    stages = json.loads((out / "track.json").read_text())["stages_s"]
    main_thread = ["setup", "kernels", "first_frames", "initialisation", "shape_window", "shape", "shape_settle",
                   "tracking", "verdict", "writing"]  # fmt: skip
    if load_tracking_config().backward.enabled:
        main_thread.append("backward")
    assert set(stages) == set(main_thread) | {"background"}
    assert all(v >= 0 for v in stages.values())
    # the main thread's stages follow one another: together they take (nearly) the whole run
    assert 0.8 * summary.seconds <= sum(stages[k] for k in main_thread) <= summary.seconds + 0.01


def test_shape_limits_must_name_parameters_and_hold_one(tmp_path):
    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["shape"]["limits"]["thigh_lenght"] = [0.9, 1.1]
    config = tmp_path / "tracking.yaml"
    config.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"shape\.limits: thigh_lenght not in shape\.parameters"):
        load_tracking_config(config, model=load_body_model())
    del data["shape"]["limits"]["thigh_lenght"]
    data["shape"]["limits"]["thigh_length"] = [1.05, 1.2]
    config.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"thigh_length: a range must satisfy 0 < low <= 1 <= high"):
        load_tracking_config(config, model=load_body_model())


def test_shape_defaults_of_the_schema_are_the_shipped_ones():
    """A config that leaves a shape key out gets the shipped value (only on/off, the parameters and
    their ranges are the schema's own: off and empty)."""
    from gaitcap.tracking.config import ShapeConfig

    shipped = yaml.safe_load(default_config_path("tracking.yaml").read_text())["shape"]
    schema = ShapeConfig().model_dump()
    differ = {k: (schema[k], v) for k, v in shipped.items()
              if k not in ("enabled", "parameters", "limits", "ranges") and schema[k] != (tuple(v) if isinstance(v, list) and isinstance(schema[k], tuple) else v)}  # fmt: skip
    assert differ == {}


def test_a_clip_of_one_frame_skips_the_shape_calibration_for_that_reason(embedded_session, caplog):
    """One frame (``--max-frames 1``): the calibration is skipped as having one frame, not as a subject out
    of view (the frame has it in view; the reason is kept in track.json and shown again by --body)."""
    from gaitcap import pipeline
    from gaitcap.prefetch import Head

    truth, rig, model = _truth_setup(embedded_session.session)
    cfg = load_tracking_config()
    cfg.init.frames, cfg.shape.frames = 1, 10
    views = tracking_views(rig, cfg.scale)
    head = Head(iter([observe(views, [truth.mask(c, 0) for c in rig.names])]), 10)
    lik = SilhouetteLikelihood(views, cfg.beta)
    filt = pipeline._new_tracker(cfg, model, lik)
    note = pipeline._calibrate_shape(filt, lik, views, cfg, head)[3]
    assert note == "skipped: 1 frame to calibrate on"
    assert "shape calibration skipped: 1 frame to calibrate on" in caplog.text and "not in every view" not in caplog.text


@pytest.mark.parametrize(("gone_at", "note"), [(None, "skipped: no subject"),
                                               (9, "skipped: subject not in view in the first frames")])
def test_the_initialisation_starts_before_the_shape_window_is_read(embedded_session, monkeypatch, gone_at, note):
    """The shape calibration initialises on the first ``init.frames`` frames while the rest of the
    window is still being read; a window frame out of view skips the calibration whatever the
    initialisation did (as when the window was checked before it)."""
    from gaitcap import pipeline
    from gaitcap.errors import TrackingError
    from gaitcap.prefetch import Head

    truth, rig, model = _truth_setup(embedded_session.session)
    cfg = load_tracking_config()
    cfg.init.frames, cfg.shape.frames = 4, 10
    views = tracking_views(rig, cfg.scale)
    masks = [[truth.mask(c, t) for c in rig.names] for t in range(10)]
    if gone_at is not None:
        masks[gone_at] = [np.zeros_like(m) for m in masks[gone_at]]
    head = Head(iter([observe(views, m) for m in masks]), 10)
    read_at_init = []

    def initialise(*args, **kwargs):
        read_at_init.append(len(head.items))
        raise TrackingError("no subject")

    monkeypatch.setattr(pipeline, "initialise", initialise)
    lik = SilhouetteLikelihood(views, cfg.beta)
    filt = pipeline._new_tracker(cfg, model, lik)
    tracker, start, settled, shape_note, problems = pipeline._calibrate_shape(filt, lik, views, cfg, head)
    assert read_at_init == [4]  # the window's other 6 frames were not read yet
    assert len(head.items) == 10
    assert tracker is filt and start is None and not settled and problems == []
    assert shape_note == note


def test_factored_ipf_without_uncertainty_tracks_the_same(embedded_session):
    """``uncertainty=False`` (the shape re-fits) leaves the poses, points and fits as they were, the
    uncertainty NaN; a tracker reusing its scratch arrays over frames equals one started afresh."""
    from gaitcap.tracking.factored_ipf import FactoredIPF

    truth, rig, model = _truth_setup(embedded_session.session)
    cfg = load_tracking_config()
    views = tracking_views(rig, cfg.scale)
    lik = SilhouetteLikelihood(views, cfg.beta)
    obs = [observe(views, [truth.mask(c, t) for c in rig.names]) for t in (10, 11)]
    kept, plain = (FactoredIPF(model, lik, cfg, np.random.default_rng(0), uncertainty=u) for u in (True, False))
    for tracker in (kept, plain):
        tracker.start(truth.poses[9], fresh=False)
    for o in obs:
        a, b = kept.step(o), plain.step(o)
        assert np.array_equal(a.q, b.q) and np.array_equal(a.points, b.points) and a.fit == b.fit
        assert np.all(np.isfinite(a.uncertainty)) and np.all(np.isnan(b.uncertainty))
    fresh = FactoredIPF(model, lik, cfg, np.random.default_rng(0))
    fresh.start(truth.poses[9], fresh=False)
    fresh.step(obs[0])
    again = FactoredIPF(model, lik, cfg, np.random.default_rng(0))
    again.start(truth.poses[9], fresh=False)
    again.step(obs[0])
    again._scratch(obs[0])[0][0][:] = 1.0  # stale masks are zeroed before use
    assert np.array_equal(fresh.step(obs[1]).q, again.step(obs[1]).q)
