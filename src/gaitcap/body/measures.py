"""Segment lengths measured from joint centres: the tracked model's, a truth's, a marker set's.

One definition for every source, so that the shape calibration's result (``track.json``) and a
truth (``gaitcap eval``) are compared on equal terms. Each length is the median over the frames
where both of its points are known; a length whose points are missing is left out.
"""

from __future__ import annotations

import numpy as np

from gaitcap.body.model import BodyModel

#: length name -> pairs of points whose distances are pooled (left and right alike) for the median
SEGMENTS: dict[str, tuple[tuple[str, str], ...]] = {
    "pelvis_width": (("hip_l", "hip_r"),),
    "thigh": (("hip_l", "knee_l"), ("hip_r", "knee_r")),
    "shank": (("knee_l", "ankle_l"), ("knee_r", "ankle_r")),
    "foot": (("heel_l", "toe_l"), ("heel_r", "toe_r")),
    "upper_arm": (("shoulder_l", "elbow_l"), ("shoulder_r", "elbow_r")),
    "forearm": (("elbow_l", "wrist_l"), ("elbow_r", "wrist_r")),
    "shoulder_width": (("shoulder_l", "shoulder_r"),),
}

#: every length :func:`segment_lengths` may give
LENGTHS = (*SEGMENTS, "leg")


def segment_lengths(point_names: list[str] | tuple[str, ...], points: np.ndarray) -> dict[str, float]:
    """Median segment lengths (metres) of joint centres ``points`` (T, P, 3) named ``point_names``
    (P,); NaN rows are skipped. Lengths of :data:`SEGMENTS` whose points are absent are left out;
    also ``leg``: hip centre to ankle along the thigh and shank, the sum of the two medians."""
    index = {n: i for i, n in enumerate(point_names)}
    P = np.asarray(points, float)
    if P.ndim == 2:
        P = P[None]
    out: dict[str, float] = {}
    for name, pairs in SEGMENTS.items():
        d = [np.linalg.norm(P[:, index[a]] - P[:, index[b]], axis=-1) for a, b in pairs if a in index and b in index]
        if not d:
            continue
        values = np.concatenate(d)
        values = values[np.isfinite(values)]
        if values.size:
            out[name] = float(np.median(values))
    if "thigh" in out and "shank" in out:
        out["leg"] = out["thigh"] + out["shank"]
    return out


def length_errors(measured: dict[str, float], truth: dict[str, float]) -> dict[str, float]:
    """Relative error (measured / truth - 1) of every length both hold."""
    return {k: measured[k] / truth[k] - 1.0 for k in measured if k in truth and truth[k] > 0}


def model_lengths(model: BodyModel) -> dict[str, float]:
    """The segment lengths (metres) of a body model, measured at its neutral pose."""
    return segment_lengths(model.point_names, model.forward(model.neutral_pose()[None]))


def outside_ranges(lengths: dict[str, float], height_m: float, ranges: dict[str, tuple[float, float]]) -> list[str]:
    """Sentences naming each length whose ratio to the height lies outside its (low, high) range."""
    out = []
    for name, (low, high) in ranges.items():
        if name in lengths:
            ratio = lengths[name] / height_m
            if not low <= ratio <= high:
                out.append(f"{name.replace('_', ' ')} {lengths[name]:.3f} m is {ratio:.3f} of the height, outside "
                           f"{low:.2f}-{high:.2f}")  # fmt: skip
    return out
