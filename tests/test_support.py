"""The share of a tracked segment the silhouettes hold (gaitcap.tracking.support)."""

from __future__ import annotations

import numpy as np
from model_truth import model_mask

from gaitcap.body.model import load_body_model
from gaitcap.camera import Camera
from gaitcap.tracking.likelihood import SilhouetteLikelihood
from gaitcap.tracking.observation import observe, tracking_views
from gaitcap.tracking.support import LEG_SEGMENTS, segment_support


def test_a_leg_drawn_where_the_silhouettes_have_it_bent_elsewhere_has_little_support():
    cams = [Camera.look_at(name, pos, (0.0, 0.0, 0.9), size=(320, 240), focal_px=260.0)
            for name, pos in (("side", (0.0, -4.0, 1.2)), ("front", (4.0, 0.5, 1.5)))]  # fmt: skip
    model = load_body_model(height_m=1.7)
    q = model.neutral_pose()
    bent = q.copy()
    bent[model.dof_index("knee_flexion_l")] = np.radians(100)  # in the images the left knee is bent
    views = tracking_views(cams, 0.5)
    likelihood = SilhouetteLikelihood(views, 40.0)
    same = segment_support(model, likelihood, observe(views, [model_mask(model, q, c) for c in cams]), q)
    assert same.shape == (len(LEG_SEGMENTS),) and np.all(same > 0.9)
    other = segment_support(model, likelihood, observe(views, [model_mask(model, bent, c) for c in cams]), q)
    shares = dict(zip(LEG_SEGMENTS, other))
    assert shares["shank_l"] < 0.5  # the straight left shank, drawn where the masks hold the bent one
    assert shares["thigh_l"] > 0.9 and shares["thigh_r"] > 0.9 and shares["shank_r"] > 0.85
