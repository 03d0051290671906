"""Background models: the empty scene per camera, and whether it can be trusted.

Two sources:

* a **plate** (an image of the empty scene): used as is; the per-pixel noise comes from frames
  sampled across the video when they are given (``sigma = 1.4826 * median_t |I_t - B|``), else
  it is estimated later from the first frame; with the frames, a plate that does not match them
  (another camera's, room's or light's: :func:`plate_mismatch` above ``max_plate_mismatch``) is
  reported unusable, loudly;
* **frames sampled across the whole video**: ``B = median_t I_t`` per pixel and channel (a
  walker who crosses the view hides any pixel in a minority of samples, so the median is the
  empty scene), the same robust per-pixel noise, and a check that the estimate is usable.

The check: a pixel is *ambiguous* when it differs from the median by more than
``hidden_diff`` grey levels in at least ``hidden_occupancy`` of the samples, i.e. something
covers it a large part of the time, so the median there may be that something rather than
the scene. A walk-across leaves few ambiguous pixels; a subject who never leaves the view
(treadmill, balance trial) leaves a band of them around the body. Above
``max_ambiguous_fraction`` of the image the background is reported unusable, loudly.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from gaitcap.errors import InputError
from gaitcap.silhouette.config import BackgroundConfig

log = logging.getLogger(__name__)

_MAD_TO_SIGMA = 1.4826
_ROW_CHUNK = 64  # rows per chunk for the per-pixel statistics: bounds temporary memory


@dataclass(frozen=True)
class BackgroundReport:
    """How a background was obtained and whether it is usable.

    Attributes:
        source: "plate" or "video".
        samples: number of video frames used (0 for a plate without samples).
        ambiguous_fraction: fraction of pixels whose background is hidden too often
            (NaN when not measured, e.g. for a plate).
        usable: False when the estimate is judged unusable (the masks will be unreliable).
        message: one line for a person.
    """

    source: str
    samples: int
    ambiguous_fraction: float
    usable: bool
    message: str


@dataclass(frozen=True)
class Background:
    """A background model at the working resolution.

    Attributes:
        image: (H, W, 3) float32 BGR, grey levels 0-255.
        noise: (H, W) float32 per-pixel noise sigma in grey levels, or None when unknown yet.
        report: provenance and usability.
    """

    image: np.ndarray
    noise: np.ndarray | None
    report: BackgroundReport


def _check_stack(frames: np.ndarray, what: str) -> np.ndarray:
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.shape[0] < 1:
        raise InputError(f"{what}: expected sampled frames of shape (N, H, W, 3), got {frames.shape}")
    return frames


def _median(x: np.ndarray, axis: int | None = None) -> np.ndarray:
    """``np.median(x, axis)`` of a float array without NaN, equal to it bit for bit, from one
    partition along a contiguous axis: numpy partitions at both middle ranks of an even count and at
    the last element (to find NaN) too, along the axis as it lies in memory, several times the work.

    Args:
        x: float array without NaN.
        axis: the axis to take the median over, or None (the flattened array).

    Returns:
        The medians: ``x``'s shape without ``axis`` (a scalar for None).
    """
    a = x.ravel() if axis is None else np.moveaxis(x, axis, -1)
    k = a.shape[-1] // 2
    part = np.partition(np.ascontiguousarray(a), k, axis=-1)
    if a.shape[-1] % 2:
        return part[..., k]
    return np.mean(np.stack([part[..., :k].max(axis=-1), part[..., k]]), axis=0)


def _channel_mean(x: np.ndarray) -> np.ndarray:
    """``x.mean(axis=-1)`` of (..., 3) float32, bit for bit ((x0 + x1) + x2) / 3, without numpy's
    slow reduction over a short last axis."""
    return (x[..., 0] + x[..., 1] + x[..., 2]) / np.float32(3)


def global_gain(frame: np.ndarray, background: np.ndarray, stride: int = 4) -> np.ndarray:
    """Per-channel global brightness ratio frame / background (robust: a median over pixels).

    frame, background: (H, W, 3). Returns (3,) float32. Pixels where the background is very
    dark are skipped; a person covering a minority of the image does not move the median.
    """
    return global_gains(frame[None], background, stride)[0]


def global_gains(frames: np.ndarray, background: np.ndarray, stride: int = 4) -> np.ndarray:
    """:func:`global_gain` of each of ``frames`` (N, H, W, 3) against one ``background`` (H, W, 3):
    (N, 3) float32, the same values, computed for all frames at once (three medians instead of
    3 N: a background thread then waits for the interpreter far less often while others run)."""
    f = frames[:, ::stride, ::stride].reshape(len(frames), -1, 3).astype(np.float32)
    b = background[::stride, ::stride].reshape(-1, 3).astype(np.float32)
    gains = np.ones((len(frames), 3), np.float32)
    for c in range(3):
        ok = b[:, c] > 16.0
        if ok.sum() > 100:
            gains[:, c] = _median(f[:, ok, c] / b[ok, c], axis=1)
    return gains


def _robust_noise(
    frames: np.ndarray, centre: np.ndarray, min_noise: float, gains: np.ndarray | None = None,
    max_factor: float = 3.0,
) -> np.ndarray:  # fmt: skip
    """Per-pixel noise sigma: 1.4826 * median over samples of the channel-mean |I - g * centre|.

    A subject who stays at one spot in most samples (walking in place, a treadmill) makes that
    median large exactly where the subject is, which would raise the foreground threshold there
    and hide the subject; sensor and compression noise vary smoothly, so each pixel's sigma is
    capped at ``max_factor`` times the image's median sigma.

    frames: (N, H, W, 3); centre: (H, W, 3); gains: (N, 3) per-sample brightness ratios or
    None (all 1). Returns (H, W) float32 >= ``min_noise``.
    """
    n, h, w, _ = frames.shape
    g = np.ones((n, 1, 1, 3), np.float32) if gains is None else gains.reshape(n, 1, 1, 3).astype(np.float32)
    out = np.empty((h, w), np.float32)
    for r0 in range(0, h, _ROW_CHUNK):
        rows = slice(r0, r0 + _ROW_CHUNK)
        dev = frames[:, rows].astype(np.float32)
        dev -= g * centre[None, rows]
        np.abs(dev, out=dev)
        out[rows] = _MAD_TO_SIGMA * _median(_channel_mean(dev), axis=0)
    out = np.maximum(out, np.float32(min_noise))
    return np.minimum(out, np.float32(max_factor * _median(out)))


def _median_and_ambiguity(frames: np.ndarray, cfg: BackgroundConfig) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel median (H, W, 3) float32 and the ambiguous-pixel map (H, W) bool."""
    n, h, w, _ = frames.shape
    median = np.empty((h, w, 3), np.float32)
    ambiguous = np.empty((h, w), bool)
    for r0 in range(0, h, _ROW_CHUNK):
        chunk = frames[:, r0 : r0 + _ROW_CHUNK].astype(np.float32)
        med = _median(chunk, axis=0)
        dev = np.abs(chunk - med[None])
        hidden = np.maximum(np.maximum(dev[..., 0], dev[..., 1]), dev[..., 2]) > cfg.hidden_diff
        median[r0 : r0 + _ROW_CHUNK] = med
        ambiguous[r0 : r0 + _ROW_CHUNK] = hidden.mean(axis=0) >= cfg.hidden_occupancy
    return median, ambiguous


def background_from_video_samples(frames: np.ndarray, cfg: BackgroundConfig, what: str = "video") -> Background:
    """Estimate the empty scene from frames sampled across a whole video.

    Args:
        frames: (N, H, W, 3) uint8 BGR samples (see :func:`gaitcap.video.sample_frames`).
        cfg: background parameters.
        what: name for messages (the video file or camera).

    Returns:
        The median background with per-pixel noise; ``report.usable`` is False (and a warning
        is logged) when too many pixels are ambiguous or there are too few samples.
    """
    frames = _check_stack(frames, what)
    n = frames.shape[0]
    median, ambiguous = _median_and_ambiguity(frames, cfg)
    noise = _robust_noise(frames, median, cfg.min_noise, max_factor=cfg.max_noise_factor)
    frac = float(ambiguous.mean())
    usable = frac <= cfg.max_ambiguous_fraction and n >= 5
    if n < 5:
        message = f"{what}: only {n} frame(s) to estimate the background from; no usable background"
    elif usable:
        message = f"{what}: background estimated from {n} frames ({100 * frac:.2f}% ambiguous pixels)"
    else:
        message = (
            f"{what}: no usable background could be estimated: something covers {100 * frac:.2f}% of the image "
            f"in at least {100 * cfg.hidden_occupancy:.0f}% of {n} sampled frames (limit "
            f"{100 * cfg.max_ambiguous_fraction:g}%); the subject probably never leaves the view. "
            "Silhouettes will be unreliable: record an empty-scene plate (background/<camera>.png)."
        )
    if usable:
        log.info("%s", message)
    else:
        log.warning("%s", message)
    report = BackgroundReport("video", n, frac, usable, message)
    return Background(median, noise, report)


def background_from_plate(
    plate: np.ndarray, cfg: BackgroundConfig, frames: np.ndarray | None = None, what: str = "plate"
) -> Background:
    """Use an image of the empty scene as the background.

    Args:
        plate: (H, W, 3) uint8 BGR image of the empty scene.
        cfg: background parameters.
        frames: optional (N, H, W, 3) uint8 samples of the video, for the per-pixel noise
            (each rescaled by its global brightness ratio to the plate first).
        what: name for messages.
    """
    plate = np.asarray(plate)
    if plate.ndim != 3 or plate.shape[2] != 3:
        raise InputError(f"{what}: background plate must be a colour image (H, W, 3), got {plate.shape}")
    image = plate.astype(np.float32)
    noise = None
    n = 0
    if frames is not None:
        frames = _check_stack(frames, what)
        if frames.shape[1:3] != plate.shape[:2]:
            raise InputError(
                f"{what}: background plate is {plate.shape[1]}x{plate.shape[0]} but the video is "
                f"{frames.shape[2]}x{frames.shape[1]}"
            )
        n = frames.shape[0]
        gains = global_gains(frames, image)
        noise = _robust_noise(frames, image, cfg.min_noise, gains, cfg.max_noise_factor)
        mismatch = plate_mismatch(frames, image, gains, cfg.hidden_diff)
        if mismatch > cfg.max_plate_mismatch:
            report = BackgroundReport(
                "plate", n, float("nan"), False,
                f"{what}: the plate does not match the video: {100 * mismatch:.0f}% of the image differs from the "
                f"median of {n} sampled frames (limit {100 * cfg.max_plate_mismatch:.0f}%); is it this camera's "
                "plate, of this room and light? Silhouettes will be unreliable.",
            )  # fmt: skip
            log.warning("%s", report.message)
            return Background(image, noise, report)
    report = BackgroundReport("plate", n, float("nan"), True, f"{what}: background from the plate")
    log.info("%s", report.message)
    return Background(image, noise, report)


def plate_mismatch(frames: np.ndarray, plate: np.ndarray, gains: np.ndarray, diff: float, stride: int = 8) -> float:
    """The fraction of the image (every ``stride``-th pixel) where the median of the samples (N, H, W, 3),
    each divided by its global gain (N, 3), differs from the plate (H, W, 3) by more than ``diff`` grey
    levels in some channel: a subject passing by moves the median little, another room or camera moves
    most of it (the suite's own plates: at most 0.14, with a subject walking on the spot; another
    session's or camera's plate: 0.30-0.58)."""
    samples = frames[:, ::stride, ::stride].astype(np.float32) / gains[:, None, None, :]
    median = _median(samples, axis=0)  # the module's exact median, one partition
    return float(np.mean(np.abs(median - plate[::stride, ::stride]).max(axis=-1) > diff))
