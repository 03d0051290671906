"""The kinematic chain as the factored filter walks it: each segment's subtree, its capsules and points."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitcap.body.model import BodyModel


@dataclass(frozen=True)
class Subtree:
    """A segment and its descendants (topological order), with their capsules and points."""

    root: int
    segments: tuple[int, ...]
    capsules: np.ndarray  # capsule indices (K,)
    own_capsules: np.ndarray  # capsules of the root segment only
    points: np.ndarray  # point indices carried by the subtree's segments


def subtrees(model: BodyModel) -> list[Subtree]:
    """One :class:`Subtree` per segment index."""
    out = []
    for seg in model.segments:
        members = [seg.index]
        for s in model.segments:  # topological: parents come before children
            if s.parent in members and s.index not in members:
                members.append(s.index)
        caps = np.where(np.isin(model.capsule_segment, members))[0]
        own = np.where(model.capsule_segment == seg.index)[0]
        pts = np.where(np.isin(model.point_segment, members))[0]
        out.append(Subtree(seg.index, tuple(members), caps, own, pts))
    return out
