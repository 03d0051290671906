"""Consistency checks of a synthetic session: the contract ``gaitcap synth`` promises."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gaitcap.io.calibration_toml import read_calibration
from gaitcap.synth.truth import read_truth

#: pairs of points joined by a rigid bone in the body model
BONES: tuple[tuple[str, str], ...] = (
    ("hip_l", "knee_l"), ("knee_l", "ankle_l"), ("hip_r", "knee_r"), ("knee_r", "ankle_r"),
    ("hip_l", "hip_r"), ("ankle_l", "heel_l"), ("ankle_l", "toe_l"), ("ankle_r", "heel_r"), ("ankle_r", "toe_r"),
    ("thorax", "neck"), ("neck", "head"), ("shoulder_l", "elbow_l"), ("elbow_l", "wrist_l"),
    ("shoulder_r", "elbow_r"), ("elbow_r", "wrist_r"),
)  # fmt: skip


def truth_inside_masks(session: str | Path) -> dict[str, float]:
    """Fraction of (frame, point) whose truth projects inside the truth mask, per camera.

    Points are projected with the session's written calibration (with its lens distortion).
    """
    session = Path(session)
    rig = read_calibration(session / "calibration.toml")
    truth = read_truth(session / "truth.h5")
    pts = truth.trajectory.points
    out = {}
    for cam in rig:
        px = np.round(cam.project(pts)).astype(int)  # (T, P, 2)
        hits = total = 0
        for t in range(len(pts)):
            mask = truth.mask(cam.name, t)
            ok = cam.in_image(px[t])
            hits += int(mask[px[t, ok, 1], px[t, ok, 0]].sum())
            total += len(px[t])
        out[cam.name] = hits / total
    return out


def bone_length_variation(session: str | Path) -> dict[str, float]:
    """(max - min) / mean length over the session, per bone of the truth points."""
    truth = read_truth(Path(session) / "truth.h5").trajectory
    out = {}
    for a, b in BONES:
        if truth.has(a) and truth.has(b):
            d = np.linalg.norm(truth.point(a) - truth.point(b), axis=1)
            out[f"{a}-{b}"] = float((d.max() - d.min()) / d.mean())
    return out
