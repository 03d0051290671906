"""A clip's passes along the walkway, from the pelvis's horizontal path.

A subject walking up and down a room turns back at each end, often stopping to pivot on the spot. A
*turn* is a peak of the pelvis's position along its travel axis (the principal axis of its
horizontal positions) with a prominence of :data:`TURN_M`: the pelvis went that far one way and as
far back. A walk never takes the pelvis backwards (the tracked pelvis of the suite's walks goes back
1 cm at most: docs/validation.md), and a walk on the spot (a treadmill, the pelvis travelling less
than :data:`MIN_TRAVEL_M`) has no turns. At each turn, the run of frames whose pelvis moves at less
than :data:`MIN_SPEED_M_S` (its displacement over :data:`SPEED_SPAN_S`) nearest the turn is its
*pause*: a pivot, where the feet step round and follow no stride.

A *pass* is the stretch between two turns (or a clip's end), its pauses left out, and the frames next
to a turn where the pelvis heads more than :data:`TURN_HEADING_DEG` off the pass's direction (a turn
walked round without a stop): a straight walk with its own direction of progression, as a gait lab's
clip of one crossing is. Everything here reads
a pelvis path xy (T, 2) metres (NaN frames ignored) sampled at ``rate_hz``; the verdict
(:mod:`gaitcap.quality`) and the gait analysis (:mod:`gaitcap.gait.analysis`) both use it.
"""

from __future__ import annotations

import numpy as np

from gaitcap.timeseries import finite_runs

#: a pelvis travelling less than this (metres) along its principal axis walks on the spot (a treadmill)
MIN_TRAVEL_M = 0.5
#: metres the pelvis travels back along its travel axis, and had travelled forth, where the walk turns
TURN_M = 0.1
#: the pelvis moves when its horizontal speed is at least this (m/s; a slow walk is 0.4-0.8)
MIN_SPEED_M_S = 0.2
#: the pelvis's velocity is its displacement over this span (seconds), centred on the frame
SPEED_SPAN_S = 0.4
#: a *stop* in a pass: the pelvis and both feet (heels and toes) each move horizontally at less than this
#: (m/s, their displacement over :data:`SPEED_SPAN_S`, centred) ... The fastest of them stays above
#: 0.36 m/s over any 0.5 s of the real walks slowed three times (0.3 m/s, strides of 3.3-3.6 s), and
#: under 0.05 m/s over the middle of a tracked 1 s stop (the walk's synthetic session held still)
STOP_SPEED_M_S = 0.1
#: ... for at least this long (s): a stop and a start, not a slow step (a foot swings in every step);
#: the span's reach makes it a stop of about 0.7 s or more
MIN_STOP_S = 0.3
#: degrees: next to a turn, a pass ends where the pelvis's velocity heads further than this off the
#: pass's direction (the straight walks of the suite and the held-out draw stay within 17 degrees)
TURN_HEADING_DEG = 20.0


def travel_axis(xy: np.ndarray) -> np.ndarray | None:
    """Unit horizontal vector (2,): the principal axis of the pelvis positions xy (T, 2) when they
    travel :data:`MIN_TRAVEL_M` or more along it, else None (NaN frames ignored)."""
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    if len(xy) < 2:
        return None
    centred = xy - xy.mean(axis=0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    return axis if np.ptp(centred @ axis) >= MIN_TRAVEL_M else None


def turns(xy: np.ndarray) -> np.ndarray:
    """(K,) int, increasing: the frames of the pelvis path xy (T, 2) just after each point where the
    walk turns back (a peak of the position along :func:`travel_axis` with a prominence of
    :data:`TURN_M`). Empty without a travel axis; NaN frames ignored."""
    from scipy.signal import find_peaks  # here, not at start-up (gaitcap.pipeline._import_late)

    line = travel_axis(xy)
    if line is None:
        return np.zeros(0, int)
    frames = np.flatnonzero(np.all(np.isfinite(xy), axis=1))
    along = xy[frames] @ line
    peaks = np.concatenate([find_peaks(sign * along, prominence=TURN_M)[0] for sign in (1.0, -1.0)])
    return np.sort(frames[peaks]) + 1


def pelvis_velocity(xy: np.ndarray, rate_hz: float) -> np.ndarray:
    """(T, 2) m/s: the velocity of the pelvis path xy (T, 2), its displacement over
    :data:`SPEED_SPAN_S` centred on the frame; NaN within half the span of the path's ends and where
    a frame of the span's ends is missing. (Paths (T, ..., 2) of other points alike: :func:`stops`.)"""
    half = max(1, round(SPEED_SPAN_S * rate_hz / 2))
    T = len(xy)
    velocity = np.full(np.shape(xy), np.nan)
    if T > 2 * half:
        velocity[half:-half] = (xy[2 * half :] - xy[: -2 * half]) * (rate_hz / (2 * half))
    return velocity


def headings(xy: np.ndarray, rate_hz: float) -> np.ndarray:
    """(T, 2): the unit direction of the pelvis path xy (T, 2)'s velocity (:func:`pelvis_velocity`)
    where it moves at :data:`MIN_SPEED_M_S` or more, NaN elsewhere."""
    velocity = pelvis_velocity(xy, rate_hz)
    with np.errstate(invalid="ignore", divide="ignore"):
        speed = np.linalg.norm(velocity, axis=1, keepdims=True)
        return np.where(speed >= MIN_SPEED_M_S, velocity / speed, np.nan)


def paused_at_turns(xy: np.ndarray, rate_hz: float, at: np.ndarray | None = None) -> np.ndarray:
    """(T,) bool: the frames of the pelvis path xy (T, 2) where it pauses at a turn (``at``:
    :func:`turns`, found when not given): the run of frames moving at less than
    :data:`MIN_SPEED_M_S` (:func:`pelvis_velocity`) that holds the still frame nearest each turn,
    within :data:`SPEED_SPAN_S` of it. The turn's frame is where the pelvis goes furthest, which a
    tracked pelvis drifting a few millimetres while it stands can put at the pause's edge or just past
    it."""
    at = turns(xy) if at is None else at
    out = np.zeros(len(xy), bool)
    if not len(at):
        return out
    with np.errstate(invalid="ignore"):
        still = np.linalg.norm(pelvis_velocity(xy, rate_hz), axis=1) < MIN_SPEED_M_S
    reach = max(1, round(SPEED_SPAN_S * rate_hz))
    for k in at:
        near = [i for i in range(k - reach, k + reach) if 0 <= i < len(xy) and still[i]]
        if not near:
            continue
        lo = hi = min(near, key=lambda i: abs(i - (k - 0.5)))  # the turn lies between frames k - 1 and k
        while lo > 0 and still[lo - 1]:
            lo -= 1
        while hi + 1 < len(xy) and still[hi + 1]:
            hi += 1
        out[lo : hi + 1] = True
    return out


def walk_passes(xy: np.ndarray, rate_hz: float, pauses: bool = True) -> list[tuple[int, int]]:
    """The passes of the pelvis path xy (T, 2): (start, stop) frames of each stretch between turns,
    its pauses at them left out, and half of :data:`SPEED_SPAN_S` more either side of each pause
    (the span's velocity reaches into the pause by up to that: a stop and a pivot's first frames
    would be taken for walking), and the frames next to a turn that head off the pass's direction
    (:func:`straight_part`); stretches of pause or turn alone dropped; [(0, T)] without a turn.
    ``pauses`` False: the pauses kept in the passes (a stretch then ends at its turn, or where a turn
    walked round begins)."""
    at = turns(xy)
    if not len(at):
        return [(0, len(xy))]
    return _passes_between(xy, rate_hz, at, pauses, headings(xy, rate_hz))


def directed_passes(xy: np.ndarray, rate_hz: float) -> list[tuple[int, int, np.ndarray | None]]:
    """The passes of the pelvis path xy (T, 2) as the tracker's leg order takes them (``gaitcap.
    pipeline``): (start, stop, lines), the stretches between turns (:func:`turns`; a pivot on the spot
    keeps its frames, whose steps still alternate), ``lines`` None where the stretch is straight (one
    walking line), else (stop - start, 2) each frame's walking direction: its :func:`headings` where
    it walks round a turn (the frames :func:`walk_passes` leaves out), the pass's net displacement's
    on the straight. [(0, T, None)] without a turn."""
    T = len(xy)
    at = turns(xy)
    if not len(at):
        return [(0, T, None)]
    heading = headings(xy, rate_hz)
    straight = _passes_between(xy, rate_hz, at, False, heading)
    out: list[tuple[int, int, np.ndarray | None]] = []
    for a, b in zip([0, *at.tolist()], [*at.tolist(), T], strict=True):
        inner = [(p, q) for p, q in straight if a <= p and q <= b]
        if not inner or inner[0] == (a, b):
            out.append((a, b, None))
            continue
        p, q = inner[0]
        travel = xy[q - 1] - xy[p]
        lines = np.tile(travel / max(float(np.linalg.norm(travel)), 1e-9), (b - a, 1))
        turning = np.ones(b - a, bool)
        turning[p - a : q - a] = False
        turning &= np.all(np.isfinite(heading[a:b]), axis=1)
        lines[turning] = heading[a:b][turning]
        out.append((a, b, lines))
    return out


def _passes_between(xy: np.ndarray, rate_hz: float, at: np.ndarray, pauses: bool,
                    heading: np.ndarray) -> list[tuple[int, int]]:  # fmt: skip
    """:func:`walk_passes` of the pelvis path xy (T, 2) given its turns ``at`` (K,) and its
    :func:`headings` (T, 2)."""
    T = len(xy)
    moving = np.arange(T)
    if pauses:
        half = max(1, round(SPEED_SPAN_S * rate_hz / 2))
        moving = np.flatnonzero(np.convolve(paused_at_turns(xy, rate_hz, at), np.ones(2 * half + 1), mode="same") == 0)
    out = []
    for a, b in zip([0, *at.tolist()], [*at.tolist(), T], strict=True):
        inside = moving[(moving >= a) & (moving < b)]
        if len(inside):
            part = straight_part(xy, heading, int(inside[0]), int(inside[-1]) + 1, a > 0, b < T)
            if part is not None:
                out.append(part)
    return out


def straight_part(xy: np.ndarray, heading: np.ndarray, start: int, stop: int, after_turn: bool,
                  before_turn: bool) -> tuple[int, int] | None:  # fmt: skip
    """Frames (start, stop) of the pelvis path xy (T, 2) without the runs of frames at an end next
    to a turn (``after_turn``: the start, ``before_turn``: the stop) whose :func:`headings` (T, 2)
    point more than :data:`TURN_HEADING_DEG` off the pass's direction (its pelvis's net displacement,
    taken again on what is left until nothing more is cut); frames without a heading (slower than
    :data:`MIN_SPEED_M_S`, or no velocity) are not judged. None when nothing is left."""
    cos_max = np.cos(np.radians(TURN_HEADING_DEG))
    for _ in range(8):  # a few rounds: each leaves less of the turn to pull the direction
        travel = xy[stop - 1] - xy[start]
        if stop - start < 2 or not np.all(np.isfinite(travel)) or not np.linalg.norm(travel):
            return (start, stop) if stop > start else None
        with np.errstate(invalid="ignore"):
            off = heading[start:stop] @ (travel / np.linalg.norm(travel)) < cos_max
        a, b = start, stop
        while after_turn and a < b and off[a - start]:
            a += 1
        while before_turn and b > a and off[b - 1 - start]:
            b -= 1
        if (a, b) == (start, stop):
            return (start, stop)
        if b <= a:
            return None
        start, stop = a, b
    return (start, stop)


def stops(tracks: np.ndarray, rate_hz: float) -> list[tuple[int, int]]:
    """(start, stop) frames of each stop of the horizontal paths ``tracks`` (T, K, 2) (the pelvis and the
    feet): at least :data:`MIN_STOP_S` during which every path moves at less than
    :data:`STOP_SPEED_M_S` (its displacement over :data:`SPEED_SPAN_S`, centred on the frame). A subject
    who stands still in the middle of a walk: the stride across it is no gait cycle. A frame where a
    path or its span is missing is not still; empty when there is no such stop."""
    with np.errstate(invalid="ignore"):
        still = np.all(np.linalg.norm(pelvis_velocity(tracks, rate_hz), axis=-1) < STOP_SPEED_M_S, axis=1)
    return [(a, b) for a, b in finite_runs(still) if (b - a) / rate_hz >= MIN_STOP_S]
