"""The silhouettes of one frame of every camera together: per-camera tests, the floor-shadow
check across cameras (:mod:`gaitcap.silhouette.floor`), then each camera's clean-up, which keeps
small components below the body down to the floor beneath the person (a foot whose leg the
foreground lost), that floor's row in each camera found from the previous frame's masks
(:func:`~gaitcap.silhouette.floor.floor_rows`: their head tops triangulated)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from gaitcap.camera import Camera
from gaitcap.errors import InputError
from gaitcap.silhouette.config import SilhouetteConfig
from gaitcap.silhouette.extract import FrameEvidence, FrameQuality, SilhouetteExtractor, working_size
from gaitcap.silhouette.floor import FloorShadowCheck, floor_rows, person_floor_point

MapFn = Callable[..., Iterable[Any]]


def floor_check(cameras: Sequence[Camera], config: SilhouetteConfig) -> FloorShadowCheck | None:
    """The floor geometry :class:`JointExtractor` re-labels shadows with, for calibrated ``cameras``
    whose videos have the calibration's size; None when ``config`` has no floor check. Built from
    the calibration alone, so it can be built while the backgrounds are fitted."""
    s = config.shadow
    if not (s.enabled and s.floor_check):
        return None
    sizes = [working_size(tuple(cam.size), config.scale) for cam in cameras]
    return FloorShadowCheck(cameras, sizes, s.floor_tolerance, s.floor_reach, s.floor_footprint)


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
        #: the floor point (x, y) beneath the person in the previous frame (None: not known)
        self._centre: np.ndarray | None = None
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
        self._follow([r[0] for r in out])
        return out

    def _follow(self, masks: list[np.ndarray]) -> None:
        """The floor's row beneath the person in each camera, from this frame's masks, for the next
        frame (the person moves a few centimetres from frame to frame)."""
        if self._cameras is not None and len(self._cameras) > 1:
            foot = person_floor_point(self._cameras, masks)
            self._floor_rows = floor_rows(self._cameras, masks, foot)
            self._centre = None if foot is None else foot[:2]

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
            centre = self._centre if cfg.floor_footprint else None
            shadows = self.floor.relabel(shadows, [e.darkening for e in evidence], deep, ratio, body,
                                         cfg.floor_ratio_tolerance, centre)  # fmt: skip
        return evidence, shadows
