"""The silhouettes of one frame of every camera together: per-camera tests, the floor-shadow
check across cameras (:mod:`gaitcap.silhouette.floor`), then each camera's clean-up, which keeps
small components below the body down to the floor beneath the person (a foot whose leg the
foreground lost), that floor's row in each camera found from the previous frame's masks
(:func:`~gaitcap.silhouette.floor.floor_rows`: their head tops triangulated); with that head top,
each mask's main parts that lie on the floor away from the person's vertical axis are dropped
(:func:`off_axis_parts`)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import replace
from typing import Any

import cv2
import numpy as np

from gaitcap.camera import Camera
from gaitcap.errors import InputError
from gaitcap.silhouette.config import SilhouetteConfig
from gaitcap.silhouette.extract import FrameEvidence, FrameQuality, SilhouetteExtractor, working_size
from gaitcap.silhouette.floor import FloorShadowCheck, person_head_top, rows_below

MapFn = Callable[..., Iterable[Any]]


def floor_check(cameras: Sequence[Camera], config: SilhouetteConfig) -> FloorShadowCheck | None:
    """The floor geometry :class:`JointExtractor` re-labels shadows with, for calibrated ``cameras``
    whose videos have the calibration's size; None when ``config`` has no floor check. Built from
    the calibration alone, so it can be built while the backgrounds are fitted."""
    s = config.shadow
    if not (s.enabled and s.floor_check):
        return None
    sizes = [working_size(tuple(cam.size), config.scale) for cam in cameras]
    return FloorShadowCheck(cameras, sizes, s.floor_tolerance, s.floor_reach, s.floor_footprint, s.floor_ratio_window)


class JointExtractor:
    """Fitted extractors of synchronised cameras, run frame by frame.

    Args:
        extractors: one fitted :class:`SilhouetteExtractor` per camera.
        cameras: their calibrations in the same order, or None (no floor check: each camera alone).
        map_fn: how the per-camera steps are mapped over the cameras (``map``, or a thread
            pool's ``map`` to run them side by side).
        floor: :func:`floor_check` of ``cameras`` with the extractors' configuration, built ahead;
            None: built here (when there are cameras and the configuration checks the floor).
    """

    def __init__(self, extractors: Sequence[SilhouetteExtractor], cameras: Sequence[Camera] | None = None,
                 map_fn: MapFn = map, floor: FloorShadowCheck | None = None) -> None:  # fmt: skip
        self.extractors = list(extractors)
        self._map = map_fn
        self.floor: FloorShadowCheck | None = None
        self._cameras = list(cameras) if cameras is not None else None
        #: per camera, the floor's row beneath the person in the previous frame (None: not known)
        self._floor_rows: list[float | None] = [None] * len(self.extractors)
        #: the person's head top (3,) in the previous frame (None: not known); the floor beneath it is
        #: where the person stands
        self._top: np.ndarray | None = None
        if cameras is None or not self.extractors:
            return
        if len(cameras) != len(self.extractors):
            raise InputError(f"{len(self.extractors)} cameras to extract but {len(cameras)} calibrations")
        for ex, cam in zip(self.extractors, cameras):
            if ex.full_size != tuple(cam.size):
                raise InputError(
                    f"{ex.name}: the video is {ex.full_size[0]}x{ex.full_size[1]} but the calibration says "
                    f"{cam.size[0]}x{cam.size[1]}"
                )
        self.floor = floor if floor is not None else floor_check(cameras, self.extractors[0].config)
        sizes = [ex.work_size[::-1] for ex in self.extractors]  # (h, w) each
        if self.floor is not None and [m.shape for m in self.floor.on_floor] != sizes:
            raise ValueError("the floor check was built for other image sizes than the extractors'")

    def process(self, images: Sequence[np.ndarray]) -> list[tuple[np.ndarray, FrameQuality]]:
        """Masks of one frame: ``images`` (H_c, W_c, 3) uint8 BGR per camera -> (mask, quality) per camera."""
        return self.finish(*self.observe(images))

    def process_soft(self, images: Sequence[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray, FrameQuality]]:
        """As :meth:`process`, with each camera's soft silhouette: (mask, soft, quality) per camera
        (:meth:`SilhouetteExtractor.finish_soft`)."""
        return self.finish(*self.observe(images), soft=True)

    def finish(self, evidence: list[FrameEvidence], shadows: list[np.ndarray], soft: bool = False) -> list[tuple]:
        """The second half of :meth:`process` (``soft``: of :meth:`process_soft`): each camera's
        clean-up of its :meth:`observe` evidence and shadows, then the floor rows for the next frame."""
        step = SilhouetteExtractor.finish_soft if soft else SilhouetteExtractor.finish
        out = list(self._map(step, self.extractors, evidence, shadows, self._floor_rows))
        cleanup = self.extractors[0].config.cleanup if self.extractors else None
        if self._top is not None and cleanup is not None and cleanup.keep_radius_m > 0 and self._cameras is not None:
            out = [r if r[-1].components < 2 else  # one component kept: nothing to drop
                   _without(r, off_axis_parts(r[0], cam, self._top, cleanup.keep_radius_m, cleanup.keep_relative))
                   for r, cam in zip(out, self._cameras)]  # fmt: skip (a head top: two cameras or more)
        self._follow([r[0] for r in out])
        return out

    def _follow(self, masks: list[np.ndarray]) -> None:
        """The floor's row beneath the person in each camera, from this frame's masks, for the next
        frame (the person moves a few centimetres from frame to frame)."""
        if self._cameras is not None and len(self._cameras) > 1:
            self._top = person_head_top(self._cameras, masks)
            self._floor_rows = rows_below(self._cameras, self._top)

    def observe(self, images: Sequence[np.ndarray]) -> tuple[list[FrameEvidence], list[np.ndarray]]:
        """The first half of :meth:`process`: every camera's per-pixel evidence
        (:meth:`SilhouetteExtractor.observe`) and its shadow map after the floor check; give both to
        :meth:`finish` (in frame order: the floor rows follow the person from frame to frame)."""
        evidence = list(self._map(lambda ex, im: ex.observe(im), self.extractors, images))
        shadows = [e.shadow for e in evidence]
        if self.floor is not None:
            deep = [e.deep_shadow for e in evidence]
            cfg = self.extractors[0].config.shadow
            ratio = body = None
            if cfg.floor_same_ratio:
                ratio = list(self._map(lambda ex, e: ex.log_brightness(e), self.extractors, evidence))
                body = [e.candidate & ~(s | d) for e, s, d in zip(evidence, shadows, deep)]
            centre = self._top[:2] if cfg.floor_footprint and self._top is not None else None
            shadows = self.floor.relabel(shadows, [e.darkening for e in evidence], deep, ratio, body,
                                         cfg.floor_ratio_tolerance, centre)  # fmt: skip
        return evidence, shadows


#: a main part with less than this fraction of its pixels within reach of the person's axis is not the person
_ON_AXIS = 0.1
#: a part whose top is lower in the image than a point this high (metres) above the floor beneath the
#: person lies on the floor (a shadow's end, a reflection); someone else in view stands higher
_FLOOR_LEVEL_M = 0.3
#: points on each circle of the person's cylinder drawn into a camera
_CIRCLE_POINTS = 24


def person_region(camera: Camera, top: np.ndarray, radius: float) -> np.ndarray:
    """(H, W) bool: the vertical cylinder of ``radius`` metres from the floor below the head top
    ``top`` (3,) up to it, drawn into ``camera`` (the convex hull of its two circles; points behind
    the camera left out)."""
    a = np.linspace(0.0, 2.0 * np.pi, _CIRCLE_POINTS, endpoint=False)
    ring = np.stack([top[0] + radius * np.cos(a), top[1] + radius * np.sin(a)], axis=1)
    pts = np.vstack([np.c_[ring, np.zeros(len(a))], np.c_[ring, np.full(len(a), top[2])]])
    pts = pts[camera.to_camera(pts)[:, 2] > 0.05]
    region = np.zeros((camera.height, camera.width), np.uint8)
    if len(pts) >= 3:
        hull = cv2.convexHull(np.clip(camera.project(pts), -1e5, 1e5).astype(np.float32)).astype(np.int32)
        cv2.fillConvexPoly(region, hull, 1)
    return region.astype(bool)


def off_axis_parts(mask: np.ndarray, camera: Camera, top: np.ndarray, radius: float,
                   relative: float) -> np.ndarray | None:  # fmt: skip
    """(H, W) bool: the pixels of the main parts of ``mask`` (connected components of at least
    ``relative`` of the largest one's area) that lie on the floor away from the person: less than a
    tenth of their pixels in the person's cylinder (:func:`person_region`, ``top`` the person's head
    top in the previous frame) and their top lower in the image than a point 0.3 m above the floor
    beneath it (the far end of a long shadow that the floor check could not confirm). Such a part
    lies where no part of the person can be (the person moves a few centimetres from frame to frame).
    Upright parts away from the axis are left alone: someone else in view, whose head may be the
    one triangulated. None when there is none (or none of the main parts is in the cylinder: the
    person is not found there, nothing is dropped)."""
    n, labels, stats, _ = cv2.connectedComponentsWithStats((mask > 0).astype(np.uint8), connectivity=8)
    if n <= 2:
        return None
    area = stats[1:, cv2.CC_STAT_AREA]
    main = np.flatnonzero(area >= relative * area.max()) + 1
    if len(main) < 2:
        return None
    low = camera.project(np.array([[top[0], top[1], _FLOOR_LEVEL_M]]))[0, 1]  # image row of knee height there
    inside = np.bincount(labels[person_region(camera, top, radius)], minlength=n)
    on = inside[main] >= _ON_AXIS * stats[main, cv2.CC_STAT_AREA]
    off = main[~on & (stats[main, cv2.CC_STAT_TOP] >= low)]
    if not on.any() or not len(off):
        return None
    lut = np.zeros(n, bool)
    lut[off] = True
    return lut[labels]


def _without(result: tuple, drop: np.ndarray | None) -> tuple:
    """One camera's :meth:`JointExtractor.finish` result, ``(mask, quality)`` or ``(mask, soft,
    quality)``, without the pixels ``drop`` (H, W) bool (None: unchanged); the quality's area, box
    and count of components are those of what is left."""
    if drop is None:
        return result
    *images, quality = result
    images = [np.where(drop, 0, im).astype(im.dtype, copy=False) for im in images]
    left = (images[0] > 0).astype(np.uint8)
    n = cv2.connectedComponents(left, connectivity=8)[0] - 1
    box = cv2.boundingRect(left) if n else None
    return (*images, replace(quality, fraction=float(left.mean()), components=n, bbox=box))
