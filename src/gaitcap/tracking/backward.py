"""A second pass over the clip, backwards in time, and the choice between the two passes.

No dynamic model carries the tracker from frame to frame, so where a forward pass goes wrong (the
legs exchanged at a crossing, a poor start) it stays wrong until the silhouettes pull it back. A
pass that walks the clip from its last frame to its first, started from the forward pass's last
pose, meets each crossing from the other side and goes wrong elsewhere, if at all. The two passes
are merged where they disagree:

    agree_t = mean_k |p_k^F(t) - p_k^B(t)| < agree_m       (p_k: the legs' points, knees to toes)

and every run of frames where they do not agree takes the pass whose fit, summed over the run, is
the higher (a whole leg assignment, never a mixture within the run); a frame where they agree
takes the better fit of the two. This is the choice a clip-level smoother makes between two
hypotheses, with the silhouettes as the only judge. Once every choice is made, a frame whose
estimate agrees with the other pass's (with ``backward.average``) takes the mean of the two poses
(:func:`mean_pose`): two searches with their own random draws, whose mean scatters less than
either, where picking the better fit of two near-equal ones picks a draw.

Where the silhouettes cannot judge (every camera beside or along the walkway: the two legs'
assignments fit alike), both passes can keep the same leg ahead where the feet meet, a bounce
instead of a pass, and carry the legs exchanged until the next passing. Walking, the leading ankle
changes at every passing, twice a stride, which such an exchange leaves visible in the ankles'
fore-aft order. :func:`order_legs` breaks the ties with it: between the passings (the minima of
the ankles' fore-aft distance, which an exchange leaves unchanged) the leading ankle alternates,
and a stretch of the merge that leads the other way takes a pass, the stretch tracked again from
the mirrored legs, or the merge with the legs exchanged in the frames that lead the wrong way (each
searched again), that leads as it must, if that fits nearly as well. This assumes that the
feet pass each other; a step-to gait (the trailing foot brought up to the leading one, not past it)
breaks it, and should be tracked with ``backward.leg_order: false``.

Both passes start from the forward pass's choice of legs, so a run trapped from its first frame
(both legs stacked on the near one, whose mirror is itself) stays trapped in both. With
``backward.restart``, a run whose merged legs the verdict would doubt gets a second backward pass,
from a pose initialised afresh on the run's last frames (turned round if the other way fits them
decisively better: a subject who turned, whose heading the forward pass lost); it is merged with
the first (:func:`merge_passes`, the same rule, but a run of disagreeing frames may switch passes
once, at a turn) and the run merged again, kept if it leaves no more frames in doubt
(``gaitcap.pipeline._backward_pass``).

The rhythm cannot see a run whose legs are exchanged from its first frame to its last: the leading
ankle still changes at every passing. Where no camera views the walk obliquely, the forward pass
settles the assignment over its first few frames, on a difference of fit that is noise there. With
``backward.mirror_run``, such a run is also tracked from its legs' mirror (forwards from the mirror
of its first pose, backwards from that of its last, merged as above); where that run holds the legs
the other way round (:func:`exchanged_legs`) and fits the silhouettes better over all its frames, it
replaces the first whole (``gaitcap.pipeline._mirror_run``).
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable
from typing import Protocol

import numpy as np

from gaitcap.quality import STRIDE_HZ, fore_aft, stride_frequency, walking_line
from gaitcap.timeseries import finite_runs
from gaitcap.trajectory import exchanged_frames
from gaitcap.tracking.config import BackwardConfig

log = logging.getLogger("gaitcap.tracking.backward")

#: the points that decide whether the two passes agree: the legs below the hips
LEG_POINT_PREFIXES = ("knee_", "ankle_", "heel_", "toe_")


class _Estimate(Protocol):  # what order_legs reads of an estimate (gaitcap.tracking.base.Estimate)
    q: np.ndarray
    points: np.ndarray
    fit: float


def leg_points(names: tuple[str, ...]) -> np.ndarray:
    """Indices of the leg points (:data:`LEG_POINT_PREFIXES`) among ``names``."""
    return np.array([i for i, n in enumerate(names) if n.startswith(LEG_POINT_PREFIXES)], int)


def legs_apart(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The mean distance (metres) between two sets of leg points, (..., K, 3) each -> (...): two
    passes agree on a frame when it is below ``backward.agree_m``."""
    return np.linalg.norm(a - b, axis=-1).mean(axis=-1)


def mean_pose(a: np.ndarray, b: np.ndarray, wrap: np.ndarray) -> np.ndarray:
    """The mean of two poses (D,) of one frame: every DOF halfway between them, a wrapped one (``wrap``
    (D,) bool: the heading) the shorter way round, so that headings of +179 and -179 degrees average
    to 180 and not to 0."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = b - a
    d[wrap] = (d[wrap] + np.pi) % (2 * np.pi) - np.pi
    out = a + d / 2
    out[wrap] = (out[wrap] + np.pi) % (2 * np.pi) - np.pi
    return out


def exchanged_legs(a: np.ndarray, b: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """(T,) bool: the frames where the leg points (:data:`LEG_POINT_PREFIXES`) of ``a`` lie nearer to
    those of ``b`` with left and right exchanged than to ``b``'s own (mean distance): the two runs hold
    the legs the other way round there (:func:`gaitcap.trajectory.exchanged_frames`). a, b: (T, P, 3)
    points named ``names`` (``*_l``, ``*_r`` pairs); a frame where either is NaN is False."""
    pairs = [(i, names.index(names[i][:-2] + "_r")) for i in leg_points(names) if names[i].endswith("_l")]
    return exchanged_frames(a, b, pairs)


def choose_backward(forward: np.ndarray, backward: np.ndarray, fit_forward: np.ndarray, fit_backward: np.ndarray,
                    agree_m: float, split_gain: float | None = None) -> np.ndarray:  # fmt: skip
    """(T,) bool: the frames that take the backward pass (module docstring).

    Args:
        forward, backward: (T, K, 3) the two passes' leg points, metres (NaN: not tracked).
        fit_forward, fit_backward: (T,) their fits (NaN: not tracked).
        agree_m: the mean distance (metres, > 0) below which the passes agree.
        split_gain: with it, a run of disagreeing frames may switch passes once, where that gains
            this much summed fit over the run's better pass (:func:`_split_run`); None: never.
    """
    forward, backward = np.asarray(forward, float), np.asarray(backward, float)
    if forward.shape != backward.shape or forward.ndim != 3:
        raise ValueError(f"forward and backward must be (T, K, 3) alike, got {forward.shape} and {backward.shape}")
    if agree_m <= 0:
        raise ValueError(f"agree_m must be > 0, got {agree_m}")
    fit_f = np.where(np.isfinite(fit_forward), fit_forward, -np.inf)
    fit_b = np.where(np.isfinite(fit_backward), fit_backward, -np.inf)
    distance = legs_apart(forward, backward)  # NaN where either is not tracked
    choice = fit_b > fit_f  # where they agree (and where one pass is missing)
    disagree = np.where(np.isfinite(distance), distance >= agree_m, False)
    for s, e in finite_runs(disagree):
        split = None
        if split_gain is not None:  # both passes tracked where their legs disagree
            split = _split_run(np.nan_to_num(np.asarray(fit_backward[s:e]) - np.asarray(fit_forward[s:e])), split_gain)
        if split is None:
            choice[s:e] = np.sum(fit_b[s:e]) > np.sum(fit_f[s:e])
        else:
            k, backward_first = split
            choice[s : s + k], choice[s + k : e] = backward_first, not backward_first
    return choice


#: a run of disagreeing frames is split between two passes (:func:`merge_passes`) when the split's
#: summed fit beats the run's best single pass by this much: a subject turning round, the pass that
#: faces right before the turn wrong after it and the other the reverse (0.05-0.15 of fit a frame
#: over the tens of frames either side), not a few hundredths over a crossing of the legs
SPLIT_GAIN = 1.0


def _split_run(gain: np.ndarray, min_gain: float) -> tuple[int, bool] | None:
    """The best single switch in a run of frames whose second pass fits ``gain`` (n,) better than the
    first frame by frame: (k, second_first) for the first pass's frames [0, k) and the second's [k, n)
    (or the reverse with ``second_first``) when that beats the whole run's better pass by
    ``min_gain``, else None."""
    if len(gain) < 2:
        return None
    head = np.cumsum(gain)[:-1]  # the second pass on frames [0, k), k = 1 .. n-1
    tail = gain.sum() - head  # the second pass on frames [k, n)
    whole = max(0.0, float(gain.sum()))
    k_tail, k_head = int(np.argmax(tail)), int(np.argmax(head))
    best, k, second_first = (float(tail[k_tail]), k_tail + 1, False)
    if head[k_head] > best:
        best, k, second_first = float(head[k_head]), k_head + 1, True
    return (k, second_first) if best > whole + min_gain else None


def merge_passes(first: list[_Estimate], second: list[_Estimate], legs: np.ndarray, agree_m: float) -> list[_Estimate]:
    """Two passes' estimates of the same T frames, merged frame by frame as :func:`choose_backward`
    merges the forward and the backward pass (a run of disagreeing frames goes whole to the pass
    with the higher summed fit), except that a run may switch once from one pass to the other where
    that gains :data:`SPLIT_GAIN` of summed fit (:func:`_split_run`); ``legs``: the indices of the
    points compared (:func:`leg_points`)."""
    if len(first) != len(second):
        raise ValueError(f"the passes must cover the same frames, got {len(first)} and {len(second)}")
    take = choose_backward(np.array([e.points[legs] for e in first]), np.array([e.points[legs] for e in second]),
                           np.array([e.fit for e in first]), np.array([e.fit for e in second]), agree_m,
                           split_gain=SPLIT_GAIN)  # fmt: skip
    return [b if k else a for a, b, k in zip(first, second, take, strict=True)]


#: half-width of the window in which a foot passing is the closest approach (seconds): the feet pass
#: each other twice a stride, at least 0.3 s apart even running, and once per approach
CROSSING_WINDOW_S = 0.12


def crossing_frames(separation: np.ndarray, rate_hz: float, cross_m: float) -> list[int]:
    """The frames where the feet pass each other (or meet): local minima of the fore-aft distance
    between the ankles ``separation`` (T,) metres (NaN: unknown) within +-``CROSSING_WINDOW_S``,
    closer than ``cross_m``; at most one per window. Then the passings the walk's rhythm expects
    (:func:`_rhythm_crossings`, at the step of :func:`step_frames`)."""
    w = max(1, round(CROSSING_WINDOW_S * rate_hz))
    s = np.where(np.isfinite(separation), separation, np.inf)
    out: list[int] = []
    for t in np.flatnonzero(s < cross_m):
        if s[t] <= s[max(0, t - w) : t + w + 1].min() and (not out or t - out[-1] > w):
            out.append(int(t))
    step = step_frames(separation, rate_hz)
    return out if step is None else _rhythm_crossings(s, out, w, cross_m, step)


#: a stretch between passings longer than this many steps (:func:`step_frames`) hides a passing
RHYTHM_GAP = 1.5
#: ... which is then accepted where the ankles come closer than this many times ``cross_m``
RHYTHM_CROSS = 2.0


def step_frames(separation: np.ndarray, rate_hz: float) -> float | None:
    """The step (frames between the feet's passings): half the stride period, at the stride
    frequency that fits the fore-aft distance between the ankles ``separation`` (T,) metres (NaN or
    inf: unknown) over the whole run (:func:`gaitcap.quality.stride_frequency`). A passing that the
    passes missed does not lengthen it, as it lengthens the intervals between the passings found.
    None under one stride of the fastest rhythm measured (:data:`gaitcap.quality.STRIDE_HZ`)."""
    known = np.flatnonzero(np.isfinite(separation))
    if len(known) < rate_hz / STRIDE_HZ[1]:
        return None
    return rate_hz / (2 * stride_frequency(known / rate_hz, separation[known]))


def _rhythm_crossings(s: np.ndarray, found: list[int], w: int, cross_m: float, step: float) -> list[int]:
    """``found`` (sorted frames of passings) with the passings the rhythm expects: the feet pass
    every step, so where a stretch (before the first, between two, after the last) lasts more than
    ``RHYTHM_GAP`` steps, the closest approach within +-w frames of a step after (or, before the
    first, before) its neighbour is one too, if closer than ``RHYTHM_CROSS`` x ``cross_m``: where
    one of the two passes has the legs misplaced, the mean distance at a passing stays above
    ``cross_m``. Needs a passing found.

    Args:
        s: (T,) the separation, metres (inf: unknown).
        found: the passings found, sorted.
        w: the half-width of a passing's window (frames).
        cross_m: the distance below which the feet pass (metres).
        step: the frames between passings (:func:`step_frames`).
    """
    if not found:
        return found
    out = list(found)

    def closest(centre: float) -> int | None:
        lo, hi = max(0, round(centre) - w), min(len(s), round(centre) + w + 1)
        if hi <= lo:
            return None
        t = lo + int(np.argmin(s[lo:hi]))
        return t if s[t] < RHYTHM_CROSS * cross_m else None

    k = 0
    while k < len(out):  # forwards: after each passing, up to the next one or the end
        nxt = out[k + 1] if k + 1 < len(out) else len(s) - 1
        if nxt - out[k] > RHYTHM_GAP * step and (t := closest(out[k] + step)) is not None and \
                out[k] + w < t < nxt - w:
            out.insert(k + 1, t)
        k += 1
    while out[0] > RHYTHM_GAP * step and (t := closest(out[0] - step)) is not None and w < t < out[0] - w:
        out.insert(0, t)  # backwards from the first
    return out


def order_sign(d: np.ndarray, margin_m: float) -> tuple[int, bool]:
    """Which ankle leads over a stretch of frames, from their fore-aft separation d (n,) (left minus
    right along the walking line, metres): the sign (+1: the left, -1: the right, 0: the ankles
    never more than ``margin_m`` apart) of the median over the frames where they are further apart
    than ``margin_m``, and whether every such frame has that sign (no exchange within the stretch)."""
    apart = d[np.isfinite(d) & (np.abs(d) > margin_m)]
    if not len(apart):
        return 0, False
    sign = int(np.sign(np.median(apart)))
    return sign, bool(np.all(np.sign(apart) == sign))


def alternating_stretches(d_forward: np.ndarray, d_backward: np.ndarray, d_merged: np.ndarray, rate_hz: float,
                          cross_m: float, margin_m: float) -> list[tuple[int, int, int]]:  # fmt: skip
    """The stretches of frames between the feet's passings and the ankle that must lead in each:
    (start, stop, sign), sign +1 the left ankle ahead, -1 the right one.

    Walking, the feet pass each other twice a stride, so the leading ankle changes from one
    stretch to the next. A tracker that keeps the same leg ahead where the feet meet (the two leg
    assignments fit the silhouettes alike, seen from beside or along the walkway) exchanges the legs
    for the whole next stretch. The passings are found from the fore-aft distance between the
    ankles, which such an exchange leaves unchanged: :func:`crossing_frames` of the mean of the two
    passes' |d|. Of the two alternating sequences of signs, the one that the merged passes follow in
    more frames (the ankles further apart than ``margin_m``) is kept: it changes the fewest frames
    of what the silhouettes chose; a tie goes to the forward pass's first stretch with a leading
    ankle (its start was settled over the first frames: :func:`gaitcap.tracking.init.settle_legs`).

    Args:
        d_forward, d_backward, d_merged: (T,) the two passes' and their merge's fore-aft separation of
            the ankles, left minus right along the walking line, metres (NaN: unknown).
        rate_hz: frame rate.
        cross_m: the feet pass where they come closer than this (metres).
        margin_m: the ankles lead where they are further apart than this (metres).

    Returns:
        The stretches in order, crossing frames left out; empty when no stretch has a leading ankle.
    """
    d_forward, d_backward, d_merged = (np.asarray(d, float) for d in (d_forward, d_backward, d_merged))
    if not d_forward.shape == d_backward.shape == d_merged.shape or d_forward.ndim != 1:
        raise ValueError(f"d_forward, d_backward and d_merged must be (T,) alike, got {d_forward.shape}, "
                         f"{d_backward.shape} and {d_merged.shape}")  # fmt: skip
    with np.errstate(invalid="ignore"):
        separation = np.nanmean(np.abs(np.stack([d_forward, d_backward])), axis=0)
    bounds = [-1, *crossing_frames(separation, rate_hz, cross_m), len(d_forward)]
    stretches = [(a + 1, b) for a, b in itertools.pairwise(bounds) if b - a > 1]
    first = next(((k, sign) for k, (a, b) in enumerate(stretches) if (sign := order_sign(d_forward[a:b], margin_m)[0])),
                 None)  # fmt: skip
    if first is None:
        return []
    k0, sign0 = first
    signs = [sign0 * (-1) ** (k - k0) for k in range(len(stretches))]
    with np.errstate(invalid="ignore"):
        votes = sum(int(np.sum(d_merged[a:b] * sign > margin_m) - np.sum(d_merged[a:b] * sign < -margin_m))
                    for (a, b), sign in zip(stretches, signs))  # fmt: skip
    flip = -1 if votes < 0 else 1
    return [(a, b, flip * sign) for (a, b), sign in zip(stretches, signs)]


def order_legs(chosen: dict[int, _Estimate], forward: np.ndarray, fit: np.ndarray, poses: np.ndarray,
               back: list[_Estimate], names: tuple[str, ...], rate_hz: float,
               again: Callable[[np.ndarray, int, int, bool], list[_Estimate]], mirrored: Callable[[np.ndarray], np.ndarray],
               cfg: BackwardConfig, margin_m: float,
               refine: Callable[[np.ndarray, int], _Estimate] | None = None,
               lines: np.ndarray | None = None) -> None:  # fmt: skip
    """Put right, in ``chosen``, the stretches of a merged run whose leading ankle does not alternate.

    Between the feet's passings (:func:`alternating_stretches`), a stretch of the merged passes whose
    ankles lead the other way, or change places within it, takes instead, among those that lead as
    they must throughout, the better-fitting of the forward and the backward pass; failing those, the
    stretch tracked again from the leg-swapped mirror of the pose where the feet passed before it
    (for the first stretch: after it, tracking back in time), if it leads so throughout; failing
    that (a tracker started from the mirror can exchange the legs again on the next frames, where the
    silhouettes prefer them so), the merge itself with the legs exchanged in its frames whose ankles
    lead the wrong way, each such frame searched again from there on its own (``refine``), if it then
    leads so throughout; failing that, the better-fitting of the passes and that exchanged merge
    leading so over most of it (a frame beside a passing, its ankles a few centimetres apart, can
    stay on the wrong side). The replacement must fit within ``cfg.order_fit_tolerance``
    of what it replaces (mean fit over the stretch), so that the silhouettes still decide where they
    can: the rule only breaks their ties.

    Args:
        chosen: frame of the run -> the estimate it takes (absent: the forward pass's); updated in place.
        forward: (n, P, 3) the forward pass's points over the run; ``fit`` (n,) and ``poses`` (n, D) its fits and poses.
        back: the backward pass's n estimates.
        names: the point names (P,).
        again: (start pose (D,), a, b, backwards) -> the estimates of frames a..b-1 (in that order) tracked
            from that pose, from frame a onwards, or with ``backwards`` from frame b - 1 back to a.
        mirrored: a pose (D,) -> the same with the legs exchanged.
        margin_m: the ankles lead where they are further apart than this (metres).
        refine: (pose (D,), frame t of the run) -> frame t's estimate searched from that pose alone (no
            other hypothesis; :meth:`gaitcap.tracking.base.Tracker.refine`); None: not tried.
        lines: (n, 2) each frame's walking direction, the fore-aft order read along it (a turn walked
            round); None: one walking line for the run (:func:`gaitcap.quality.walking_line`).
    """
    line = walking_line(forward, names) if lines is None else None
    if lines is None and line is None:
        return

    def along(points: np.ndarray, a: int) -> np.ndarray:  # the fore-aft order of frames a.. (points (k, P, 3))
        return fore_aft(points, names, line if line is not None else lines[a : a + len(points)])

    d_forward = along(forward, 0)
    d_back = along(np.array([b.points for b in back]), 0)
    # the merge as it enters (``chosen`` holds backward estimates only); stretches do not overlap, so
    # a stretch's frames are still so when it is reached
    merged = np.array([t in chosen for t in range(len(forward))], bool)
    d_merged = np.where(merged, d_back, d_forward)
    fit_merged = np.where(merged, [x.fit for x in back], fit)

    def lead(ests: list[_Estimate], a: int) -> tuple[int, bool]:  # estimates of frames a..
        return order_sign(along(np.array([x.points for x in ests]), a), margin_m)

    def merged_pose(t: int) -> np.ndarray:  # frame t's pose in the merge as it stands
        return chosen[t].q if t in chosen else poses[t]

    for a, b, sign in alternating_stretches(d_forward, d_back, d_merged, rate_hz, cfg.crossing_m, margin_m):
        if order_sign(d_merged[a:b], margin_m) == (sign, True):
            continue
        now_fit = float(np.mean(fit_merged[a:b]))
        steady, mostly = [], []  # (mean fit, estimates (None: the forward pass's)) leading as they must
        for d, ests, fits in ((d_forward[a:b], [None] * (b - a), fit[a:b]),
                              (d_back[a:b], back[a:b], [x.fit for x in back[a:b]])):  # fmt: skip
            leads, throughout = order_sign(d, margin_m)
            if leads == sign:
                (steady if throughout else mostly).append((float(np.mean(fits)), ests))
        if not steady and (a > 0 or b < len(forward)):  # the stretch again, from the mirror of the pose where
            # the feet passed before it (forwards), or after it for a first stretch (backwards)
            at = a - 1 if a > 0 else b
            redone = again(mirrored(merged_pose(at)), a, b, a == 0)
            if lead(redone, a) == (sign, True):
                steady.append((float(np.mean([x.fit for x in redone])), redone))
        if not steady and refine is not None:  # the merge, its frames that lead the wrong way exchanged
            ests, fits, d = [chosen.get(t) for t in range(a, b)], fit_merged[a:b].copy(), d_merged[a:b].copy()
            for k in np.flatnonzero(d * sign < -margin_m):
                x = refine(mirrored(merged_pose(a + k)), a + k)
                ests[k], fits[k], d[k] = x, x.fit, along(x.points[None], a + k)[0]
            leads, throughout = order_sign(d, margin_m)
            if leads == sign:
                (steady if throughout else mostly).append((float(np.mean(fits)), ests))
        best = max(steady or mostly, key=lambda c: c[0], default=None)
        log.debug("leg order: frames %d-%d, %s ankle must lead (fit %.4f): %d candidates leading so throughout, "
                  "%d mostly; best fit %s", a, b - 1, "left" if sign > 0 else "right", now_fit, len(steady),
                  len(mostly), "-" if best is None else f"{best[0]:.4f}")  # fmt: skip
        if best is None or best[0] < now_fit - cfg.order_fit_tolerance:
            continue
        for k, est in enumerate(best[1]):
            if est is None:
                chosen.pop(a + k, None)
            else:
                chosen[a + k] = est
