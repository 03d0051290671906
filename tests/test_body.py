from __future__ import annotations

import numpy as np
import pytest
import yaml

from gaitcap.body import load_body_model
from gaitcap.body.model import axis_rotation, load_body_spec
from gaitcap.config import default_config_path
from gaitcap.errors import ConfigError
from gaitcap.trajectory import POINT_NAMES

BONES = [("hip_l", "knee_l"), ("knee_l", "ankle_l"), ("hip_r", "knee_r"), ("knee_r", "ankle_r"),
         ("ankle_l", "heel_l"), ("ankle_l", "toe_l"), ("hip_l", "hip_r"), ("shoulder_l", "elbow_l"),
         ("elbow_r", "wrist_r"), ("thorax", "neck"), ("neck", "head")]


@pytest.fixture(scope="module")
def model():
    return load_body_model(height_m=1.75)


def _random_poses(model, rng, n):
    lo = np.where(np.isfinite(model.lower), model.lower, -2.0)
    hi = np.where(np.isfinite(model.upper), model.upper, 2.0)
    return rng.uniform(lo, hi, size=(n, model.n_dofs))


def test_model_has_31_dofs_and_all_points(model):
    assert model.n_dofs == 31
    assert model.point_names == POINT_NAMES
    assert len(model.segments) == 13


def test_neutral_pose_stands_on_the_floor(model):
    q = model.neutral_pose(heading_rad=0.3, x=1.0, y=-2.0)
    pts = model.forward(q[None])[0]
    assert pts[:, 2].min() == pytest.approx(0.0, abs=1e-12)
    head = pts[model.point_index("head")]
    assert 0.85 * 1.75 < head[2] < 1.75
    pelvis = pts[model.point_index("pelvis")]
    np.testing.assert_allclose(pelvis[:2], [1.0, -2.0])
    # standing hip height about 0.53 H (Winter 2009)
    assert pelvis[2] == pytest.approx(0.53 * 1.75, rel=0.02)


def test_bone_lengths_constant_over_random_poses(model, rng):
    q = _random_poses(model, rng, 500)
    pts = model.forward(q)
    ref = model.forward(model.neutral_pose()[None])[0]
    for a, b in BONES:
        ia, ib = model.point_index(a), model.point_index(b)
        lengths = np.linalg.norm(pts[:, ia] - pts[:, ib], axis=1)
        expected = np.linalg.norm(ref[ia] - ref[ib])
        np.testing.assert_allclose(lengths, expected, rtol=1e-10, err_msg=f"{a}-{b}")


def test_forward_is_vectorised_consistently(model, rng):
    q = _random_poses(model, rng, 64)
    batch = model.forward(q)
    single = np.stack([model.forward(q[i : i + 1])[0] for i in range(len(q))])
    np.testing.assert_allclose(batch, single)
    assert batch.shape == (64, 20, 3)


def test_clinical_sign_conventions(model):
    q0 = model.neutral_pose()
    base = model.forward(q0[None])[0]

    def moved(dof, deg):
        q = q0.copy()
        q[model.dof_index(dof)] = np.radians(deg)
        return model.forward(q[None])[0]

    k = model.point_index
    # hip flexion brings the knee forward (+x, the body faces +x at heading 0)
    assert moved("hip_flexion_l", 30)[k("knee_l"), 0] > base[k("knee_l"), 0] + 0.1
    # knee flexion takes the ankle backwards
    assert moved("knee_flexion_r", 40)[k("ankle_r"), 0] < base[k("ankle_r"), 0] - 0.1
    # ankle dorsiflexion raises the toe
    assert moved("ankle_dorsiflexion_l", 20)[k("toe_l"), 2] > base[k("toe_l"), 2] + 0.01
    # hip adduction moves the knee towards the midline, on both sides
    assert moved("hip_adduction_l", 15)[k("knee_l"), 1] < base[k("knee_l"), 1] - 0.05
    assert moved("hip_adduction_r", 15)[k("knee_r"), 1] > base[k("knee_r"), 1] + 0.05
    # internal hip rotation with a flexed knee swings the ankle outwards
    q = q0.copy()
    q[model.dof_index("knee_flexion_l")] = np.radians(90)
    flexed = model.forward(q[None])[0]
    q[model.dof_index("hip_rotation_l")] = np.radians(30)
    assert model.forward(q[None])[0][k("ankle_l"), 1] > flexed[k("ankle_l"), 1] + 0.1
    # anterior pelvic tilt brings the thorax forward
    assert moved("pelvis_tilt", 20)[k("thorax"), 0] > base[k("thorax"), 0] + 0.02
    # heading 90 degrees faces +y
    turned = moved("pelvis_rotation", 90)
    foot = turned[k("toe_l")] - turned[k("heel_l")]
    assert foot[1] > 0.15 and abs(foot[0]) < 1e-9


def test_clip_enforces_limits_and_wraps_heading(model, rng):
    q = rng.normal(0, 5, size=(200, model.n_dofs))
    c = model.clip(q)
    assert model.within_limits(c).all()
    h = model.dof_index("pelvis_rotation")
    assert np.all((c[:, h] >= -np.pi) & (c[:, h] < np.pi))
    np.testing.assert_allclose(np.cos(c[:, h]), np.cos(q[:, h]))


def test_capsules_contain_their_points(model, rng):
    """Every named point lies inside the body volume (needed for the synth's truth-in-mask check)."""
    q = _random_poses(model, rng, 50)
    pts = model.forward(q)
    A, B, r = model.capsules(q)
    ab = B - A
    d = pts[:, :, None, :] - A[:, None]  # (N, P, C, 3)
    t = np.clip(np.einsum("npcj,ncj->npc", d, ab) / np.einsum("ncj,ncj->nc", ab, ab)[:, None], 0, 1)
    closest = A[:, None] + t[..., None] * ab[:, None]
    dist = np.linalg.norm(pts[:, :, None] - closest, axis=-1)
    radius = r[None, None, :, 0] + t * (r[None, None, :, 1] - r[None, None, :, 0])
    inside = (dist < radius).any(axis=2)
    assert inside.all(), [model.point_names[i] for i in np.where(~inside.all(axis=0))[0]]


def test_scales_change_lengths(model):
    scaled = model.with_proportions({"thigh_l": (1.0, 1.0, 1.2)})
    q = scaled.neutral_pose()
    p = scaled.forward(q[None])[0]
    thigh = np.linalg.norm(p[scaled.point_index("hip_l")] - p[scaled.point_index("knee_l")])
    assert thigh == pytest.approx(0.245 * 1.75 * 1.2, rel=1e-9)


def _spec_with(tmp_path, edit):
    data = yaml.safe_load(default_config_path("body.yaml").read_text())
    edit(data)
    path = tmp_path / "body.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))  # the segments in order, parents first
    return path


def test_unknown_key_is_rejected_with_suggestion(tmp_path):
    path = _spec_with(tmp_path, lambda d: d["segments"]["thigh_l"].update(orgin=[0, 0, 0]))
    with pytest.raises(ConfigError, match=r"segments\.thigh_l\.orgin: unknown key \(did you mean 'origin'\?\)"):
        load_body_spec(path)


def test_min_greater_than_max_names_the_key(tmp_path):
    path = _spec_with(tmp_path, lambda d: d["segments"]["shank_l"]["dofs"][0].update(limits=[90, 10]))
    with pytest.raises(ConfigError, match=r"body.yaml: segments\.shank_l\.dofs\.0\.limits.*greater than max"):
        load_body_spec(path)


def test_impossible_rotation_limits_and_a_wrapped_translation_are_rejected(tmp_path):
    """body.yaml's "impossible values are rejected": a knee limit of 400 degrees and wrap on a translation
    were accepted."""
    path = _spec_with(tmp_path, lambda d: d["segments"]["shank_l"]["dofs"][0].update(limits=[-10, 400]))
    with pytest.raises(ConfigError, match=r"segments\.shank_l\.dofs\.0: .*knee_flexion_l: limits \[-10\.0, 400\.0\] "
                                          r"must lie within \[-180, 180\] degrees"):
        load_body_spec(path)
    path = _spec_with(tmp_path, lambda d: d["segments"]["pelvis"]["dofs"][0].update(wrap=True))
    with pytest.raises(ConfigError, match=r"segments\.pelvis\.dofs\.0: .*pelvis_tx: wrap is for an angle"):
        load_body_spec(path)
    path = _spec_with(tmp_path, lambda d: d["segments"]["pelvis"]["dofs"][2].update(limits=[-5, 400]))
    load_body_spec(path)  # a translation's limits are metres, not bound to a half turn


def test_negative_radius_and_non_finite_values_rejected(tmp_path):
    path = _spec_with(tmp_path, lambda d: d["segments"]["foot_r"]["shapes"][0].update(radius=-0.01))
    with pytest.raises(ConfigError, match=r"segments\.foot_r\.shapes\.0\.radius.*positive"):
        load_body_spec(path)
    path = _spec_with(tmp_path, lambda d: d["segments"]["torso"].update(origin=[0, 0, float("nan")]))
    with pytest.raises(ConfigError, match=r"segments\.torso\.origin.*finite"):
        load_body_spec(path)


def test_parent_must_come_first(tmp_path):
    def edit(d):
        segs = d["segments"]
        d["segments"] = {"shank_l": segs.pop("shank_l"), **segs}

    with pytest.raises(ConfigError, match="shank_l"):
        load_body_spec(_spec_with(tmp_path, edit))


def test_bad_poses_shape_is_an_error(model):
    with pytest.raises(ValueError, match=r"\(N, 31\)"):
        model.forward(np.zeros((3, 30)))


def test_local_angles_invert_local_rotation(model, rng):
    """For every joint with three rotations about distinct axes (lumbar, hips, shoulders), the
    angles recovered from the joint's rotation are the angles that made it."""
    joints = [s for s in model.segments if s.n_dofs == 3 and not any(s.translation)]
    assert {s.name for s in joints} >= {"torso", "thigh_l", "thigh_r"}
    for seg in joints:
        q = rng.uniform(-1.2, 1.2, size=(50, 3))
        q[:, 1] = rng.uniform(-1.4, 1.4, size=50)  # the middle angle within +-90 degrees
        np.testing.assert_allclose(model.local_angles(seg, model.local_rotation(seg, q)), q, atol=1e-9)
    with pytest.raises(ValueError, match="shank_l"):
        model.local_angles(model.segment("shank_l"), np.eye(3)[None])


def test_nearest_angle_inverts_one_dof_joints_and_projects_others(model, rng):
    """For every joint with one rotation (knees, elbows) the angle recovered from its rotation is
    the angle that made it; for a rotation with a component off the axis, the angle returned is
    nearer (larger trace of Rot^T R) than 0.01 rad either side of it."""
    joints = [s for s in model.segments if s.n_dofs == 1 and not any(s.translation)]
    assert {s.name for s in joints} >= {"shank_l", "shank_r"}
    for seg in joints:
        q = rng.uniform(-3.0, 3.0, size=(50, 1))
        np.testing.assert_allclose(model.nearest_angle(seg, model.local_rotation(seg, q)), q[:, 0], atol=1e-9)
        off = model.local_rotation(seg, q) @ axis_rotation((seg.axes[0] + 1) % 3, rng.uniform(-0.3, 0.3, size=50))
        best = model.nearest_angle(seg, off)
        traces = [np.trace(np.swapaxes(model.local_rotation(seg, (best + d)[:, None]), 1, 2) @ off, axis1=1, axis2=2)
                  for d in (-0.01, 0.0, 0.01)]  # fmt: skip
        assert np.all(traces[1] > traces[0]) and np.all(traces[1] > traces[2])
    with pytest.raises(ValueError, match="thigh_l"):
        model.nearest_angle(model.segment("thigh_l"), np.eye(3)[None])
