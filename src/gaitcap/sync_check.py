"""Do the cameras' videos start at the same instant? A check of a session's frame sync, from the silhouettes.

gaitcap takes frame k of every video as one instant (the session format). Cameras started by hand
(webcams, phones, camcorders) often are not: one video starts a frame or a few after the other, and
the views then disagree by what the subject moved in between. On two synthetic walks (2 cameras,
25 fps, both videos re-encoded alike), one frame raised the lower-limb error from 22-30 mm to
48-68 mm and two frames to 77-164 mm, the verdict ok at one frame and nothing else said.

How it is found: the head rises and falls once a step, and that motion is vertical, so every camera
sees it at the same instants whatever its view of the walk. Per frame and camera, the top of the
silhouette to a fraction of a row (:func:`head_top`); per camera, the series less its samples more
than :data:`SPIKE_ROWS` rows off its running median of :data:`SPIKE_FRAMES` frames (a blob above the
head in one frame), and less its quadratic trend over the clip's first :data:`WINDOW_S` seconds (the
subject nearing or leaving the camera). For each pair of cameras the two series are correlated at
lags of up to :data:`MAX_LAG_S`; the lag of the best correlation, refined to a fraction of a frame by a
parabola through it and its neighbours, is the offset between the two videos (:func:`pair_offset`). A
pair is judged only when that correlation is :data:`MIN_CORRELATION` or more at a lag inside the range,
and out of step when the refined lag is :data:`MIN_OFFSET_S` or more (0.8 frame at 25 fps).

Measured 2026-12-02 on the tracking-scale silhouettes ``gaitcap track`` sees (default configuration):
59 synchronised sessions (the suite's 24, the six external ones, 29 more drawn by ``gaitcap synth`` from
the three walks with other seeds), 85 camera pairs: 78 judged (no pair in 7 two-camera sessions: a
camera whose view of the head's motion is too faint or noisy), the largest refined lag 0.61 frame, none
out of step. The same series with one camera's started 1, 2 or 4 frames later (either camera): one
frame found in 134 of the 156 judged pairs (86 %; the refined lag within 0.6 frame of the truth in all),
two and four frames in all. Copies of two walks re-encoded with camera 2 started d frames later: d = 1
read 1.13 and 0.51 frames (the second not reported), d = 2 1.99 and 1.65, d = 4 3.88 and 3.51 (the
second at a correlation of 0.67: not judged); camera 1 later: -0.85 / -1.17, -1.77 / -2.15, -3.77 /
-4.21. So a one-frame offset is not always told from none; two frames or more mostly are. The width of the silhouette's lowest quarter (the legs' spread), which a walk
also repeats every step, was tried first and dropped: its phase depends on how the camera sees the
walk (4 of the 59 sessions read about a frame out of step when synchronised).
"""

from __future__ import annotations

import logging
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

#: the top of a silhouette is its first row holding this many pixels' worth (a stray pixel is not it)
MIN_ROW_MASS = 2.0
#: the rows from the top whose fill refines it to a fraction of a row (the top of the head)
TOP_ROWS = 8
#: a silhouette of fewer pixels (working resolution) gives no value
MIN_PIXELS = 20
#: the longest offset looked for, seconds (6 frames at 25 fps): a step lasts about 0.5 s, and lags of
#: half a step correlate negatively, so the range stays well inside one step
MAX_LAG_S = 0.24
#: the seconds of the clip looked at, from its start (the quadratic trend fits a short walk only)
WINDOW_S = 4.0
#: the most frames a run keeps for the check (WINDOW_S at 120 fps): a run's memory stays flat in its length
MAX_FRAMES = 480
#: fewer seconds of frames overlapping at a lag: the pair is not judged (two steps at least)
MIN_OVERLAP_S = 1.2
#: a pair whose best correlation is lower is not judged
MIN_CORRELATION = 0.7
#: a refined lag of this many seconds or more is reported (0.8 frame at 25 fps)
MIN_OFFSET_S = 0.032
#: a sample this many rows off the series' running median is left out (a blob above the head) ...
SPIKE_ROWS = 2.0
#: ... the running median over this many frames
SPIKE_FRAMES = 5


def head_top(silhouette: np.ndarray) -> float:
    """How high the top of a silhouette (h, w) (soft, 0..1) is in the image, in rows, up positive, to a
    fraction of a row: the first row holding :data:`MIN_ROW_MASS` pixels' worth, plus the part of the
    :data:`TOP_ROWS` rows from it that the silhouette leaves empty (its mass over the band's widest row);
    NaN for a silhouette of less than :data:`MIN_PIXELS` pixels' worth."""
    mass = silhouette.sum(axis=1, dtype=np.float64)
    if mass.sum() < MIN_PIXELS:
        return math.nan
    first = np.nonzero(mass >= MIN_ROW_MASS)[0]
    if not len(first):
        return math.nan
    r0 = int(first[0])
    band = mass[r0 : r0 + TOP_ROWS]
    return -(r0 + len(band) - float(band.sum()) / float(band.max()))


def _despiked(x: np.ndarray) -> np.ndarray:
    """``x`` with NaN where a sample lies more than :data:`SPIKE_ROWS` from the running median of
    :data:`SPIKE_FRAMES` frames (the ends padded with their own values)."""
    if len(x) < SPIKE_FRAMES:
        return x
    half = SPIKE_FRAMES // 2
    padded = np.concatenate([np.full(half, x[0]), x, np.full(half, x[-1])])
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a window of NaN only (no silhouette): its median NaN
        median = np.nanmedian(np.lib.stride_tricks.sliding_window_view(padded, SPIKE_FRAMES), axis=1)
        return np.where(np.abs(x - median) > SPIKE_ROWS, np.nan, x)


def _detrended(x: np.ndarray) -> np.ndarray:
    t = np.arange(len(x), dtype=float)
    ok = np.isfinite(x)
    if ok.sum() < 5:
        return np.full(len(x), np.nan)
    return x - np.polyval(np.polyfit(t[ok], x[ok], 2), t)


def _correlation(a: np.ndarray, b: np.ndarray, lag: int, min_frames: int) -> float:
    """Correlation of a[j + lag] with b[j] over the frames both hold; NaN under ``min_frames`` frames."""
    j = np.arange(len(b))
    j = j[(j + lag >= 0) & (j + lag < len(a))]
    x, y = a[j + lag], b[j]
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < min_frames:
        return math.nan
    x, y = x[ok] - x[ok].mean(), y[ok] - y[ok].mean()
    den = math.sqrt(float(x @ x) * float(y @ y))
    return float(x @ y) / den if den > 0 else math.nan


@dataclass(frozen=True)
class PairOffset:
    """Two cameras' videos compared (:func:`pair_offset`).

    Attributes:
        first, second: the cameras (rig order).
        lag: the refined lag, frames: frame j of ``second`` shows the instant of frame j + lag of
            ``first`` (positive: ``second``'s video started later).
        correlation: the two series' correlation at the best whole lag.
        judged: whether the pair says anything (see the module docstring); when False ``lag`` is
            meaningless.
    """

    first: str
    second: str
    lag: float
    correlation: float
    judged: bool


def pair_offset(a: np.ndarray, b: np.ndarray, fps: float, first: str = "a", second: str = "b") -> PairOffset:
    """The offset between two cameras' :func:`head_top` series (T,) (NaN where not seen), frame j of
    ``b`` against frame j + lag of ``a``."""
    n = min(len(a), len(b), max(1, round(WINDOW_S * fps)))
    a, b = (_detrended(_despiked(np.asarray(x[:n], float))) for x in (a, b))
    max_lag = max(2, round(MAX_LAG_S * fps))
    lags = np.arange(-max_lag, max_lag + 1)
    r = np.array([_correlation(a, b, int(k), round(MIN_OVERLAP_S * fps)) for k in lags])
    if not np.isfinite(r).any():
        return PairOffset(first, second, math.nan, math.nan, False)
    from gaitcap.gait.signals import parabolic_peak  # with scipy.signal, which a run imports late anyway

    i = int(np.nanargmax(r))
    inside = 0 < i < len(r) - 1 and bool(np.isfinite(r[i - 1]) and np.isfinite(r[i + 1]))
    lag = float(lags[i]) + (parabolic_peak(r, i) - i)  # the parabola's vertex through the best lag and its neighbours
    return PairOffset(first, second, lag, float(r[i]), inside and r[i] >= MIN_CORRELATION)


def pair_offsets(tops: np.ndarray, cameras: Sequence[str], fps: float) -> list[PairOffset]:
    """Every pair of cameras compared; ``tops``: (T, C) :func:`head_top` per frame and camera."""
    tops = np.asarray(tops, float).reshape(len(tops), len(cameras))
    return [pair_offset(tops[:, i], tops[:, j], fps, cameras[i], cameras[j])
            for i in range(len(cameras)) for j in range(i + 1, len(cameras))]  # fmt: skip


def out_of_step(pairs: Sequence[PairOffset], fps: float) -> list[PairOffset]:
    """The judged pairs whose videos are out of step by :data:`MIN_OFFSET_S` or more."""
    return [p for p in pairs if p.judged and abs(p.lag) >= MIN_OFFSET_S * fps]


def start_delays(pairs: Sequence[PairOffset], cameras: Sequence[str]) -> dict[str, int]:
    """Each camera's start after the earliest one, whole frames, from the judged pairs (the
    strongest first: a spanning tree), for the cameras the judged pairs connect to the first such
    camera; the others are left out."""
    judged = sorted((p for p in pairs if p.judged), key=lambda p: -p.correlation)
    if not judged:
        return {}
    start: dict[str, float] = {judged[0].first: 0.0}
    grew = True
    while grew:
        grew = False
        for p in judged:
            if p.first in start and p.second not in start:
                start[p.second] = start[p.first] + p.lag
                grew = True
            elif p.second in start and p.first not in start:
                start[p.first] = start[p.second] - p.lag
                grew = True
    earliest = min(start.values())
    return {c: round(start[c] - earliest) for c in cameras if c in start}


def _s(n: int) -> str:
    return "" if n == 1 else "s"


def out_of_step_listing(pairs: Sequence[PairOffset], fps: float) -> str:
    """The pairs out of step (:func:`out_of_step`) in words, "cam2's video starts 1.1 frames (45 ms)
    after cam1's (correlation 0.92); ..."; empty when none is."""
    return "; ".join(
        f"{p.second}'s video starts {abs(p.lag):.1f} frames ({1000 * abs(p.lag) / fps:.0f} ms) "
        f"{'after' if p.lag > 0 else 'before'} {p.first}'s (correlation {p.correlation:.2f})"
        for p in out_of_step(pairs, fps))  # fmt: skip


def sync_note(pairs: Sequence[PairOffset], cameras: Sequence[str], fps: float,
              videos: Mapping[str, Path] | None = None, skipped: Mapping[str, int] | None = None) -> str | None:  # fmt: skip
    """One sentence for track.json and the log when some pair is out of step (:func:`out_of_step`),
    naming the cameras, the offset in frames and milliseconds, the ``skip_frames`` of session.yaml that
    would bring them into step (``skipped``: the session's own, which the offsets were measured after)
    and how to trim the videos instead; else None."""
    found = out_of_step_listing(pairs, fps)
    if not found:
        return None
    trims = _trims(pairs, cameras)
    fix = ""
    if trims:
        def video(c: str) -> str:
            return f"videos/{videos[c].name}" if videos and c in videos else f"videos/{c}.mp4"
        cmds = "; ".join(f"ffmpeg -i {video(c)} -vf \"trim=start_frame={k},setpts=PTS-STARTPTS\" -an {c}_synced.mp4"
                         for c, k in trims.items())  # fmt: skip
        setting = skip_setting(corrected_skips(trims, skipped or {}, cameras))
        fix = (f": set skip_frames: {setting} in session.yaml (frames dropped at the start of a camera's video, "
               f"without re-encoding it) and track again, or trim the first "
               f"{', '.join(f'{k} frame{_s(k)} of {c}' for c, k in trims.items())}, e.g. {cmds}, "
               "and put the result in place of the original (moved out of videos/)")
    return (f"the cameras' videos look out of step ({found}; from when the head rises and falls in each "
            f"camera's silhouettes): gaitcap takes frame k of every video as one instant, and views out of step "
            f"by a frame put the joints centimetres off{fix}")


def _trims(pairs: Sequence[PairOffset], cameras: Sequence[str]) -> dict[str, int]:
    """The whole frames each camera is to lose at its start to be in step with the latest one
    (:func:`start_delays`); the cameras with none are left out."""
    delays = start_delays(pairs, cameras)
    latest = max(delays.values(), default=0)
    return {c: latest - d for c, d in delays.items() if latest - d > 0}


def advised_skips(pairs: Sequence[PairOffset], cameras: Sequence[str], fps: float,
                  skipped: Mapping[str, int] | None = None) -> dict[str, int] | None:  # fmt: skip
    """session.yaml's ``skip_frames`` that would bring out-of-step cameras (:func:`out_of_step`) into
    step, the session's own (``skipped``) added in (:func:`corrected_skips`); None when no pair is out of
    step or the judged pairs give no camera a whole frame to lose."""
    if not out_of_step(pairs, fps):
        return None
    trims = _trims(pairs, cameras)
    return corrected_skips(trims, skipped or {}, cameras) if trims else None


def skip_setting(skips: Mapping[str, int]) -> str:
    """``skip_frames`` as written in session.yaml: "{cam1: 2}"."""
    return "{" + ", ".join(f"{c}: {k}" for c, k in skips.items()) + "}"


def corrected_skips(trims: Mapping[str, int], skipped: Mapping[str, int], cameras: Sequence[str]) -> dict[str, int]:
    """session.yaml's ``skip_frames`` that would bring the cameras into step: the session's own
    (``skipped``) plus the frames each camera is to lose (``trims``, measured after them), less what
    every camera would skip alike; the cameras left at 0 are left out."""
    total = {c: int(skipped.get(c, 0)) + int(trims.get(c, 0)) for c in cameras}
    least = min(total.values(), default=0)
    return {c: k - least for c, k in total.items() if k > least}


@dataclass(frozen=True)
class SyncFinding:
    """Cameras out of step (:func:`find_out_of_step`).

    Attributes:
        listing: the pairs out of step in words (:func:`out_of_step_listing`), for a verdict's reason.
        note: :func:`sync_note`, with the skip_frames to set and how to trim the videos.
        skips: the ``skip_frames`` that would bring them into step (:func:`advised_skips`), or None.
        lag: the largest offset of the pairs out of step, frames (absolute).
    """

    listing: str
    note: str
    skips: dict[str, int] | None
    lag: float


def find_out_of_step(tops: np.ndarray | Sequence[Sequence[float]], cameras: Sequence[str], fps: float,
                     videos: Mapping[str, Path] | None = None,
                     skipped: Mapping[str, int] | None = None) -> SyncFinding | None:  # fmt: skip
    """The check of a session's :func:`head_top` series ``tops`` (T, C): the cameras out of step, or None
    (in step, or no pair judged); ``videos``, ``skipped``: see :func:`sync_note`."""
    pairs = pair_offsets(np.asarray(tops, float).reshape(len(tops), len(cameras)), cameras, fps)
    for p in pairs:
        log.debug("frame sync %s-%s: lag %.2f frames, correlation %.2f%s", p.first, p.second, p.lag, p.correlation,
                  "" if p.judged else " (not judged)")  # fmt: skip
    note = sync_note(pairs, cameras, fps, videos, skipped)
    if note is None:
        return None
    lag = max(abs(p.lag) for p in out_of_step(pairs, fps))
    return SyncFinding(out_of_step_listing(pairs, fps), note, advised_skips(pairs, cameras, fps, skipped), lag)


class SyncRecorder:
    """The check of a session's frame sync from its full-resolution masks (``gaitcap silhouettes``):
    each frame's masks are taken to the silhouettes ``gaitcap track`` sees (the shipped tracking scale,
    undistorted), where the check's thresholds were measured, and their :func:`head_top` kept for the
    first :data:`MAX_FRAMES` frames."""

    def __init__(self, cameras: Sequence, scale: float | None = None) -> None:
        """``cameras``: the calibrated cameras (:class:`gaitcap.camera.Camera`), in the masks' order;
        ``scale``: the silhouettes' scale (None: the shipped tracking.yaml's)."""
        from gaitcap.camera import CameraRig
        from gaitcap.tracking.config import load_tracking_config
        from gaitcap.tracking.observation import tracking_views

        scale = load_tracking_config().scale if scale is None else scale
        self.cameras = [c.name for c in cameras]
        self._views = tracking_views(CameraRig(tuple(cameras)), scale)
        self.tops: list[list[float]] = []

    def add(self, index: int, masks: Sequence[np.ndarray]) -> None:
        """Frame ``index``'s (H, W) masks, one per camera (``run_silhouettes``' ``on_masks``)."""
        if len(self.tops) < MAX_FRAMES:
            self.tops.append([head_top(v.prepare(m)) for v, m in zip(self._views, masks, strict=True)])

    def note(self, fps: float, videos: Mapping[str, Path] | None = None,
             skipped: Mapping[str, int] | None = None) -> str | None:  # fmt: skip
        """:func:`sync_note` of the frames added, or None (in step, or not judged)."""
        found = find_out_of_step(self.tops, self.cameras, fps, videos, skipped) if self.tops else None
        return None if found is None else found.note
