"""Summaries and sanity checks of a calibrated rig (``gaitcap calibrate check``), and the
geometric checks that refuse a calibration that cannot be right before tracking
(:func:`geometry_problems`, :func:`check_rig_geometry`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations
from pathlib import Path
from typing import Any

import numpy as np

from gaitcap.camera import Camera, CameraRig
from gaitcap.errors import CalibrationError

#: the largest recorded reprojection RMS (px) of a good calibration (``gaitcap calibrate check``)
MAX_ERROR_PX = 1.0
#: a recorded reprojection RMS (px) above which a camera's calibration cannot be tracked with: its
#: rays miss the subject by a limb's width or more (``gaitcap track`` refuses it)
UNUSABLE_ERROR_PX = 5.0
MAX_ASPECT_DEVIATION = 0.05
#: the farthest a camera of a gait lab stands from the calibration's origin (on the walkway), and
#: the farthest it sees the floor: a walkway and its cameras fit in a few tens of metres
MAX_CAMERA_DISTANCE_M = 30.0
#: the nearest a camera stands from the origin once its translation is read in millimetres
MIN_CAMERA_DISTANCE_M = 0.3
#: samples per image edge where the rays that reach the floor are looked for
_EDGE_SAMPLES = 9


def floor_distance(cam: Camera) -> float:
    """Distance (m) from the camera to the nearest point of the floor plane z = 0 that its image
    sees (in front of it), inf when no ray of its image meets the floor.

    The ray through pixel (u, v) has the world direction ``d = R^T K^-1 (u, v, 1)``; from the
    centre ``C`` (``C_z > 0``) it meets the floor at ``s = C_z / -d_z`` along the unit ray when
    it points down. The nearest such point lies on the image border (the lowest ray), sampled
    ``_EDGE_SAMPLES`` times per edge.
    """
    w, h = cam.size
    t = np.linspace(0.0, 1.0, _EDGE_SAMPLES)
    u = np.concatenate([t * (w - 1), t * (w - 1), np.zeros_like(t), np.full_like(t, w - 1)])
    v = np.concatenate([np.zeros_like(t), np.full_like(t, h - 1), t * (h - 1), t * (h - 1)])
    rays = np.linalg.solve(cam.matrix, np.stack([u, v, np.ones_like(u)])).T @ cam.R  # (N, 3) world
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    cz = float(cam.center[2])
    down = rays[:, 2] < 0
    if cz <= 0 or not down.any():
        return float("inf")
    return float(np.min(cz / -rays[down, 2]))


def geometry_problems(rig: CameraRig) -> list[str]:
    """What makes ``rig`` impossible for a gait lab, with the likely cause; [] when plausible.

    In order (the first cause found explains the others, so only its sentences are returned):

    1. a camera farther than ``MAX_CAMERA_DISTANCE_M`` from the origin: when every far camera
       would stand 0.3-30 m away with its translation divided by 1000, the translations are in
       millimetres (a common slip: the cameras then stand kilometres away);
    2. a camera that is the world frame itself (zero rotation and translation: a stereo or one-camera
       calibration, whose frame is its first camera's, not the floor's);
    3. a camera below the floor (``C_z < 0``): the world's z axis points down, or the floor is not
       z = 0 (gaitcap needs z up, the floor at z = 0);
    4. a camera that looks away from the floor: no ray of its image meets z = 0 within
       ``MAX_CAMERA_DISTANCE_M`` (looking up, or a y-up world), so it cannot see the feet.
    """
    dist = {cam.name: float(np.linalg.norm(cam.center)) for cam in rig}
    far = {name: d for name, d in dist.items() if d > MAX_CAMERA_DISTANCE_M}
    if far:
        listing = ", ".join(f"{name!r} {d:,.0f} m" for name, d in far.items())
        if all(MIN_CAMERA_DISTANCE_M <= d / 1000.0 <= MAX_CAMERA_DISTANCE_M for d in far.values()):
            return [f"camera(s) {listing} from the origin: the translations look like millimetres given as metres "
                    "(divide them by 1000; gaitcap reads metres)"]  # fmt: skip
        return [f"camera(s) {listing} from the origin, farther than {MAX_CAMERA_DISTANCE_M:g} m: the origin is not on the "
                "walkway or the translations are not in metres"]  # fmt: skip
    own = [cam.name for cam in rig if not cam.rvec.any() and not cam.tvec.any()]
    if own:
        return [f"camera {own[0]!r} is the world frame itself (at the origin, its axes the world's): a stereo or "
                "one-camera calibration, with no floor; place the cameras on the floor with `gaitcap calibrate "
                "extrinsics` (gaitcap needs z up, the floor at z = 0)"]  # fmt: skip
    below = ", ".join(f"{cam.name!r} (z = {cam.center[2]:.2f} m)" for cam in rig if cam.center[2] < 0)
    if below:
        return [f"camera(s) {below} below the floor: the world's z axis must point up with the floor at z = 0 "
                "(is it pointing down?)"]  # fmt: skip
    away = ", ".join(repr(cam.name) for cam in rig if not floor_distance(cam) <= MAX_CAMERA_DISTANCE_M)
    if away:
        return [f"camera(s) {away} look away from the floor: no ray of the image meets the floor plane z = 0 within "
                f"{MAX_CAMERA_DISTANCE_M:g} m (a camera looking up, or a world whose z axis is not up), so the feet "
                "cannot be seen"]  # fmt: skip
    return []


def check_rig_geometry(rig: CameraRig, source: str | Path) -> None:
    """Refuse a calibration that cannot be right (see :func:`geometry_problems`).

    Raises:
        CalibrationError: one line, ``"<source>: <the problems and their likely cause>"``.
    """
    problems = geometry_problems(rig)
    if problems:
        raise CalibrationError(f"{source}: " + "; ".join(problems))


def recorded_errors(metadata: dict[str, Any], key: str = "reprojection_rms_px") -> dict[str, float]:
    """A per-camera table of calibration.toml's ``[metadata]`` (camera -> px): ``reprojection_rms_px``
    (the extrinsics', as ``calibrate extrinsics`` records it) or ``intrinsics_rms_px``; empty when absent."""
    table = metadata.get(key)
    if not isinstance(table, dict):
        return {}
    return {str(k): float(v) for k, v in table.items() if isinstance(v, (int, float))}


def overall_error(metadata: dict[str, Any]) -> float | None:
    """``[metadata] error``, the overall reprojection RMS (px), or None when absent or not measured (-1)."""
    overall = metadata.get("error")
    return float(overall) if isinstance(overall, (int, float)) and overall >= 0 else None


def camera_error(metadata: dict[str, Any], name: str) -> float | None:
    """A camera's own reprojection error (px) in a calibration.toml ``[metadata]``: its intrinsics' (as
    OpenCV files record it), else its extrinsics', else the overall one; None when not measured."""
    for key in ("intrinsics_rms_px", "reprojection_rms_px"):
        if (error := recorded_errors(metadata, key).get(name)) is not None:
            return error
    return overall_error(metadata)


def check_recorded_errors(rig: CameraRig, metadata: dict[str, Any], source: str | Path) -> list[str]:
    """Refuse a calibration whose recorded reprojection error (``[metadata]``: each camera's, or else
    the overall one) is above :data:`UNUSABLE_ERROR_PX`; returns a note when one is above
    :data:`MAX_ERROR_PX`.

    Raises:
        CalibrationError: naming ``source`` and each camera (or the overall error) and its value.
    """
    per_cam = recorded_errors(metadata)
    errors = {f"camera {c.name!r}": per_cam[c.name] for c in rig if c.name in per_cam}
    if not errors and (overall := overall_error(metadata)) is not None:
        errors = {"overall": overall}

    def listing(limit: float) -> str:  # those above limit, with their errors
        return ", ".join(f"{e:.2f} px overall" if what == "overall" else f"{what} {e:.2f} px"
                         for what, e in errors.items() if e > limit)  # fmt: skip

    if unusable := listing(UNUSABLE_ERROR_PX):
        raise CalibrationError(
            f"{source}: the reprojection error it records ([metadata]) is {unusable}: above "
            f"{UNUSABLE_ERROR_PX:g} px a camera's rays miss the subject; calibrate again "
            f"(`gaitcap calibrate check` lists the problems)")  # fmt: skip
    if poor := listing(MAX_ERROR_PX):
        return [f"{source}: the reprojection error it records is {poor} (above {MAX_ERROR_PX:g} px: a poor "
                "calibration; positions may be off by centimetres)"]  # fmt: skip
    return []


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

    Problems: a recorded reprojection error (of the extrinsics, or of a camera's intrinsics as
    ``calibrate intrinsics`` records it) above ``max_error_px``, fx/fy differing by more than
    5 %, a principal point outside the middle half of the image, the geometry that cannot be
    right (:func:`geometry_problems`: cameras kilometres away, under the floor or looking away
    from it), two cameras at the same place, or video frames whose size cannot be a crop of the
    calibration.
    """
    meta = metadata or {}
    rep = CheckReport()
    per_cam = recorded_errors(meta)
    intrinsics = recorded_errors(meta, "intrinsics_rms_px")
    w = max([10, *(len(cam.name) for cam in rig)])  # the names' column: long names keep the table aligned
    rep.lines.append(f"{'camera':<{w}} {'size':>10} {'fx':>9} {'fy':>9} {'cx':>8} {'cy':>8}  {'position x, y, z (m)':<24} {'rms px':>7}")
    for cam in rig:
        K = cam.matrix
        c = cam.center
        err = per_cam.get(cam.name)
        rep.lines.append(
            f"{cam.name:<{w}} {cam.width:>5}x{cam.height:<4} {K[0, 0]:9.2f} {K[1, 1]:9.2f} {K[0, 2]:8.2f} {K[1, 2]:8.2f}  "
            f"{c[0]:7.3f} {c[1]:7.3f} {c[2]:7.3f}   {'' if err is None else f'{err:7.3f}'}"
        )
        if abs(K[0, 0] / K[1, 1] - 1) > MAX_ASPECT_DEVIATION:
            rep.problems.append(f"camera {cam.name!r}: fx/fy = {K[0, 0] / K[1, 1]:.3f} (square pixels expected)")
        if not (0.25 * cam.width < K[0, 2] < 0.75 * cam.width and 0.25 * cam.height < K[1, 2] < 0.75 * cam.height):
            rep.problems.append(f"camera {cam.name!r}: principal point ({K[0, 2]:.0f}, {K[1, 2]:.0f}) far from the image centre")
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
    rep.problems.extend(geometry_problems(rig))
    if len(rig) > 1:
        rep.lines.append("distances between cameras (m):")
        for a, b in combinations(rig, 2):
            d = float(np.linalg.norm(a.center - b.center))
            rep.lines.append(f"  {a.name} - {b.name}: {d:.3f}")
            if d < 0.01:
                rep.problems.append(f"cameras {a.name!r} and {b.name!r} are at the same place (extrinsics missing?)")
    if (overall := overall_error(meta)) is not None:
        rep.lines.append(f"reprojection error (overall RMS): {overall:.3f} px")
        if overall > max_error_px and not per_cam and not intrinsics:  # else named per camera
            rep.problems.append(f"reprojection error {overall:.2f} px > {max_error_px:g} px")
    else:
        rep.notes.append("no reprojection error recorded in [metadata] (imported or unknown)")
    if intrinsics:
        rep.lines.append("intrinsics reprojection RMS (px): " + ", ".join(f"{c} {e:.3f}" for c, e in intrinsics.items()))
        rep.problems.extend(f"camera {c!r}: intrinsics reprojection error {e:.2f} px > {max_error_px:g} px"
                            for c, e in intrinsics.items() if e > max_error_px)  # fmt: skip
    if "check_3d_mm" in meta and float(meta["check_3d_mm"]) >= 0:
        rep.lines.append(f"3D check: {float(meta['check_3d_mm']):.2f} mm RMS")
    return rep
