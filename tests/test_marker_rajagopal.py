"""The OpenSim Rajagopal model's marker set: chosen automatically, joint centres near the
source walk's own (fixture: the Vicon Plug-in-Gait walk relabelled, see
fixtures/walking/make_rajagopal_walk.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from click.testing import CliRunner

from gaitcap.cli.main import cli
from gaitcap.markers.jointcentres import apply_mapping
from gaitcap.markers.mapping import load_mapping
from gaitcap.markers.motion import read_markers, read_motion

WALKING = Path(__file__).resolve().parent / "fixtures" / "walking"
RAJAGOPAL = WALKING / "rajagopal_walk.trc"
SOURCE = WALKING / "rajagopal_walk_source_centres.trc"  # the source's PiG joint centres


def _distance_mm(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.norm(a - b, axis=1) * 1000.0


def test_rajagopal_set_is_chosen_and_gives_the_sources_joint_centres():
    joints, source = read_motion(RAJAGOPAL), read_motion(SOURCE)
    assert joints.meta["mapping"] == "opensim_rajagopal"
    assert joints.n_frames == source.n_frames == 111
    for side in ("l", "r"):
        # condyles and malleoli sit symmetrically about the source's centres: the mid-points
        assert _distance_mm(joints.point(f"knee_{side}"), source.point(f"knee_{side}")).max() < 1.0
        assert _distance_mm(joints.point(f"ankle_{side}"), source.point(f"ankle_{side}")).max() < 1.0
        # Harrington's hips against Plug-in-Gait's (a different regression): within 4 cm
        assert np.median(_distance_mm(joints.point(f"hip_{side}"), source.point(f"hip_{side}"))) < 40.0
        foot = _distance_mm(joints.point(f"toe_{side}"), joints.point(f"heel_{side}"))
        assert 150 < np.median(foot) < 260  # heel (CAL) to ball of the foot (TOE/MT5)
        assert np.nanpercentile(joints.point(f"heel_{side}")[:, 2], 5) < 0.02  # on the floor


def test_without_medial_markers_the_lateral_ones_are_moved_medially():
    markers = read_markers(RAJAGOPAL)
    lateral_only = markers.subset(n for n in markers.names if n not in ("RMFC", "LMFC", "RMMAL", "LMMAL"))
    joints, source = apply_mapping(load_mapping("opensim_rajagopal"), lateral_only), read_motion(SOURCE)
    for point in ("knee_l", "knee_r", "ankle_l", "ankle_r"):
        err = _distance_mm(joints.point(point), source.point(point))
        lateral = _distance_mm(markers.point({"knee_l": "LLFC", "knee_r": "RLFC", "ankle_l": "LLMAL",
                                              "ankle_r": "RLMAL"}[point]), source.point(point))  # fmt: skip
        assert np.median(err) < 15.0 and np.median(err) < 0.3 * np.median(lateral)


def test_markers_command_names_the_rajagopal_mapping():
    res = CliRunner().invoke(cli, ["markers", str(RAJAGOPAL)])
    assert res.exit_code == 0, res.output
    assert "mapping opensim_rajagopal: fits" in res.output and "mean(RLFC, RMFC)" in res.output
