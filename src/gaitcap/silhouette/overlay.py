"""Overlay drawing: the mask tinted and outlined on the frame, with its quality line."""

from __future__ import annotations

import cv2
import numpy as np

from gaitcap.silhouette.extract import FrameQuality

#: the mask's tint and outline (BGR): cyan and yellow, apart from the report's red (left) and green (right)
MASK_BGR, OUTLINE_BGR = (230, 200, 0), (0, 230, 255)


def draw_overlay(frame: np.ndarray, mask: np.ndarray, quality: FrameQuality | None = None) -> np.ndarray:
    """Return a copy of ``frame`` (H, W, 3) uint8 with ``mask`` (H, W) 0/1 tinted cyan and outlined in
    yellow: not the report's left (red) and right (green) colours, which the mask has nothing to do with.

    The top-left corner shows the frame index, foreground fraction and flags.
    """
    out = frame.copy()
    on = mask.astype(bool)
    tint = np.array(MASK_BGR, np.float32)
    out[on] = (0.55 * out[on] + 0.45 * tint).astype(np.uint8)
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    thick = max(1, round(frame.shape[1] / 640))
    cv2.drawContours(out, contours, -1, OUTLINE_BGR, thick)
    if quality is not None:
        text = f"#{quality.index}  fg {100 * quality.fraction:.1f}%  " + (",".join(quality.flag_names) or "ok")
        scale, origin = 0.5 * thick, (8, int(22 * thick))
        # white on a black box: an outline drawn as the same text at a greater thickness is laid out wider by
        # OpenCV 5, so it no longer lines up with the text
        (w, h), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thick)
        pad = 3 * thick
        cv2.rectangle(out, (origin[0] - pad, origin[1] - h - pad), (origin[0] + w + pad, origin[1] + base + pad),
                      (0, 0, 0), cv2.FILLED)  # fmt: skip
        cv2.putText(out, text, origin, cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), thick, cv2.LINE_AA)
    return out
