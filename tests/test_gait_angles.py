"""Joint angles: known poses give the known angles and Plug-in-Gait signs."""

from __future__ import annotations

import numpy as np
import pytest

from gaitcap.gait.angles import cardan_yxz, joint_angles
from gaitcap.gait.events import WalkingDirection
from gaitcap.trajectory import POINT_NAMES, Trajectory

FWD = WalkingDirection(np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), "test", 1.0, False)


def _leg(hip_flex: float, knee_flex: float, dorsi: float) -> dict[str, np.ndarray]:
    """Sagittal leg (walking +x) relative to the hip: knee, ankle, heel, toe."""
    th, kn = np.radians(hip_flex), np.radians(knee_flex)
    knee = 0.45 * np.array([np.sin(th), 0, -np.cos(th)])
    sh = th - kn
    ankle = knee + 0.42 * np.array([np.sin(sh), 0, -np.cos(sh)])
    fa = sh + np.pi / 2 + np.radians(dorsi)
    fdir = np.array([np.sin(fa), 0, -np.cos(fa)])
    heel = ankle - 0.05 * fdir + np.array([0, 0, -0.07])
    return {"knee": knee, "ankle": ankle, "heel": heel, "toe": heel + 0.2 * fdir}


def _pose(left: dict, right: dict, hips: dict | None = None, rot: np.ndarray | None = None) -> Trajectory:
    hips = hips or {"l": np.array([0, 0.09, 0.9]), "r": np.array([0, -0.09, 0.9])}
    P = np.full((1, len(POINT_NAMES), 3), np.nan)
    rot = np.eye(3) if rot is None else rot
    for s, leg in (("l", left), ("r", right)):
        P[0, POINT_NAMES.index(f"hip_{s}")] = hips[s]
        for name, v in leg.items():
            P[0, POINT_NAMES.index(f"{name}_{s}")] = hips[s] + rot @ v
    P[0, POINT_NAMES.index("pelvis")] = 0.5 * (hips["l"] + hips["r"])
    return Trajectory(POINT_NAMES, P, 100.0)


@pytest.mark.parametrize(("hip", "knee", "ankle"), [(30, 40, 10), (-10, 5, -20), (0, 60, 0), (15, 0, -5)])
def test_sagittal_angles_are_recovered_on_both_sides(hip: float, knee: float, ankle: float) -> None:
    tr = _pose(_leg(hip, knee, ankle), _leg(hip, knee, ankle))
    ang, _ = joint_angles(tr, FWD)
    for s in ("_l", "_r"):
        assert ang[f"hip_flexion{s}"][0] == pytest.approx(hip, abs=1e-6)
        assert ang[f"knee_flexion{s}"][0] == pytest.approx(knee, abs=1e-6)
        assert ang[f"ankle_dorsiflexion{s}"][0] == pytest.approx(ankle, abs=1e-6)
        assert ang[f"hip_adduction{s}"][0] == pytest.approx(0.0, abs=1e-6)
        assert ang[f"pelvis_tilt{s}"][0] == pytest.approx(0.0, abs=1e-6)


def test_hip_adduction_is_positive_when_the_knee_moves_medially_on_each_side() -> None:
    def add(deg: float, medial_sign: float) -> np.ndarray:
        a = np.radians(deg) * medial_sign
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    leg = _leg(0, 30, 0)
    # the right knee moves medially towards +y: rotate about +x by +angle; the left one mirrored
    tr_r = _pose(leg, leg, rot=add(10, 1))
    tr_l = _pose(leg, leg, rot=add(10, -1))
    assert joint_angles(tr_r, FWD)[0]["hip_adduction_r"][0] == pytest.approx(10.0, abs=0.5)
    assert joint_angles(tr_l, FWD)[0]["hip_adduction_l"][0] == pytest.approx(10.0, abs=0.5)


def test_pelvis_obliquity_and_rotation_signs() -> None:
    leg = _leg(0, 20, 0)
    up_left = {"l": np.array([0, 0.09, 0.92]), "r": np.array([0, -0.09, 0.88])}
    ang, _ = joint_angles(_pose(leg, leg, hips=up_left), FWD)
    assert ang["pelvis_obliquity_l"][0] > 5 and ang["pelvis_obliquity_r"][0] < -5
    right_fwd = {"l": np.array([-0.03, 0.09, 0.9]), "r": np.array([0.03, -0.09, 0.9])}
    ang, _ = joint_angles(_pose(leg, leg, hips=right_fwd), FWD)
    assert ang["pelvis_rotation_r"][0] > 5 and ang["pelvis_rotation_l"][0] < -5
    assert ang["pelvis_rotation_r"][0] == pytest.approx(np.degrees(np.arctan2(0.06, 0.18)), abs=1e-6)


def test_angles_do_not_depend_on_the_walking_heading() -> None:
    c, s = np.cos(np.radians(130)), np.sin(np.radians(130))
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    tr = _pose(_leg(25, 35, 5), _leg(-5, 10, -10))
    rotated = Trajectory(tr.names, tr.points @ R.T, tr.rate_hz)
    d = WalkingDirection(R @ FWD.forward, R @ FWD.left, "test", 1.0, False)
    a0, a1 = joint_angles(tr, FWD)[0], joint_angles(rotated, d)[0]
    for k in a0:
        assert a1[k][0] == pytest.approx(a0[k][0], abs=1e-6), k


def test_a_subject_walking_backwards_keeps_the_pelvis_angles_of_the_way_it_faces() -> None:
    """The pose facing +x (obliquity, rotation and sagittal angles set) walked the other way (-x, a
    subject walking backwards): every angle is that of the walk facing its direction, pelvis
    rotation near 0 rather than 180 degrees and tilt and obliquity with their usual signs."""
    tilted = {"l": np.array([-0.03, 0.09, 0.92]), "r": np.array([0.03, -0.09, 0.88])}
    tr = _pose(_leg(25, 35, 5), _leg(-5, 10, -10), hips=tilted)
    thorax = np.array([0.04, 0.0, 1.4])  # leaning forward: anterior "tilt" of the pelvis-thorax line
    pts = tr.points.copy()
    pts[0, POINT_NAMES.index("thorax")] = thorax
    tr = Trajectory(tr.names, pts, tr.rate_hz)
    backwards = WalkingDirection(-FWD.forward, -FWD.left, "test", 1.0, False)
    a0, a1 = joint_angles(tr, FWD)[0], joint_angles(tr, backwards)[0]
    assert a0["pelvis_tilt_l"][0] > 1 and a0["pelvis_obliquity_l"][0] > 5 and a0["pelvis_rotation_r"][0] > 5
    for k in a0:
        assert a1[k][0] == pytest.approx(a0[k][0], abs=1e-6), k


def test_missing_points_give_nan_angles_not_errors() -> None:
    tr = _pose(_leg(20, 30, 0), _leg(20, 30, 0))
    pts = np.repeat(tr.points, 3, axis=0)
    pts[1, POINT_NAMES.index("knee_l")] = np.nan
    ang, _ = joint_angles(Trajectory(tr.names, pts, 100.0), FWD)
    assert np.isnan(ang["knee_flexion_l"][1]) and np.isnan(ang["hip_flexion_l"][1])
    assert ang["knee_flexion_l"][0] == pytest.approx(30.0)
    assert ang["knee_flexion_r"][1] == pytest.approx(30.0)


def test_cardan_identity_is_zero() -> None:
    eye = np.broadcast_to(np.eye(3), (2, 3, 3))
    assert np.allclose(cardan_yxz(eye, eye), 0.0)


@pytest.mark.parametrize("knee", [5.0, 40.0])
def test_knee_and_ankle_do_not_need_the_pelvis_markers(knee: float) -> None:
    """A marker file whose ASIS markers are in a gap (C3D.ORG's gait-pig.c3d from 2.28 s to its end) has no
    pelvis frame there, yet its hip, knee and ankle centres: every angle was NaN, knee and ankle too, so the
    report's second left cycle had no knee curve at all (found comparing cycles.h5 with the file's own
    angles). Now the knee and ankle take the hip centres' line where the pelvis frame is missing; the pelvis
    and hip angles, which need it, stay NaN."""
    tr = _pose(_leg(20, knee, 5), _leg(20, knee, 5))
    asis = {"LASI": [0.05, 0.12, 0.95], "RASI": [0.05, -0.12, 0.95], "SACR": [-0.12, 0.0, 0.97]}
    pts = np.concatenate([tr.points, np.array([[v for v in asis.values()]])], axis=1)
    pts = np.repeat(pts, 2, axis=0)
    pts[1, len(POINT_NAMES):] = np.nan  # frame 1: the pelvis markers in a gap
    ang, notes = joint_angles(Trajectory(POINT_NAMES + tuple(asis), pts, 100.0), FWD)
    assert notes["pelvis_frame"] == "ASIS/PSIS markers"
    for s in ("_l", "_r"):
        assert ang[f"knee_flexion{s}"] == pytest.approx([knee, knee], abs=1e-6)
        assert ang[f"ankle_dorsiflexion{s}"] == pytest.approx([5.0, 5.0], abs=1e-6)
        assert np.isfinite(ang[f"hip_flexion{s}"][0]) and np.isnan(ang[f"hip_flexion{s}"][1])
        assert np.isnan(ang[f"pelvis_tilt{s}"][1])
