"""How much of a tracked segment the silhouettes hold: the share of its drawn pixels on the masks.

A leg the masks lost in one camera (trousers the floor's colour, taken for shadow) is placed there
by the other cameras and the priors alone: right or wrong, the silhouettes do not confirm it, and
neither the fit (the lost leg costs nothing where nothing is expected) nor the legs' order reads
that. The verdict notes it (:func:`gaitcap.quality.assess`, ``verdict.min_leg_support``), and the
same of a foot, whose heel and toe points and gait events then follow the leg above it.
"""

from __future__ import annotations

import numpy as np

from gaitcap.body.model import BodyModel
from gaitcap.quality import FOOT_SEGMENTS, LEG_SEGMENTS
from gaitcap.tracking.likelihood import SilhouetteLikelihood
from gaitcap.tracking.observation import Observation

__all__ = ["FOOT_SEGMENTS", "LEG_SEGMENTS", "MIN_PIXELS", "segment_support"]


#: a segment drawn over fewer full-resolution pixels than this in a camera (out of view, seen end-on)
#: is not judged there
MIN_PIXELS = 50.0


def segment_support(model: BodyModel, likelihood: SilhouetteLikelihood, obs: Observation, q: np.ndarray,
                    segments: tuple[str, ...] = LEG_SEGMENTS) -> np.ndarray:  # fmt: skip
    """(S,) for each of ``segments`` at pose ``q`` (D,), the lowest over the cameras of the share of
    its drawn pixels (all its capsules, as the likelihood draws them) that the silhouette holds
    (a soft silhouette's values summed); NaN where no camera sees it over :data:`MIN_PIXELS`."""
    A, B, radii = model.capsules(np.asarray(q, float)[None])
    index = {seg.name: i for i, seg in enumerate(model.segments)}
    least = np.array([MIN_PIXELS * v.scale**2 for v in likelihood.views])
    out = np.full(len(segments), np.nan)
    for i, name in enumerate(segments):
        k = np.flatnonzero(model.capsule_segment == index[name])
        inside, drawn = likelihood.terms(obs, likelihood.projected(A[:, k], B[:, k], radii[k]))
        seen = drawn[:, 0] >= least
        if np.any(seen):
            out[i] = float(np.min(inside[seen, 0] / drawn[seen, 0]))
    return out
