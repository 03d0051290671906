"""Per-frame silhouette extraction: foreground test, shadow suppression, clean-up, quality.

One :class:`SilhouetteExtractor` per camera. It never opens a video: the caller feeds frames
it has decoded (``gaitcap.video``), so the tracker can share its decoding. Typical use::

    ex = SilhouetteExtractor(config)
    ex.fit_background(samples=sample_frames(path, config.background.samples))   # or plate=...
    for index, frame in VideoReader(path):
        mask, quality = ex.process(frame)          # (H, W) uint8 0/1, FrameQuality
    # or: for mask, quality in ex.extract(frames): ...
    # several cameras together: evidence = ex.observe(frame); ...; ex.finish(evidence, shadow)

Per pixel, at the working scale (``config.scale``), with ``B`` the background and ``g`` the
frame's global per-channel brightness ratio to it (lighting drift and jumps):

1. difference: with ``D = I - g B`` split into its part along the background's colour ``B`` (a
   change of brightness: shading, shadow, light) and the rest ``D_perp`` (a change of colour),
   ``d = sqrt((|D|^2 + (w^2 - 1) |D_perp|^2) / 3)``, ``w = chroma_weight`` (``w = 1``: the RMS over
   channels): lighting changes the brightness of a surface, not its colour, so a colour change is
   stronger evidence of something in front of it (grey trousers over a teal carpet differ in
   colour, hardly in brightness). Confident foreground where ``d > t = max(k * sigma, min_diff)``
   (``sigma``: per-pixel noise of the background model), weak foreground where
   ``d > hysteresis * t``: weak pixels are kept only where they are 8-connected to confident ones
   (hysteresis: a grey trouser leg over a grey floor joins the body through its confident edges,
   background noise of the same strength stays alone). Video stores colour at half resolution,
   so a colour difference bleeds a pixel or two past the outline: the outermost ``chroma_edge``
   rings of the connected foreground are kept only where the plain RMS difference passes the weak
   level too. ``d / t`` is also the pixel's foreground strength, from which
   :meth:`SilhouetteExtractor.finish_soft` makes a soft silhouette (1 confident, ``soft_min``
   doubtful, 0 background) for the tracker;
2. shadow (Horprasert-style brightness/chromaticity test): a candidate (weak or confident) pixel is a cast shadow
   when its brightness ratio ``r = sum_c I_c / sum_c g_c B_c`` lies in ``[min_ratio, max_ratio]``,
   its normalised rgb chromaticity is within ``max_chroma`` of the background's, and, where the
   background is textured, the frame's local texture correlates with the background's
   (normalised cross-correlation >= ``min_ncc``: a shadow darkens the floor's texture, a dark
   trouser leg replaces it); with calibrated cameras run together (:mod:`gaitcap.silhouette.joint`)
   these candidates are then checked on the floor across the cameras (:mod:`gaitcap.silhouette.floor`),
   which also accepts deeper ones (ratio down to ``floor_min_ratio``: the hard shadow of one strong
   light) where another camera confirms them; to one camera alone they look like dark clothes;
3. clean-up: opening, closing; components smaller than ``min_component_fraction`` of the image
   dropped unless the main parts lie just over or under them (:func:`_attached_parts`: a foot
   cut off at the ankle, a head at the neck), and smaller than ``keep_relative`` of the largest
   dropped unless near the main parts (within ``keep_margin`` of their box's height: a head or a
   foot cut off at the neck or ankle stays; below the box within ``keep_below`` of its height: a
   foot whose leg was lost);
   holes up to ``max_hole_fraction`` of their component filled; then the outline matted
   (``matte_outline``, :func:`matte_outline`): its pixels are the person's where the person covers
   at least half of the pixel, judged from the background's colour and the person's colour just
   inside, not from the difference's strength (which also takes the halo of pixels the person
   covers a little: the blur of the optics, the video's half-resolution colour);
4. background adaptation: ``B <- (1 - a) B + a I / g`` where the (dilated) mask is off and the
   pixel does not differ even weakly (shadows included): a part the mask missed does not fade
   into the background.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import cv2
import numpy as np

from gaitcap.errors import InputError
from gaitcap.silhouette.background import (
    Background,
    BackgroundReport,
    background_from_plate,
    background_from_video_samples,
    global_gain,
)
from gaitcap.silhouette.config import SilhouetteConfig

log = logging.getLogger(__name__)

# quality flags (bit field)
EMPTY = 1
BORDER = 2
TOO_LARGE = 4
NO_BACKGROUND = 8
FLAG_NAMES = {EMPTY: "empty", BORDER: "border", TOO_LARGE: "too_large", NO_BACKGROUND: "no_background"}


def flag_names(flags: int) -> list[str]:
    """Names of the bits set in ``flags`` (e.g. ``["empty"]``); [] for a good frame."""
    return [name for bit, name in FLAG_NAMES.items() if flags & bit]


@dataclass(frozen=True)
class FrameQuality:
    """Per-frame quality record.

    Attributes:
        index: frame index (0-based, counted by the extractor).
        fraction: foreground pixels / image pixels, full resolution.
        shadow_fraction: pixels classified cast shadow / image pixels (working scale).
        components: number of kept connected components.
        bbox: (x, y, w, h) of the mask at full resolution, or None when empty.
        flags: bit field of EMPTY, BORDER, TOO_LARGE, NO_BACKGROUND.
    """

    index: int
    fraction: float
    shadow_fraction: float
    components: int
    bbox: tuple[int, int, int, int] | None
    flags: int

    @property
    def ok(self) -> bool:
        return self.flags == 0

    @property
    def flag_names(self) -> list[str]:
        return flag_names(self.flags)


def _scalar(values: np.ndarray) -> tuple[float, float, float, float]:
    """Per-channel factors as an OpenCV Scalar (for cv2.multiply on 3-channel images)."""
    return (float(values[0]), float(values[1]), float(values[2]), 0.0)


#: below the main parts, smaller components are kept down to the floor beneath the person's head and
#: this fraction of the person's height (head top to that floor row) further: a foot half a stride
#: ahead of the head lies lower in the image (up to 11 of 175 pixels on the suite's s11_c3dorg)
_FLOOR_SLACK = 0.08


def _body_components(stats: np.ndarray, min_area: float, relative: float, margin: float, below: float = 0.0,
                     floor_row: float | None = None) -> tuple[np.ndarray, np.ndarray, int | None]:  # fmt: skip
    """Indices of the components that belong to the person.

    The main parts are the components of at least ``relative`` of the largest one's area; a
    smaller component is kept when it touches their common bounding box grown by ``margin`` of
    its height on every side (a head or a foot cut off at the neck or ankle) and, downwards, by
    ``below`` of its height if that is more (a foot whose leg the foreground lost, below the
    trunk), but not past ``floor_row``, the image row of the floor beneath the person, when it is
    known (plus :data:`_FLOOR_SLACK` of the person's height there: a foot half a stride ahead
    of the head), where only the floor and the person's shadow are: the smaller components' pixels
    past that row are dropped too (a cast shadow joined to the foot). A component is dropped when
    it lies away from the body. Nothing below ``min_area`` pixels is kept.

    Args:
        stats: (n, 5) ``cv2.connectedComponentsWithStats`` rows (x, y, w, h, area), background excluded.
        min_area: least area in pixels.
        relative: fraction of the largest area that makes a main part.
        margin: growth of the main parts' box, as a fraction of its height.
        below: largest growth of the box downwards (image rows increasing), as a fraction of its height.
        floor_row: the row (same pixels as ``stats``) of the floor beneath the person, or None.

    Returns:
        (k,) int indices into ``stats`` of the kept components, (m,) those of the main parts, and
        the first row past the floor (None: no ``floor_row``).
    """
    x, y, w, h, area = (stats[:, i].astype(np.float64) for i in range(5))
    main = area >= relative * area.max()
    x0, y0 = x[main].min(), y[main].min()
    x1, y1 = (x + w)[main].max(), (y + h)[main].max()
    grow = margin * (y1 - y0)
    down, cut = below * (y1 - y0), None
    if floor_row is not None:  # down to the floor, give or take the feet's place along the stride
        floor = floor_row + _FLOOR_SLACK * (floor_row - y0)
        down, cut = min(down, floor - y1), max(int(np.floor(floor)) + 1, 0)
    down = max(grow, down)
    near = (x + w >= x0 - grow) & (x <= x1 + grow) & (y + h >= y0 - grow) & (y <= y1 + down)
    return np.flatnonzero((main | near) & (area >= min_area)), np.flatnonzero(main), cut


#: a component too small for ``cleanup.min_component_fraction`` is still kept when it is at least this
#: fraction of that area and the main parts lie within ``_ATTACHED_REACH`` of their height directly
#: over or under it, over at least ``_ATTACHED_COLUMNS`` of its columns: a foot cut off at the ankle
#: (the ankle taken for shadow, the foot found), a head at the neck; not a piece of shadow beside a
#: foot, nor a thin line of shadow that reaches under the leg at one end (docs/validation.md, "Feet
#: cut off at the ankle")
_ATTACHED_MIN = 0.125
_ATTACHED_REACH = 0.1
_ATTACHED_COLUMNS = 0.25


def _attached_parts(stats: np.ndarray, labels: np.ndarray, main: np.ndarray, min_area: float) -> np.ndarray:
    """Labels (k,) of the components (``stats`` (n, 5), row 0 the background; ``labels`` (h, w) their
    label image) below ``min_area`` but at least :data:`_ATTACHED_MIN` of it, over or under which the
    main parts (labels ``main``) have pixels within :data:`_ATTACHED_REACH` of the main parts'
    height, in at least :data:`_ATTACHED_COLUMNS` of the component's columns."""
    area = stats[:, 4]
    small = np.flatnonzero((area >= _ATTACHED_MIN * min_area) & (area < min_area))
    small = small[small > 0]
    if not small.size:
        return small
    y0 = stats[main, 1].min()
    y1 = (stats[main, 1] + stats[main, 3]).max()
    reach = max(int(round(_ATTACHED_REACH * (y1 - y0))), 1)
    lut = np.zeros(len(stats), bool)
    lut[main] = True
    out = []
    for j in small:
        x, y, w, h = (int(v) for v in stats[j, :4])
        above = lut[labels[max(y - reach, 0) : y, x : x + w]].any(axis=0)
        below = lut[labels[y + h : y + h + reach, x : x + w]].any(axis=0)
        if max(above.mean(), below.mean()) >= _ATTACHED_COLUMNS:
            out.append(j)
    return np.array(out, int)


def _channel_sum(image: np.ndarray) -> np.ndarray:
    """(h, w) float32 sum of the channels of an (h, w, 3) float32 image."""
    return cv2.transform(image, np.ones((1, 3), np.float32))


def _brightness_ratio(si: np.ndarray, sb: np.ndarray) -> np.ndarray:
    """(h, w) float32 brightness ratio frame / background from their channel sums ``si``, ``sb``
    (h, w) float32, each plus one (a black pixel divides by one, not zero): the shadow test's ratio,
    and the floor check's (:meth:`SilhouetteExtractor.log_brightness`)."""
    one = np.float32(1.0)
    return (si + one) / (sb + one)


def _label_type(mask: np.ndarray) -> int:
    """Label type for the connected components of ``mask`` (h, w) uint8: 16-bit labels when they fit
    (each component holds a pixel: fewer than 2^16 - 1 pixels set), else 32-bit. The labels and
    statistics are the same; OpenCV computes them with statistics three times faster in 16 bits."""
    return cv2.CV_16U if cv2.countNonZero(mask) < 2**16 - 1 else cv2.CV_32S


def _connected_to(weak: np.ndarray, seeds: np.ndarray, open_kernel: np.ndarray | None) -> np.ndarray:
    """(h, w) uint8 0/255: the 8-connected components of ``weak`` that hold a seed pixel.

    Args:
        weak: (h, w) bool, the pixels that may belong to the person (``seeds`` included).
        seeds: (h, w) bool, the confident ones.
        open_kernel: structuring element of an opening of both first (isolated noise seeds nothing,
            thin rings and bridges of weak pixels join nothing), or None.
    """
    seed = seeds.view(np.uint8)
    if open_kernel is not None:
        seed = cv2.morphologyEx(seed, cv2.MORPH_OPEN, open_kernel)
    if not weak.any():
        return seed * np.uint8(255)
    weak = weak.view(np.uint8)
    if open_kernel is not None:  # no thin rings or bridges of weak pixels
        weak = cv2.morphologyEx(weak, cv2.MORPH_OPEN, open_kernel)
    both = weak | seed
    n, labels = cv2.connectedComponents(both, connectivity=8, ltype=_label_type(both))
    hit = np.zeros(n, np.uint8)
    hit[labels[seed > 0]] = 255
    hit[0] = 0
    return np.take(hit, labels)


#: the person's colour next to an outline pixel is the mean over the mask's interior in this window (pixels)
_MATTE_WINDOW = 5
#: the outline re-decided by the matte: this many rings outside the mask, and inside it (the interior starts past them)
_MATTE_OUT, _MATTE_IN = 1, 1
#: one ring of pixels per erosion or dilation: the outline's rings (the matte, the trim of the colour-only ones)
_RING_K = np.ones((3, 3), np.uint8)


def matte_outline(image: np.ndarray, background: np.ndarray, mask: np.ndarray, keep_out: np.ndarray,
                  min_contrast: float) -> np.ndarray:  # fmt: skip
    """The mask with its outline re-decided by how much of each pixel the person covers.

    A pixel on the outline mixes the person's colour ``F`` and the background's ``B``:
    ``I = a F + (1 - a) B``. With ``F`` the mean colour of the mask's interior (more than
    ``_MATTE_IN`` pixels inside) within ``_MATTE_WINDOW``, ``a = (I - B).(F - B) / |F - B|^2``, and
    the pixel is the person's when ``a >= 1/2``: a threshold on the colour difference alone also
    takes the pixels the person covers a little (blur, the video's half-resolution colour), a
    one-pixel halo. The pixels re-decided lie up to ``_MATTE_OUT`` outside the mask and ``_MATTE_IN``
    inside it; where no interior pixel is near, or ``F`` and ``B`` differ by less than
    ``min_contrast`` (RMS over channels, grey levels), the mask's decision stands.

    Args:
        image: (h, w, 3) float32 frame.
        background: (h, w, 3) float32 background, scaled to the frame's lighting.
        mask: (h, w) uint8 0/255.
        keep_out: (h, w) bool pixels never added (cast shadows).
        min_contrast: grey levels.

    Returns:
        (h, w) uint8 0/255, a new array.
    """
    inner = cv2.erode(mask, _RING_K, iterations=_MATTE_IN)
    ring = (cv2.dilate(mask, _RING_K, iterations=_MATTE_OUT) > 0) & (inner == 0)
    box = (_MATTE_WINDOW, _MATTE_WINDOW)
    count = cv2.boxFilter((inner > 0).astype(np.float32), -1, box, normalize=False)
    colour_sum = cv2.boxFilter(cv2.bitwise_and(image, image, mask=inner), -1, box, normalize=False)
    at = ring & (count > 0)
    fb = colour_sum[at] / count[at, None] - background[at]  # (n, 3) F - B
    n2 = np.einsum("ij,ij->i", fb, fb)
    alpha = np.einsum("ij,ij->i", image[at] - background[at], fb) / np.maximum(n2, 1e-6)
    decide = n2 >= 3.0 * min_contrast**2
    person = (alpha >= 0.5)[decide]
    ys, xs = np.nonzero(at)
    ys, xs = ys[decide], xs[decide]
    person &= (mask[ys, xs] > 0) | ~keep_out[ys, xs]
    out = mask.copy()
    out[ys, xs] = np.where(person, 255, 0).astype(np.uint8)
    return out


def _disk(radius: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


@dataclass(frozen=True)
class FrameEvidence:
    """One frame's per-pixel tests at working scale (h, w), before the joint step over cameras.

    Attributes:
        image: (h, w, 3) float32 frame at working scale.
        gain: (3,) the frame's global per-channel brightness ratio to the background.
        background: (h, w, 3) float32 background scaled by ``gain`` (what the frame is compared with).
        candidate: (h, w) bool, differs from the background by more than the threshold.
        weak: (h, w) bool, differs by more than ``hysteresis`` times the threshold (includes ``candidate``).
        strength: (h, w) float32, squared difference / squared threshold (``(d / t)^2``).
        colour_only: (h, w) bool, weak only thanks to the colour weight (the plain RMS difference is
            below the weak level): such pixels are trimmed off the outline's outer rings.
        shadow: (h, w) bool, weak pixels that pass this camera's cast-shadow test.
        deep_shadow: (h, w) bool, weak pixels that would pass it at a deeper brightness ratio
            (``shadow.floor_min_ratio``): shadows only if the floor check confirms them.
        darkening: (h, w) bool, candidate or darker than the background (what another camera
            looks up to confirm that a floor point is shadowed).
        sums: the (h, w) float32 channel sums of the frame and of the background scaled by
            ``gain`` (their ratio is the pixel's brightness ratio).
    """

    image: np.ndarray
    gain: np.ndarray
    background: np.ndarray
    candidate: np.ndarray
    weak: np.ndarray
    strength: np.ndarray
    colour_only: np.ndarray
    shadow: np.ndarray
    deep_shadow: np.ndarray
    darkening: np.ndarray
    sums: tuple[np.ndarray, np.ndarray]


def working_size(full_size: tuple[int, int], scale: float) -> tuple[int, int]:
    """(w, h) of the working-scale image of a (w, h) video at ``scale`` (``SilhouetteConfig.scale``)."""
    return max(8, round(full_size[0] * scale)), max(8, round(full_size[1] * scale))


class SilhouetteExtractor:
    """Background subtraction with shadow suppression for one camera.

    Args:
        config: the parameters (``SilhouetteConfig()`` for the defaults).
        name: camera or file name used in messages.
    """

    def __init__(self, config: SilhouetteConfig | None = None, name: str = "camera") -> None:
        self.config = config or SilhouetteConfig()
        self.name = name
        self._bg: np.ndarray | None = None  # (h, w, 3) float32 working scale
        self._thr2: np.ndarray | None = None  # (h, w) float32 squared threshold
        self._weak2: np.ndarray | None = None  # (h, w) float32 squared weak level (hysteresis x threshold)
        self._half_weak2: np.ndarray | None = None  # (h, w) float32 squared half weak level
        self._full_size: tuple[int, int] | None = None  # (W, H)
        self._work_size: tuple[int, int] | None = None  # (w, h)
        self.report: BackgroundReport | None = None
        self._count = 0
        c = self.config.cleanup
        self._open_k = _disk(c.open_radius) if c.open_radius > 0 else None
        self._close_k = _disk(c.close_radius) if c.close_radius > 0 else None
        self._adapt_k = _disk(max(2, c.close_radius))

    # -- background ---------------------------------------------------------------------------
    def _work(self, image: np.ndarray) -> np.ndarray:
        if self._work_size is None or (image.shape[1], image.shape[0]) == self._work_size:
            return image
        return cv2.resize(image, self._work_size, interpolation=cv2.INTER_AREA)

    def fit_background(self, plate: np.ndarray | None = None, samples: np.ndarray | None = None) -> BackgroundReport:
        """Build the background model from a plate, from sampled video frames, or both.

        Args:
            plate: (H, W, 3) uint8 BGR empty-scene image, or None.
            samples: (N, H, W, 3) uint8 BGR frames spread over the whole video, or None. With a
                plate they only give the per-pixel noise; without one, the median background.

        Returns:
            The :class:`BackgroundReport` (also kept as ``self.report``); with ``usable`` False
            every frame is flagged NO_BACKGROUND.
        """
        if plate is None and samples is None:
            raise InputError(f"{self.name}: no background plate and no video frames to estimate one from")
        if plate is not None and (np.ndim(plate) != 3 or np.shape(plate)[2] != 3):
            raise InputError(f"{self.name}: expected a background plate of shape (H, W, 3) (BGR), got {np.shape(plate)}")
        if samples is not None and (np.ndim(samples) != 4 or np.shape(samples)[3] != 3 or not len(samples)):
            raise InputError(f"{self.name}: expected sampled frames of shape (N, H, W, 3) (BGR), got {np.shape(samples)}")
        ref = plate if plate is not None else samples[0]  # type: ignore[index]
        h, w = ref.shape[:2]
        if plate is not None and samples is not None and samples.shape[1:3] != (h, w):
            raise InputError(
                f"{self.name}: background plate is {w}x{h} but the video is {samples.shape[2]}x{samples.shape[1]}"
            )
        s = self.config.scale
        self._full_size = (w, h)
        self._work_size = working_size((w, h), s)
        work_samples = None if samples is None else np.stack([self._work(f) for f in samples])
        cfg = self.config.background
        if plate is not None:
            bg = background_from_plate(self._work(plate), cfg, work_samples, what=self.name)
        else:
            bg = background_from_video_samples(work_samples, cfg, what=self.name)  # type: ignore[arg-type]
        self._set_background(bg)
        return bg.report

    def _set_background(self, bg: Background) -> None:
        self._bg = bg.image.copy()
        self.report = bg.report
        self._set_threshold2(None if bg.noise is None else self._threshold2(bg.noise))
        self._count = 0

    def _threshold2(self, noise: np.ndarray) -> np.ndarray:
        f = self.config.foreground
        thr = np.maximum(f.threshold_sigma * noise, np.float32(f.min_diff)).astype(np.float32)
        return thr * thr

    def _set_threshold2(self, thr2: np.ndarray | None) -> None:
        """Keep the (h, w) float32 squared threshold and the squared levels derived from it."""
        self._thr2 = thr2
        if thr2 is None:
            self._weak2 = self._half_weak2 = None
            return
        h = self.config.foreground.hysteresis
        half = 0.5 * h
        self._weak2 = np.float32(h * h) * thr2
        self._half_weak2 = np.float32(half * half) * thr2

    @property
    def background(self) -> np.ndarray:
        """The current background at working scale, (h, w, 3) uint8 BGR."""
        if self._bg is None:
            raise InputError(f"{self.name}: fit_background() must be called first")
        return np.clip(self._bg, 0, 255).astype(np.uint8)

    # -- per frame ----------------------------------------------------------------------------
    def process(self, frame: np.ndarray) -> tuple[np.ndarray, FrameQuality]:
        """Silhouette of one frame.

        Args:
            frame: (H, W, 3) uint8 BGR, the size of the background.

        Returns:
            ``(mask, quality)``: mask (H, W) uint8 with 1 = person, and its :class:`FrameQuality`.
        """
        evidence = self.observe(frame)
        return self.finish(evidence, evidence.shadow)

    def observe(self, frame: np.ndarray) -> FrameEvidence:
        """Steps 1-2 for one frame: the per-pixel tests, before any joint step over cameras.

        Args:
            frame: (H, W, 3) uint8 BGR, the size of the background.

        Returns:
            The frame's :class:`FrameEvidence` at working scale; pass it (and its shadow map,
            possibly re-labelled) to :meth:`finish`.
        """
        if self._bg is None or self._full_size is None:
            raise InputError(f"{self.name}: fit_background() must be called before extracting silhouettes")
        if frame.ndim != 3 or frame.shape[2] != 3:
            raise InputError(f"{self.name}: frame {self._count} has shape {frame.shape}, expected (H, W, 3) (BGR)")
        if (frame.shape[1], frame.shape[0]) != self._full_size:
            raise InputError(
                f"{self.name}: frame {self._count} is {frame.shape[1]}x{frame.shape[0]}, "
                f"the background is {self._full_size[0]}x{self._full_size[1]}"
            )
        img = self._work(frame).astype(np.float32)
        gain = global_gain(img, self._bg) if self.config.background.gain_compensation else np.ones(3, np.float32)
        bg = cv2.multiply(self._bg, _scalar(gain))
        if self._thr2 is None:  # plate without samples: one global noise level from this frame
            g = gain if self.config.background.gain_compensation else global_gain(img, self._bg)
            self._set_threshold2(self._threshold2(self._global_noise(img, self._bg * g.reshape(1, 1, 3))))
        d2, plain2 = self._diff2(img, bg)
        strength = cv2.divide(d2, self._thr2)
        candidate = strength > 1.0
        h = self.config.foreground.hysteresis
        weak = strength > np.float32(h * h) if h < 1 else candidate
        colour_only = np.zeros_like(weak) if plain2 is d2 else weak & (plain2 <= self._weak2)
        si, sb = _channel_sum(img), _channel_sum(bg)
        if self.config.foreground.texture_ncc > -1:
            weak = weak | self._texture_changed(si, sb, candidate)
        if self.config.shadow.enabled:
            shadow, deep = self._shadow(img, bg, si, sb, weak)
        else:
            shadow, deep = np.zeros_like(candidate), np.zeros_like(candidate)
        darkening = candidate | self._darker(si, sb, plain2)
        return FrameEvidence(img, gain, bg, candidate, weak, strength, colour_only, shadow, deep, darkening, (si, sb))

    def finish(self, evidence: FrameEvidence, shadow: np.ndarray,
               floor_row: float | None = None) -> tuple[np.ndarray, FrameQuality]:  # fmt: skip
        """Steps 3-4: clean-up of ``candidate & ~shadow`` and background adaptation.

        Args:
            evidence: this camera's :meth:`observe` of the frame.
            shadow: (h, w) bool, the pixels finally taken as cast shadow.
            floor_row: the image row (full resolution) of the floor beneath the person, when the
                cameras' calibration tells it (:class:`~gaitcap.silhouette.joint.JointExtractor`):
                below the main parts, smaller components are kept down to it (``cleanup.keep_below``).

        Returns:
            ``(mask, quality)`` as :meth:`process`.
        """
        mask, _, quality = self._finish(evidence, shadow, soft=False, floor_row=floor_row)
        return mask, quality

    def finish_soft(self, evidence: FrameEvidence, shadow: np.ndarray,
                    floor_row: float | None = None) -> tuple[np.ndarray, np.ndarray, FrameQuality]:  # fmt: skip
        """As :meth:`finish`, with the soft silhouette too.

        Returns:
            ``(mask, soft, quality)``: ``soft`` (H, W) float32 in [0, 1] is 0 outside ``mask`` and
            ``m + (1 - m) c`` inside (``m``: ``foreground.soft_min``), with ``c`` the pixel's
            confidence: 1 at or above the threshold, 0 at or below ``hysteresis`` times it (and for
            pixels the clean-up filled in), linear in between. The likelihood counts 0.5 as neither
            silhouette nor background, 1 as silhouette.
        """
        return self._finish(evidence, shadow, soft=True, floor_row=floor_row)

    def _finish(self, evidence: FrameEvidence, shadow: np.ndarray, soft: bool,
                floor_row: float | None = None) -> tuple[np.ndarray, np.ndarray | None, FrameQuality]:  # fmt: skip
        raw = _connected_to(evidence.weak & ~shadow, evidence.candidate & ~shadow, self._open_k)
        self._trim_outline(raw, evidence.colour_only)
        if floor_row is not None and self._full_size is not None:  # full resolution -> working scale
            floor_row = (floor_row + 0.5) * raw.shape[0] / self._full_size[1] - 0.5
        mask_small, n_comp = self._clean(raw, floor_row)
        if self.config.cleanup.matte_outline:
            mask_small = self._matte(evidence, mask_small, shadow)
        self._adapt(evidence.image, evidence.gain, mask_small, evidence.weak | shadow)
        mask = self._to_full(mask_small)
        quality = self._quality(mask, int(np.count_nonzero(shadow)) / shadow.size, n_comp)  # = shadow.mean(), 10x cheaper
        self._count += 1
        if not soft:
            return mask, None, quality
        return mask, self._soft(evidence.strength, mask_small, mask, shadow), quality

    def _matte(self, evidence: FrameEvidence, mask: np.ndarray, shadow: np.ndarray) -> np.ndarray:
        """:func:`matte_outline` of ``mask`` (h, w) uint8 0/255 in its bounding box (plus the window)."""
        x, y, w, h = cv2.boundingRect(mask)
        if not w or not h:
            return mask
        pad = _MATTE_WINDOW + _MATTE_OUT
        box = np.s_[max(y - pad, 0) : y + h + pad, max(x - pad, 0) : x + w + pad]
        out = mask.copy()
        out[box] = matte_outline(evidence.image[box], evidence.background[box], mask[box], shadow[box], self.config.foreground.min_diff)
        return out

    def _soft(self, strength: np.ndarray, mask_small: np.ndarray, mask: np.ndarray, shadow: np.ndarray) -> np.ndarray:
        """(H, W) float32 soft silhouette of :meth:`finish_soft` from the working-scale strength
        (h, w) float32, the working-scale mask (h, w) uint8 0/255 and the full-resolution one (H, W)
        uint8 0/1, with the doubt outside the mask (:meth:`_with_doubt`; ``shadow`` (h, w) bool). At full
        resolution it is computed in the mask's bounding box only (0 elsewhere)."""
        if (mask_small.shape[1], mask_small.shape[0]) == self._full_size:
            soft = np.zeros(mask.shape, np.float32)
            x, y, w, h = cv2.boundingRect(mask_small)
            if w and h:
                box = np.s_[y : y + h, x : x + w]
                soft[box] = self._soft_at_scale(strength[box], mask_small[box], mask[box])
        else:
            soft = self._soft_at_scale(strength, mask_small, mask)
        return self._with_doubt(soft, strength, mask_small, mask, shadow) if self.config.foreground.doubts else soft

    def _with_doubt(self, soft: np.ndarray, strength: np.ndarray, mask_small: np.ndarray, mask: np.ndarray,
                    shadow: np.ndarray) -> np.ndarray:  # fmt: skip
        """``soft`` (H, W) with ``foreground.doubt_min``'s doubtful pixels outside ``mask`` (H, W): in the
        working-scale mask's bounding box, grown by an eighth of its height, pixels no shadow whose
        difference d / t lies between doubt_min and the weak level get 0.5 (d / t - doubt_min) /
        (hysteresis - doubt_min), at most 0.5: a model pixel there is penalised less, never rewarded."""
        lo, hi = self.config.foreground.doubt_min, self.config.foreground.hysteresis
        x, y, w, h = cv2.boundingRect(mask_small)
        if not w or not h:
            return soft
        pad = max(h // 8, 1)
        box = np.s_[max(y - pad, 0) : y + h + pad, max(x - pad, 0) : x + w + pad]
        doubt = np.zeros(strength.shape, np.float32)
        d = (cv2.sqrt(strength[box]) - np.float32(lo)) * np.float32(0.5 / (hi - lo))
        np.clip(d, 0.0, 0.5, out=d)
        d[(mask_small[box] > 0) | shadow[box]] = 0.0
        doubt[box] = d
        if doubt.shape != mask.shape:
            doubt = cv2.resize(doubt, (mask.shape[1], mask.shape[0]), interpolation=cv2.INTER_LINEAR)
        return np.where(mask > 0, soft, np.minimum(doubt, np.float32(0.5)))

    def _soft_at_scale(self, strength: np.ndarray, mask_small: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """:meth:`_soft` over whole arrays: (h, w) ``strength`` and ``mask_small`` -> (H, W), resized to
        the size of ``mask`` (H, W) when it differs."""
        h = self.config.foreground.hysteresis
        if h < 1:
            conf = (cv2.sqrt(strength) - np.float32(h)) * np.float32(1.0 / (1.0 - h))
        else:
            conf = (strength > 1.0).astype(np.float32)
        np.clip(conf, 0.0, 1.0, out=conf)
        m = np.float32(self.config.foreground.soft_min)
        soft = (m + (np.float32(1.0) - m) * conf) * (mask_small > 0)
        if soft.shape != mask.shape:
            soft = cv2.resize(soft, (mask.shape[1], mask.shape[0]), interpolation=cv2.INTER_LINEAR)
        return soft * mask

    @staticmethod
    def log_brightness(evidence: FrameEvidence) -> np.ndarray:
        """(h, w) float32: log of the frame's brightness over the background's (channel sums, the
        background scaled by the frame's gain), at working scale: the same at a floor point for
        every camera when a shadow darkens it (:mod:`gaitcap.silhouette.floor`)."""
        return cv2.log(_brightness_ratio(*evidence.sums))

    @property
    def work_size(self) -> tuple[int, int]:
        """(w, h) of the working scale (known once the background is fitted)."""
        if self._work_size is None:
            raise InputError(f"{self.name}: fit_background() must be called first")
        return self._work_size

    @property
    def full_size(self) -> tuple[int, int]:
        """(W, H) of the video (known once the background is fitted)."""
        if self._full_size is None:
            raise InputError(f"{self.name}: fit_background() must be called first")
        return self._full_size

    def extract(self, frames: Iterable[np.ndarray]) -> Iterator[tuple[np.ndarray, FrameQuality]]:
        """Lazily apply :meth:`process` to each frame: yields ``(mask, quality)``."""
        for frame in frames:
            yield self.process(frame)

    def _global_noise(self, img: np.ndarray, bg: np.ndarray) -> np.ndarray:
        dev = np.abs(img[::2, ::2] - bg[::2, ::2]).mean(axis=2)
        sigma = max(1.4826 * float(np.median(dev)), self.config.background.min_noise)
        log.debug("%s: global noise sigma %.2f grey levels (from the first frame)", self.name, sigma)
        return np.full(img.shape[:2], sigma, np.float32)

    def _diff2(self, img: np.ndarray, bg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Squared differences frame - background, each (h, w) float32: the colour-weighted
        ``d^2 = (|D|^2 + (w^2 - 1) |D_perp|^2) / 3`` of step 1 and the plain mean over channels
        ``|D|^2 / 3`` (the same array when ``chroma_weight`` is 1)."""
        diff = cv2.subtract(img, bg)
        plain2 = cv2.transform(cv2.multiply(diff, diff), np.full((1, 3), 1.0 / 3.0, np.float32))
        w2 = np.float32(self.config.foreground.chroma_weight ** 2)
        if w2 == 1:
            return plain2, plain2
        # |D_perp|^2 = |D|^2 - (D . B)^2 / |B|^2; the background is never black (+1)
        ones = np.ones((1, 3), np.float32)
        dot = cv2.transform(cv2.multiply(diff, bg), ones)
        norm2 = cv2.transform(cv2.multiply(bg, bg), ones) + np.float32(1.0)
        along2 = cv2.divide(cv2.multiply(dot, dot), norm2, scale=1.0 / 3.0)
        return cv2.addWeighted(plain2, float(w2), along2, float(1 - w2), 0.0), plain2

    def _trim_outline(self, raw: np.ndarray, colour_only: np.ndarray) -> None:
        """Drop, in place, the ``colour_only`` (h, w) bool pixels of the outermost
        ``foreground.chroma_edge`` rings of ``raw`` (h, w) uint8 0/255: the half-resolution colour
        of video bleeds past the outline, the brightness does not."""
        for _ in range(self.config.foreground.chroma_edge):
            ring = cv2.subtract(raw, cv2.erode(raw, _RING_K))
            raw[(ring > 0) & colour_only] = 0

    def _darker(self, si: np.ndarray, sb: np.ndarray, d2: np.ndarray) -> np.ndarray:
        """(h, w) bool: darker than the background (brightness ratio below ``shadow.max_ratio``) by
        at least half the weakest foreground (``hysteresis`` times the threshold), whether or not the
        difference passes it. ``si``, ``sb``: (h, w) channel sums of the frame and the background."""
        darker = si < np.float32(self.config.shadow.max_ratio) * sb
        return darker & (d2 > self._half_weak2)

    def _shadow(self, img: np.ndarray, bg: np.ndarray, si_full: np.ndarray, sb_full: np.ndarray,
                candidate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """Candidate pixels explained as cast shadow on the background: (h, w) bool each, those in
        ``[min_ratio, max_ratio]`` and the deep ones in ``[floor_min_ratio, min_ratio)`` (a shadow
        only if the floor check confirms it). ``img``, ``bg``: (h, w, 3) frame and background;
        ``si_full``, ``sb_full``: (h, w) their channel sums.

        Computed inside the bounding box of the candidates (plus the texture window) only.
        """
        s = self.config.shadow
        shadow = np.zeros_like(candidate)
        deep = np.zeros_like(candidate)
        x, y, w, h = cv2.boundingRect(candidate.view(np.uint8))
        if w == 0 or h == 0:
            return shadow, deep
        m = s.texture_window
        y0, y1 = max(0, y - m), min(candidate.shape[0], y + h + m)
        x0, x1 = max(0, x - m), min(candidate.shape[1], x + w + m)
        si = si_full[y0:y1, x0:x1] + np.float32(1.0)  # sum of channels
        sb = sb_full[y0:y1, x0:x1] + np.float32(1.0)
        ratio = _brightness_ratio(si_full[y0:y1, x0:x1], sb_full[y0:y1, x0:x1])
        lowest = s.floor_min_ratio if s.floor_check else s.min_ratio
        darker = candidate[y0:y1, x0:x1] & (ratio >= lowest) & (ratio <= s.max_ratio)
        # chromaticity, then texture, only where they matter (candidate pixels in the brightness range)
        at = np.flatnonzero(darker)  # flat indices into the box
        rows, cols = np.divmod(at, x1 - x0)
        pixel = (rows + y0) * candidate.shape[1] + cols + x0  # the same pixels, flat indices into the image
        si_at, sb_at = si.ravel()[at, None], sb.ravel()[at, None]
        change = np.abs(img.reshape(-1, 3)[pixel] / si_at - bg.reshape(-1, 3)[pixel] / sb_at)  # (n, 3)
        chroma = np.maximum(np.maximum(change[:, 0], change[:, 1]), change[:, 2])  # (numpy's max(axis=1) is slow on 3 columns)
        at = at[chroma <= s.max_chroma]
        found = np.zeros_like(darker)
        found.ravel()[at[self._same_texture(si, sb, at)]] = True
        is_deep = ratio < s.min_ratio
        shadow[y0:y1, x0:x1] = found & ~is_deep
        deep[y0:y1, x0:x1] = found & is_deep
        return shadow, deep

    def _texture_changed(self, si: np.ndarray, sb: np.ndarray, candidate: np.ndarray) -> np.ndarray:
        """(h, w) bool: the background is textured there and the frame no longer shows its texture
        (local correlation below ``foreground.texture_ncc``): something stands in front of it. Eroded
        by half the window: a window that straddles the person's outline changes too. Tested only in
        the box of the candidates grown by half its height (the rest cannot join the body), and there
        only where the background is textured. ``si``, ``sb``: (h, w) channel sums of the frame and
        the background."""
        changed = np.zeros_like(candidate)
        x, y, w, h = cv2.boundingRect(candidate.view(np.uint8))
        if w == 0 or h == 0:
            return changed
        g = h // 2
        box = np.s_[max(0, y - g) : y + h + g, max(0, x - g) : x + w + g]
        si, sb = si[box], sb[box]
        k = self.config.shadow.texture_window
        mb, vb = self._local_stats(sb)
        at = np.flatnonzero(~self._flat(vb))
        ncc = self._texture_ncc(si, sb, at, mb.ravel()[at], vb.ravel()[at], min_var=1.0)
        inside = np.zeros(vb.shape, np.uint8)
        inside.ravel()[at[ncc < np.float32(self.config.foreground.texture_ncc)]] = 1
        changed[box] = cv2.erode(inside, np.ones((k, k), np.uint8)).view(bool)
        return changed

    def _local_stats(self, sb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The background's local mean and variance (h, w) float32 each, over the texture window,
        of its channel sums ``sb`` (h, w) float32."""
        k = (self.config.shadow.texture_window,) * 2
        mb = cv2.blur(sb, k)
        return mb, cv2.blur(sb * sb, k) - mb * mb

    def _flat(self, vb: np.ndarray) -> np.ndarray:
        """Where the background is flat (local std below ``texture_min_std``: no texture to test), from
        the local variance ``vb`` of its channel sums (any shape) -> bool of that shape."""
        return vb < (3.0 * self.config.shadow.texture_min_std) ** 2  # channel sums: 3x the grey-level std

    def _texture_ncc(self, si: np.ndarray, sb: np.ndarray, at: np.ndarray, mb: np.ndarray, vb: np.ndarray,
                     min_var: float = 0.0) -> np.ndarray:  # fmt: skip
        """(n,) local normalised cross-correlation of the channel sums ``si``, ``sb`` (h, w) float32
        over a box window, at the pixels of flat indices ``at`` (n,), given there the background's
        local mean ``mb`` (n,) and variance ``vb`` (n,). ``min_var`` floors the frame's local variance
        (a flat patch then correlates with nothing, instead of rounding errors over zero)."""
        k = (self.config.shadow.texture_window,) * 2
        mi = cv2.blur(si, k).ravel()[at]
        vi = cv2.blur(si * si, k).ravel()[at] - mi * mi
        if min_var > 0:
            vi = np.maximum(vi, np.float32(min_var))
        cov = cv2.blur(si * sb, k).ravel()[at] - mi * mb
        return cov / np.sqrt(np.maximum(vi * vb, 1e-6))

    def _same_texture(self, si: np.ndarray, sb: np.ndarray, at: np.ndarray) -> np.ndarray:
        """(n,) bool: the frame keeps the background's local texture (or there is none) at the
        pixels of flat indices ``at`` (n,) into the (h, w) channel sums ``si``, ``sb``.

        Normalised cross-correlation of channel sums over a box window; where the background
        is flat (local std below ``texture_min_std``) the test cannot tell and passes.
        """
        mb, vb = (v.ravel()[at] for v in self._local_stats(sb))
        flat = self._flat(vb)
        same = flat.copy()
        textured = ~flat
        same[textured] = self._texture_ncc(si, sb, at[textured], mb[textured], vb[textured]) >= self.config.shadow.min_ncc
        return same

    def _clean(self, raw: np.ndarray, floor_row: float | None = None) -> tuple[np.ndarray, int]:
        """Morphology, component selection and hole filling; (h, w) uint8 0/255 -> same, count.
        ``floor_row``: the floor's row beneath the person at working scale (:func:`_body_components`)."""
        c = self.config.cleanup
        mask = raw
        if self._open_k is not None:
            mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, self._open_k)
        if self._close_k is not None:
            mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, self._close_k)
        n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8, ltype=_label_type(mask))
        if n <= 1:
            return np.zeros_like(mask), 0
        keep, main, cut = _body_components(stats[1:], c.min_component_fraction * mask.size, c.keep_relative,
                                           c.keep_margin, c.keep_below, floor_row)  # fmt: skip
        keep += 1
        lut = np.zeros(n, np.uint8)
        lut[keep] = 255
        mask = np.take(lut, labels)
        small = _attached_parts(stats, labels, main + 1, c.min_component_fraction * mask.size)
        if small.size:
            lut[small] = 255
            mask = np.take(lut, labels)
            keep = np.concatenate([keep, small])
        if cut is not None and cut < mask.shape[0]:  # past the floor: the main parts only
            lut[:] = 0
            lut[main + 1] = 255
            mask[cut:] = np.take(lut, labels[cut:])
        if c.max_hole_fraction > 0:
            mask = self._fill_holes(mask, c.max_hole_fraction)
        return mask, int(keep.size)

    @staticmethod
    def _fill_holes(mask: np.ndarray, max_fraction: float) -> np.ndarray:
        contours, hierarchy = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
        if hierarchy is None:
            return mask
        hierarchy = hierarchy[0]
        out = mask.copy()
        for i, (_, _, _, parent) in enumerate(hierarchy):
            if parent < 0:
                continue  # an outer contour
            if cv2.contourArea(contours[i]) <= max_fraction * cv2.contourArea(contours[parent]):
                cv2.drawContours(out, contours, i, 255, thickness=cv2.FILLED)
        return out

    def _adapt(self, img: np.ndarray, gain: np.ndarray, mask: np.ndarray, changed: np.ndarray) -> None:
        """Blend the frame into the background where nobody is: off the dilated ``mask`` (h, w) and off
        ``changed`` (h, w) bool, every pixel that differs even weakly (a missed trouser leg, a shadow),
        so that what the mask missed does not fade into the background."""
        rate = self.config.background.adapt_rate
        if rate <= 0:
            return
        busy = cv2.dilate(mask, self._adapt_k) > 0
        still = (~busy & ~changed).astype(np.uint8)
        target = cv2.multiply(img, _scalar(1.0 / np.maximum(gain, 1e-3)))
        cv2.accumulateWeighted(target, self._bg, rate, mask=still)

    def _to_full(self, mask_small: np.ndarray) -> np.ndarray:
        full = self._full_size
        if full is not None and (mask_small.shape[1], mask_small.shape[0]) != full:
            mask_small = cv2.resize(mask_small, full, interpolation=cv2.INTER_LINEAR)
        return (mask_small > 127).astype(np.uint8)

    def _quality(self, mask: np.ndarray, shadow_fraction: float, n_comp: int) -> FrameQuality:
        q = self.config.quality
        fraction = float(cv2.countNonZero(mask)) / mask.size
        flags = 0
        bbox = None
        if fraction < q.empty_fraction:
            flags |= EMPTY
        if fraction > q.large_fraction:
            flags |= TOO_LARGE
        if fraction > 0:
            x, y, w, h = cv2.boundingRect(mask)
            bbox = (int(x), int(y), int(w), int(h))
            m = q.border_margin
            H, W = mask.shape
            if x < m or y < m or x + w > W - m or y + h > H - m:
                flags |= BORDER
        if self.report is not None and not self.report.usable:
            flags |= NO_BACKGROUND
        return FrameQuality(self._count, fraction, shadow_fraction, n_comp, bbox, flags)
