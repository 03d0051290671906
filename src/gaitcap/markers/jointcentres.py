"""Joint-centre rules: the maths behind each mapping rule (:mod:`gaitcap.markers.mapping`).

Every function takes point trajectories of shape (T, 3) in metres, gaitcap frame (z up, floor
z = 0) and returns shape (T, 3); NaN propagates (a frame missing an input gives NaN).
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from gaitcap.errors import InputError
from gaitcap.markers.mapping import (
    ChordRule,
    ClusterRule,
    FloorContact,
    HarringtonRule,
    LerpRule,
    Mapping,
    Resolution,
    Rule,
    ShiftRule,
    SoleRule,
)
from gaitcap.timeseries import finite_runs
from gaitcap.trajectory import TOE_RELEASES, Trajectory

log = logging.getLogger("gaitcap.markers.jointcentres")

UP = np.array([0.0, 0.0, 1.0])


def _unit(v: np.ndarray) -> np.ndarray:
    """Normalise rows of (..., 3); zero-length rows become NaN."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 1e-12, v / n, np.nan)


def harrington_hjc(
    lasi: np.ndarray, rasi: np.ndarray, mid_psis: np.ndarray, side: str
) -> np.ndarray:
    """Hip joint centre, Harrington et al. 2007 (J Biomech 40:595-602), pelvis width/depth form.

    Pelvis frame (ISB): origin at mid-ASIS; z from LASI to RASI (right); x anterior, in the
    plane of the ASISs and mid-PSIS, orthogonal to z; y = z x x (up). With PW = |RASI - LASI|
    and PD = |mid-ASIS - mid-PSIS| in mm:

        x = -0.24 PD - 9.9     y = -0.30 PW - 10.9     z = +/-(0.33 PW + 7.3)   (+ right)

    Args:
        lasi, rasi, mid_psis: shape (T, 3), metres.
        side: ``"left"`` or ``"right"``.
    Returns:
        shape (T, 3), metres.
    """
    origin = 0.5 * (lasi + rasi)
    z = _unit(rasi - lasi)
    back = origin - mid_psis
    x = _unit(back - np.sum(back * z, axis=-1, keepdims=True) * z)
    y = np.cross(z, x)
    pw = np.linalg.norm(rasi - lasi, axis=-1, keepdims=True) * 1000.0
    pd = np.linalg.norm(back, axis=-1, keepdims=True) * 1000.0
    sign = 1.0 if side == "right" else -1.0
    local_x = -0.24 * pd - 9.9
    local_y = -0.30 * pw - 10.9
    local_z = sign * (0.33 * pw + 7.3)
    return origin + (local_x * x + local_y * y + local_z * z) / 1000.0


def rigid_cluster_point(
    static_cluster: np.ndarray, static_point: np.ndarray, cluster: np.ndarray
) -> np.ndarray:
    """Carry a point fixed to a rigid marker cluster from a static pose into each frame.

    For each frame, the rotation R and translation minimising sum_i |c_i - (R s_i + t)|^2 over
    the cluster markers present (>= 3) is found with :meth:`Rotation.align_vectors` (Kabsch)
    on centred coordinates, and the point is moved the same way: p = R (p_s - s_bar) + c_bar.

    Args:
        static_cluster: cluster markers in the static pose, shape (M, 3).
        static_point: the point in the static pose, shape (3,).
        cluster: cluster markers over time, shape (T, M, 3), NaN where missing.
    Returns:
        shape (T, 3); NaN in frames with fewer than 3 markers present.
    """
    out = np.full((cluster.shape[0], 3), np.nan)
    for i, frame in enumerate(cluster):
        ok = np.isfinite(frame).all(axis=1) & np.isfinite(static_cluster).all(axis=1)
        if ok.sum() < 3:
            continue
        s, c = static_cluster[ok], frame[ok]
        s_bar, c_bar = s.mean(axis=0), c.mean(axis=0)
        rot, _ = Rotation.align_vectors(c - c_bar, s - s_bar)
        out[i] = rot.apply(static_point - s_bar) + c_bar
    return out


def sole_point(marker: np.ndarray, heel: np.ndarray, toe: np.ndarray, height_m: float) -> np.ndarray:
    """A foot marker moved ``height_m`` along the foot's down axis.

    down = world down (-z) minus its component along the foot axis heel -> toe, normalised: in
    foot-flat it is the world vertical, and it pitches with the foot in swing.
    """
    axis = _unit(toe - heel)
    down = -UP - np.sum(-UP * axis, axis=-1, keepdims=True) * axis
    return marker + height_m * _unit(down)


def sole_height(marker: np.ndarray, percentile: float) -> float:
    """The marker's height above the floor (z = 0) in foot-flat: a low percentile of its z."""
    z = marker[:, 2][np.isfinite(marker[:, 2])]
    if z.size == 0:
        return float("nan")
    return float(np.percentile(z, percentile))


def shift_point(
    point: np.ndarray,
    start: np.ndarray,
    end: np.ndarray,
    distance: np.ndarray | float,
    ortho_start: np.ndarray | None = None,
    ortho_end: np.ndarray | None = None,
) -> np.ndarray:
    """``point + distance * d``, d = unit(end - start), optionally orthogonal to unit(ortho_end - ortho_start)."""
    d = end - start
    if ortho_start is not None and ortho_end is not None:
        a = _unit(ortho_end - ortho_start)
        d = d - np.sum(d * a, axis=-1, keepdims=True) * a
    return point + np.reshape(distance, (-1, 1)) * _unit(d)


def chord_point(proximal: np.ndarray, wand: np.ndarray, marker: np.ndarray, distance: float) -> np.ndarray:
    """Plug-in-Gait's chord function (see :class:`gaitcap.markers.mapping.ChordRule`).

    With a = unit(proximal - marker), b = the unit vector of the plane orthogonal to a, pointing
    away from the wand: J = marker + d (cos t a + sin t b), cos t = d / |proximal - marker|.
    All arrays shape (T, 3), metres; returns shape (T, 3).
    """
    axis = proximal - marker
    length = np.linalg.norm(axis, axis=-1, keepdims=True)
    a = _unit(axis)
    w = wand - marker
    b = -_unit(w - np.sum(w * a, axis=-1, keepdims=True) * a)
    with np.errstate(invalid="ignore"):
        cos_t = np.clip(distance / length, -1.0, 1.0)
    return marker + distance * (cos_t * a + np.sqrt(1.0 - cos_t**2) * b)


def _carry(point_ref: np.ndarray, donors_ref: np.ndarray, donors: np.ndarray) -> np.ndarray:
    """A marker seen in a reference frame, carried through a gap by the motion of its donors.

    Donors (markers of the same rigid body) seen in the reference frame and in every gap frame
    are used: three or more carry the point rigidly (Kabsch, :func:`rigid_cluster_point`), one
    or two by their mean translation (the rotation since the reference frame is not followed).

    Args:
        point_ref: the marker in the reference frame, shape (3,).
        donors_ref: the donors in the reference frame, shape (D, 3), NaN where missing.
        donors: the donors over the gap, shape (G, D, 3).
    Returns:
        shape (G, 3); NaN when no donor qualifies.
    """
    keep = np.isfinite(donors_ref).all(axis=1) & np.isfinite(donors).all(axis=(0, 2))
    if keep.sum() >= 3:
        return rigid_cluster_point(donors_ref[keep], point_ref, donors[:, keep])
    if keep.any():
        return point_ref + donors[:, keep].mean(axis=1) - donors_ref[keep].mean(axis=0)
    return np.full((donors.shape[0], 3), np.nan)


def fill_from_donors(target: np.ndarray, donors: np.ndarray) -> np.ndarray:
    """Fill a marker's gaps from other markers of its rigid body (a pattern fill).

    Each gap is filled by carrying the marker from the frame before it and from the frame after
    it (:func:`_carry`); inside the trial the two are blended linearly across the gap (weight 1
    next to each edge), so the filled samples meet the seen ones at both ends; a gap at the
    start or end of the trial follows its one edge.

    Args:
        target: the marker, shape (T, 3), NaN in gaps.
        donors: the other markers of its body, shape (T, D, 3), NaN where missing.
    Returns:
        shape (T, 3): a copy with the gaps filled where a donor allows.
    """
    out = np.array(target, dtype=np.float64, copy=True)
    seen = np.isfinite(out).all(axis=1)
    if seen.all() or not seen.any():
        return out
    n = len(out)
    for start, stop in finite_runs(~seen):
        gap = donors[start:stop]
        edges = [(ref, _carry(target[ref], donors[ref], gap)) for ref in (start - 1, stop) if 0 <= ref < n]
        if len(edges) == 2:
            w = ((stop - np.arange(start, stop)) / (stop - start + 1))[:, None]
            a, b = edges[0][1], edges[1][1]
            both = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
            fill = np.where(np.isfinite(a).all(axis=1)[:, None], a, b)
            fill[both] = (w * a + (1.0 - w) * b)[both]
        else:
            fill = edges[0][1]
        out[start:stop] = fill
    return out


def fill_segment_gaps(markers: Trajectory, segments: dict[str, list[str]]) -> Trajectory:
    """Fill the gaps of each segment's markers from the segment's other markers
    (:func:`fill_from_donors`; donors are always the markers as read, never filled ones).

    Args:
        markers: marker trajectory (T, M, 3), metres.
        segments: segment name -> its markers (those absent from the file are ignored).
    Returns:
        the trajectory with the gaps filled (the same object when nothing was filled).
    """
    source = markers.meta.get("source", "motion")
    points = markers.points.copy()
    filled_any = False
    for segment, names in segments.items():
        present = [markers.names.index(n) for n in dict.fromkeys(names) if markers.has(n)]
        for i in present:
            donors = [j for j in present if j != i]
            if not donors:
                continue
            before = np.isfinite(points[:, i]).all(axis=1)
            points[:, i] = fill_from_donors(markers.points[:, i], markers.points[:, donors])
            count = int((np.isfinite(points[:, i]).all(axis=1) & ~before).sum())
            if count:
                filled_any = True
                log.info("%s: %s: %d frame(s) filled from the other %s markers (%s)", source, markers.names[i],
                         count, segment, ", ".join(markers.names[j] for j in donors))  # fmt: skip
    return replace(markers, points=points) if filled_any else markers


def _on_floor(marker: np.ndarray, last: int, rate_hz: float, contact: FloorContact) -> bool:
    """Whether ``marker`` (T, 3) stood on the floor at frame ``last``: near its foot-flat height
    (5th percentile of its height over the trial) and nearly still since the frame before."""
    if last < 1 or not np.isfinite(marker[last - 1 : last + 1]).all():
        return False
    flat = float(np.nanpercentile(marker[:, 2], 5))
    speed = float(np.linalg.norm(marker[last] - marker[last - 1])) * rate_hz
    return marker[last, 2] <= flat + contact.max_height_m and speed <= contact.max_speed_m_s


def hold_on_floor(marker: np.ndarray, reach: np.ndarray, rate_hz: float, contact: FloorContact) -> tuple[np.ndarray, list[float]]:
    """Hold a foot marker lost while on the floor where it was, while the foot can still stand on it.

    At push-off the toe marker is often hidden (by the other foot, or it leaves the volume) while
    the toe still stands on the floor. A standing toe does not move: the marker is held at its
    last position for as long as the ankle (``reach``) stays within the foot's length of it, the
    largest toe-ankle distance seen while both were visible, plus ``tolerance_m``; the foot is
    rigid, so once the ankle is further away the toe has left that spot: the toe is off, the
    rest of the gap stays open, and the sub-frame of the crossing is returned. A gap that opens
    in swing (the marker above its foot-flat height or moving) is left alone.

    The crossing is the latest the toe can have lifted. In a normal push-off the foot is steeply
    plantarflexed at toe off (the ankle nearly above the toe) and the swing carries the ankle out
    of reach within a frame: on the C3D.ORG Plug-in-Gait sample the right foot off recorded at
    2.600 s is found at 2.598 s (toe lost at 2.50 s). A foot lifted flat (no heel rise) keeps the
    ankle within reach longer and is found late; the gait events' rhythm check drops a release
    that lengthens the stance by more than ``GaitOptions.edge_rhythm_tolerance``.

    Args:
        marker: the toe marker, shape (T, 3), metres, z up, NaN in gaps.
        reach: the ankle marker, shape (T, 3), NaN where missing.
        rate_hz: sampling rate.
        contact: the thresholds.
    Returns:
        the marker with the held frames filled (a copy), and the release sub-frames, one per gap
        that ended with the toe lifting (linear interpolation of the distance's crossing).
    """
    out = np.array(marker, dtype=np.float64, copy=True)
    seen = np.isfinite(out).all(axis=1)
    both = seen & np.isfinite(reach).all(axis=1)
    if not both.any():
        return out, []
    length = float(np.max(np.linalg.norm(marker[both] - reach[both], axis=1))) + contact.tolerance_m
    releases: list[float] = []
    for start, stop in finite_runs(~seen):
        if start == 0 or not _on_floor(marker, start - 1, rate_hz, contact):
            continue
        held = marker[start - 1]
        dist = np.linalg.norm(reach[start - 1 : stop] - held, axis=1)  # dist[0]: the last seen frame
        k = 1
        while k < len(dist) and dist[k] <= length:
            out[start - 1 + k] = held
            k += 1
        if k < len(dist) and np.isfinite(dist[k]) and np.isfinite(dist[k - 1]):
            frac = (length - dist[k - 1]) / (dist[k] - dist[k - 1])
            releases.append(float(start - 2 + k + np.clip(frac, 0.0, 1.0)))
    return out, releases


def hold_floor_contacts(markers: Trajectory, contacts: dict[str, FloorContact]) -> Trajectory:
    """:func:`hold_on_floor` for each foot's contact marker present with its reach marker.

    Returns:
        the trajectory with the held frames filled (the same object when nothing was held) and
        ``meta[TOE_RELEASES]``: side -> release sub-frames, when any.
    """
    source = markers.meta.get("source", "motion")
    points = markers.points.copy()
    releases: dict[str, list[float]] = {}
    held_any = False
    for side, contact in contacts.items():
        names = contact.present(markers.names)
        if names is None:
            continue
        i = markers.index(names[0])
        before = np.isfinite(points[:, i]).all(axis=1)
        points[:, i], found = hold_on_floor(markers.points[:, i], markers.point(names[1]), markers.rate_hz, contact)
        count = int((np.isfinite(points[:, i]).all(axis=1) & ~before).sum())
        if count:
            held_any = True
            log.info("%s: %s: %d frame(s) held on the floor while %s could reach it%s", source, names[0], count,
                     names[1], f"; lifted at frame(s) {', '.join(f'{f:.1f}' for f in found)}" if found else "")  # fmt: skip
        if found:
            releases[side] = found
    if not (held_any or releases):
        return markers
    meta = {**markers.meta, TOE_RELEASES: releases} if releases else markers.meta
    return replace(markers, points=points, meta=meta)


class _Evaluator:
    """Evaluates a mapping's definitions in order over a marker trajectory."""

    def __init__(self, markers: Trajectory, static: Trajectory | None, source: str, label: str = "mapping") -> None:
        self.markers = markers
        self.static = static
        self.source = source
        self.label = label  # the mapping's (Mapping.label), for the errors
        self.values: dict[str, np.ndarray] = {}

    def get(self, name: str) -> np.ndarray:
        if name in self.values:
            return self.values[name]
        if self.markers.has(name):
            return self.markers.point(name)
        raise InputError(f"{self.source}: marker {name!r} not found")

    def first_present(self, names: list[str]) -> np.ndarray:
        for n in names:
            if n in self.values or self.markers.has(n):
                return self.get(n)
        raise InputError(f"{self.source}: none of the markers {names} found")

    def static_mean(self, names: list[str]) -> np.ndarray:
        """Mean over the static trial's frames of each named marker, shape (len(names), 3)."""
        if self.static is None:
            raise InputError(f"{self.source}: a static trial is needed (cluster rule) but none was given")
        missing = [n for n in names if not self.static.has(n)]
        if missing:
            raise InputError(f"{self.static.meta.get('source', 'static trial')}: missing markers {missing}")
        pts = self.static.subset(names).points
        complete = np.isfinite(pts).all(axis=(1, 2))
        if not complete.any():
            raise InputError(f"{self.static.meta.get('source')}: no frame has all of {names}")
        return pts[complete].mean(axis=0)

    def evaluate(self, name: str, rule: Rule) -> np.ndarray:
        kind = rule.kind  # a ``first`` rule arrives here already resolved (Rule.chosen)
        if kind == "marker":
            names = [rule.marker] if isinstance(rule.marker, str) else list(rule.marker or [])
            return self.first_present(names)
        if kind == "mean":
            return np.mean([self.get(n) for n in rule.mean or []], axis=0)
        if kind == "harrington":
            return self._harrington(rule.harrington)  # type: ignore[arg-type]
        if kind == "cluster":
            return self._cluster(rule.cluster)  # type: ignore[arg-type]
        if kind == "sole":
            return self._sole(name, rule.sole)  # type: ignore[arg-type]
        if kind == "shift":
            return self._shift(rule.shift)  # type: ignore[arg-type]
        if kind == "chord":
            c: ChordRule = rule.chord  # type: ignore[assignment]
            wand, marker = self.get(c.wand), self.get(c.marker)
            self._refuse_apart(name, f"its chord's wand {c.wand} and marker {c.marker}", wand, marker, MAX_WAND_SPREAD_M,
                               "a wand and its joint's marker, on one segment, keep theirs within 2 cm")  # fmt: skip
            return chord_point(self.get(c.proximal), wand, marker, self._chord_distance(name, c))
        if kind == "lerp":
            r: LerpRule = rule.lerp  # type: ignore[assignment]
            a, b = self.get(r.start), self.get(r.end)
            return a + r.fraction * (b - a)
        raise InputError(f"unknown rule {kind}")  # pragma: no cover - schema prevents it

    def _refuse_apart(self, name: str, what: str, a: np.ndarray, b: np.ndarray, limit: float, norm: str) -> None:
        """Raise when the distance between ``a`` and ``b`` (points of one body segment) changes by more
        than ``limit`` over the frames (:func:`length_spread`): one of them is on another segment,
        most likely the other side's (``RKNE`` in the left knee's rule)."""
        spread = length_spread(a, b)
        if spread is not None and spread[1] - spread[0] > limit:
            raise InputError(
                f"{self.source}: {self.label}: {name}: {what} are not on one segment: their distance changes by "
                f"{1000 * (spread[1] - spread[0]):.0f} mm over the frames ({1000 * spread[0]:.0f} to "
                f"{1000 * spread[1]:.0f} mm, 5th to 95th percentile; {norm}): a rule names the other side's marker "
                "or point, or the file's labels of the two sides are swapped in part of it"
            )  # fmt: skip

    def _harrington(self, r: HarringtonRule) -> np.ndarray:
        if r.sacral is not None:
            mid_psis = self.get(r.sacral)
        else:
            mid_psis = 0.5 * (self.get(r.lpsi) + self.get(r.rpsi))  # type: ignore[arg-type]
        return harrington_hjc(self.get(r.lasi), self.get(r.rasi), mid_psis, r.side)

    def _chord_distance(self, name: str, c: ChordRule) -> float:
        """Half the subject's joint width plus the marker radius when the file has the width
        (PROCESSING, mm), else the rule's typical ``distance_m`` (logged either way)."""
        measured: dict[str, float] = self.markers.meta.get("anthropometry_mm") or {}
        if c.width is None or c.width not in measured:
            if c.width is not None:
                log.info("%s: %s: no %s in the file, typical chord distance %.4f m", self.source, name, c.width,
                         c.distance_m)  # fmt: skip
            return c.distance_m
        radius = measured["MarkerDiameter"] / 2000.0 if "MarkerDiameter" in measured else c.marker_radius_m
        distance = measured[c.width] / 2000.0 + radius
        log.info("%s: %s: the file's %s %g mm + marker radius %.1f mm (%s) -> chord distance %.4f m",
                 self.source, name, c.width, measured[c.width], radius * 1000,
                 "MarkerDiameter / 2" if "MarkerDiameter" in measured else "typical", distance)  # fmt: skip
        return distance

    def _cluster(self, r: ClusterRule) -> np.ndarray:
        static_cluster = self.static_mean(r.markers)
        static_point = self.static_mean(r.static_mean).mean(axis=0)
        cluster = np.stack([self.get(m) for m in r.markers], axis=1)
        return rigid_cluster_point(static_cluster, static_point, cluster)

    def _sole(self, name: str, r: SoleRule) -> np.ndarray:
        marker = self.get(r.point)
        h = r.height_m if r.height_m is not None else sole_height(marker, r.percentile)
        if not (0.0 <= h <= 0.15):
            log.warning("%s: %s: marker height above the floor estimated at %.3f m: is the floor at z = 0?",
                        self.source, name, h)  # fmt: skip
        log.debug("%s: %s: %s lowered by %.4f m to the sole", self.source, name, r.point, h)
        return sole_point(marker, self.get(r.heel), self.get(r.toe), h)

    def _shift(self, r: ShiftRule) -> np.ndarray:
        if r.distance_m is not None:
            distance: np.ndarray | float = r.distance_m
        else:
            a, b = r.fraction_of  # type: ignore[misc]
            distance = r.fraction * np.linalg.norm(self.get(a) - self.get(b), axis=-1)  # type: ignore[operator]
        ortho = (self.get(r.orthogonal_to[0]), self.get(r.orthogonal_to[1])) if r.orthogonal_to else (None, None)
        return shift_point(self.get(r.point), self.get(r.direction[0]), self.get(r.direction[1]), distance, *ortho)


def _evaluate_alternatives(ev: _Evaluator, name: str, rules: list[Rule], n_frames: int) -> np.ndarray:
    """A definition's value, shape (T, 3): its first usable rule, each frame where that gives
    NaN taken from the next rule that has it there (a lab's joint centres with gaps, say)."""
    value = np.broadcast_to(np.asarray(ev.evaluate(name, rules[0]), dtype=np.float64), (n_frames, 3)).copy()
    for rule in rules[1:]:
        gap = ~np.isfinite(value).all(axis=1)
        if not gap.any():
            break
        other = np.broadcast_to(np.asarray(ev.evaluate(name, rule), dtype=np.float64), (n_frames, 3))
        take = gap & np.isfinite(other).all(axis=1)
        if take.any():
            value[take] = other[take]
            have = set(ev.markers.names) | set(ev.values)
            log.info("%s: %s: %d frame(s) from %s where %s has none", ev.source, name, int(take.sum()),
                     rule.describe(have), rules[0].describe(have).split(", gaps:")[0])  # fmt: skip
    return value


SAME_POINT_M = 0.01  # a left and a right joint centre closer than this (median over frames) are one point

#: the length of a limb segment between two joint centres, hip-knee or knee-ankle, changes by less than
#: this over a file's frames (5th to 95th percentile; at most 45 mm in the shared Plug-in-Gait, C3D.ORG
#: and OpenSim walks); a joint centre a rule builds from the other side's marker changes it by 160-300 mm
MAX_SEGMENT_SPREAD_M = 0.1
#: the distance between a chord's wand and its marker (THI-KNE, TIB-ANK), on one segment, changes by less
#: than this (at most 17 mm in the shared walks; 66-350 mm with one of them the other side's)
MAX_WAND_SPREAD_M = 0.04
#: the limb segments whose length is checked: (segment, proximal joint, distal joint)
LIMB_SEGMENTS = (("thigh", "hip", "knee"), ("shank", "knee", "ankle"))
#: frames with both points that a length's spread needs to be judged
MIN_SPREAD_FRAMES = 10


def length_spread(a: np.ndarray, b: np.ndarray) -> tuple[float, float] | None:
    """The 5th and 95th percentiles over the frames of the distance between ``a`` and ``b`` ((T, 3),
    metres); None for fewer than :data:`MIN_SPREAD_FRAMES` frames with both (a standing trial's
    few frames, a constant point, or gaps)."""
    d = np.atleast_1d(np.linalg.norm(np.asarray(a, np.float64) - np.asarray(b, np.float64), axis=-1))
    d = d[np.isfinite(d)]
    if len(d) < MIN_SPREAD_FRAMES:
        return None
    lo, hi = np.percentile(d, [5, 95])
    return float(lo), float(hi)


def _refuse_limbs_off_their_segments(resolution: Resolution, names: tuple[str, ...], points: np.ndarray,
                                     source: str) -> None:  # fmt: skip
    """A thigh or shank (hip-knee, knee-ankle) whose length changes by more than
    :data:`MAX_SEGMENT_SPREAD_M` over the frames: one of its joint centres is built from the other
    side's markers (the right knee marker in the left knee's chord), and lies off the limb.

    Raises:
        InputError: naming the mapping (its file), the two points and how each is computed.
    """
    for side in ("l", "r"):
        for segment, proximal, distal in LIMB_SEGMENTS:
            a, b = f"{proximal}_{side}", f"{distal}_{side}"
            if a not in names or b not in names:
                continue
            spread = length_spread(points[:, names.index(a)], points[:, names.index(b)])
            if spread is None or spread[1] - spread[0] <= MAX_SEGMENT_SPREAD_M:
                continue
            how = f"{a} = {resolution.describe(a)}, {b} = {resolution.describe(b)}"
            raise InputError(
                f"{source}: {resolution.mapping.label}: the {'left' if side == 'l' else 'right'} {segment}, {a} to {b}, "
                f"changes length by {1000 * (spread[1] - spread[0]):.0f} mm over the frames ({1000 * spread[0]:.0f} "
                f"to {1000 * spread[1]:.0f} mm, 5th to 95th percentile; a limb's joint centres keep theirs within a "
                f"few cm; {how}): a rule of one of them names the other side's marker or point, or the file's labels "
                "of the two sides are swapped in part of it"
            )  # fmt: skip


def _refuse_same_left_and_right(resolution: Resolution, names: tuple[str, ...], points: np.ndarray, source: str) -> None:
    """A left point and its right twin that are one point (median distance under 1 cm): a rule names
    the other side's marker, helper point or ``side`` (``harrington: {side: right}`` for hjc_l).

    Raises:
        InputError: naming the mapping (its file), the two points and how each is computed.
    """
    for i, name in enumerate(names):
        twin = name[:-2] + "_r" if name.endswith("_l") else None
        if twin not in names:
            continue
        d = np.linalg.norm(points[:, i] - points[:, names.index(twin)], axis=-1)
        if np.isfinite(d).any() and np.nanmedian(d) < SAME_POINT_M:
            how = f"{name} = {resolution.describe(name)}, {twin} = {resolution.describe(twin)}"
            raise InputError(f"{source}: {resolution.mapping.label}: {name} and {twin} are the same point "
                             f"({np.nanmedian(d) * 1000:.1f} mm apart; {how}): a rule of one of them names the other "
                             "side's markers, point or side")  # fmt: skip


def apply_mapping(
    mapping: Mapping,
    markers: Trajectory,
    static: Trajectory | None = None,
) -> Trajectory:
    """Evaluate ``mapping`` on marker trajectories (metres, z up) -> gaitcap points.

    Args:
        mapping: the rules.
        markers: marker trajectory of the motion trial, (T, M, 3).
        static: marker trajectory of the static trial (needed by cluster rules).
    Returns:
        a :class:`Trajectory` with the mapping's output points in :data:`POINT_NAMES` order
        (optional points whose markers are missing left out), shape (T, P, 3), same time axis,
        events and meta as ``markers`` (plus ``mapping``).
    Raises:
        InputError: naming the missing markers.
    """
    source = str(markers.meta.get("source", "motion"))
    resolution = mapping.resolve(markers.names)
    missing = resolution.missing_required()
    if missing:
        raise InputError(f"{source}: {mapping.label} needs markers missing from the file: "
                         f"{resolution.explain_missing(markers.names)}")  # fmt: skip
    markers = hold_floor_contacts(fill_segment_gaps(markers, mapping.segments), mapping.floor_contacts)
    ev = _Evaluator(markers, static, source, mapping.label)
    for name, rule in mapping.definitions():
        if name in resolution.unresolved:
            continue
        ev.values[name] = _evaluate_alternatives(ev, name, rule.usable(resolution.have), markers.n_frames)
    names = tuple(resolution.output_points())
    points = np.stack([ev.values[n] for n in names], axis=1)
    _refuse_same_left_and_right(resolution, names, points, source)
    _refuse_limbs_off_their_segments(resolution, names, points, source)
    meta = {**markers.meta, "mapping": mapping.name}
    return Trajectory(names, points, markers.rate_hz, markers.t0_s, markers.events, meta)


