"""Silhouettes: background models, foreground/shadow classification, clean-up, quality flags.

The tracker's API::

    from gaitcap.silhouette import SilhouetteConfig, SilhouetteExtractor
    ex = SilhouetteExtractor(SilhouetteConfig.load(), name="cam0")
    ex.fit_background(plate=plate_bgr)            # or samples=(N, H, W, 3) frames across the video
    mask, quality = ex.process(frame_bgr)         # (H, W) uint8 0/1 and a FrameQuality

``gaitcap.silhouette.run`` runs the whole stage over videos and writes its outputs.
"""

from gaitcap.silhouette.background import Background, BackgroundReport
from gaitcap.silhouette.config import SilhouetteConfig
from gaitcap.silhouette.extract import FrameQuality, SilhouetteExtractor, flag_names

__all__ = [
    "Background",
    "BackgroundReport",
    "FrameQuality",
    "SilhouetteConfig",
    "SilhouetteExtractor",
    "flag_names",
]
