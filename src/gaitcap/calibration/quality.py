"""Summaries and sanity checks of a calibrated rig (``gaitcap calibrate check``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations
from typing import Any

import numpy as np

from gaitcap.camera import CameraRig

MAX_ERROR_PX = 1.0
MAX_ASPECT_DEVIATION = 0.05


@dataclass
class CheckReport:
    """Lines to print and the problems that make a calibration poor."""

    lines: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems


def check_rig(
    rig: CameraRig,
    metadata: dict[str, Any] | None = None,
    frame_sizes: dict[str, tuple[int, int]] | None = None,
    max_error_px: float = MAX_ERROR_PX,
) -> CheckReport:
    """Describe every camera, the distances between cameras and the reprojection summary.

    Problems: a recorded reprojection error above ``max_error_px``, fx/fy differing by more than
    5 %, a principal point outside the middle half of the image, a camera under the floor, two
    cameras at the same place, or video frames whose size cannot be a crop of the calibration.
    """
    meta = metadata or {}
    rep = CheckReport()
    per_cam = meta.get("reprojection_rms_px", {}) if isinstance(meta.get("reprojection_rms_px"), dict) else {}
    rep.lines.append(f"{'camera':<10} {'size':>10} {'fx':>9} {'fy':>9} {'cx':>8} {'cy':>8}  {'position x, y, z (m)':<24} {'rms px':>7}")
    for cam in rig:
        K = cam.matrix
        c = cam.center
        err = per_cam.get(cam.name)
        rep.lines.append(
            f"{cam.name:<10} {cam.width:>5}x{cam.height:<4} {K[0, 0]:9.2f} {K[1, 1]:9.2f} {K[0, 2]:8.2f} {K[1, 2]:8.2f}  "
            f"{c[0]:7.3f} {c[1]:7.3f} {c[2]:7.3f}   {'' if err is None else f'{err:7.3f}'}"
        )
        if abs(K[0, 0] / K[1, 1] - 1) > MAX_ASPECT_DEVIATION:
            rep.problems.append(f"camera {cam.name!r}: fx/fy = {K[0, 0] / K[1, 1]:.3f} (square pixels expected)")
        if not (0.25 * cam.width < K[0, 2] < 0.75 * cam.width and 0.25 * cam.height < K[1, 2] < 0.75 * cam.height):
            rep.problems.append(f"camera {cam.name!r}: principal point ({K[0, 2]:.0f}, {K[1, 2]:.0f}) far from the image centre")
        if c[2] < 0:
            rep.problems.append(f"camera {cam.name!r}: below the floor (z = {c[2]:.2f} m)")
        if err is not None and err > max_error_px:
            rep.problems.append(f"camera {cam.name!r}: reprojection error {err:.2f} px > {max_error_px:g} px")
        if frame_sizes and cam.name in frame_sizes and tuple(frame_sizes[cam.name]) != cam.size:
            fw, fh = frame_sizes[cam.name]
            dw, dh = cam.width - fw, cam.height - fh
            msg = f"camera {cam.name!r}: video frames are {fw}x{fh}, calibration {cam.width}x{cam.height}"
            if abs(dw) <= 0.05 * cam.width and abs(dh) <= 0.05 * cam.height:
                rep.notes.append(msg + f" (treated as a centred crop: principal point shifted by ({-dw / 2:g}, {-dh / 2:g}) px)")
            else:
                rep.problems.append(msg + " (not a small crop: recalibrate)")
    if len(rig) > 1:
        rep.lines.append("distances between cameras (m):")
        for a, b in combinations(rig, 2):
            d = float(np.linalg.norm(a.center - b.center))
            rep.lines.append(f"  {a.name} - {b.name}: {d:.3f}")
            if d < 0.01:
                rep.problems.append(f"cameras {a.name!r} and {b.name!r} are at the same place (extrinsics missing?)")
    if "error" in meta and float(meta["error"]) >= 0:
        overall = float(meta["error"])
        rep.lines.append(f"reprojection error (overall RMS): {overall:.3f} px")
        if overall > max_error_px and not per_cam:
            rep.problems.append(f"reprojection error {overall:.2f} px > {max_error_px:g} px")
    else:
        rep.notes.append("no reprojection error recorded in [metadata] (imported or unknown)")
    if "check_3d_mm" in meta and float(meta["check_3d_mm"]) >= 0:
        rep.lines.append(f"3D check: {float(meta['check_3d_mm']):.2f} mm RMS")
    return rep
