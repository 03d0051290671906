"""The kinematic chain as the factored filter walks it: subtrees, their frames, capsules, points."""

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


def subtree_frames(
    model: BodyModel, sub: Subtree, Q: np.ndarray, parent_R: np.ndarray | None, parent_o: np.ndarray | None
) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """Frames of a subtree's segments for poses Q (N, D) given the (shared) parent frame.

    parent_R (3, 3) and parent_o (3,) are the world frame of the subtree root's parent (None for
    the body root). Returns {segment: R (N, 3, 3)}, {segment: o (N, 3)}.
    """
    n = Q.shape[0]
    Rs: dict[int, np.ndarray] = {}
    os_: dict[int, np.ndarray] = {}
    for s in sub.segments:
        seg = model.segments[s]
        if s == sub.root:
            pR = None if parent_R is None else np.broadcast_to(parent_R, (n, 3, 3))
            po = None if parent_o is None else np.broadcast_to(parent_o, (n, 3))
        else:
            pR, po = Rs[seg.parent], os_[seg.parent]
        Rs[s], os_[s] = model.segment_frame(seg, Q[:, seg.dofs], pR, po)
    return Rs, os_


def capsules_of(
    model: BodyModel, caps: np.ndarray, Rs: dict[int, np.ndarray], os_: dict[int, np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Capsule ends A, B (N, K, 3) and radii (K, 2) for capsule indices ``caps``."""
    segs = model.capsule_segment[caps]
    R = np.stack([Rs[s] for s in segs], axis=1)  # (N, K, 3, 3)
    o = np.stack([os_[s] for s in segs], axis=1)
    A = o + np.einsum("nkij,kj->nki", R, model.capsule_a[caps])
    B = o + np.einsum("nkij,kj->nki", R, model.capsule_b[caps])
    return A, B, model.capsule_radii[caps]


def points_of(
    model: BodyModel, pts: np.ndarray, Rs: dict[int, np.ndarray], os_: dict[int, np.ndarray]
) -> np.ndarray:
    """Positions (N, len(pts), 3) of points ``pts``."""
    segs = model.point_segment[pts]
    R = np.stack([Rs[s] for s in segs], axis=1)
    o = np.stack([os_[s] for s in segs], axis=1)
    return o + np.einsum("nkij,kj->nki", R, model.point_local[pts])
