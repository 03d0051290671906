"""The contact sheet: video frames of every camera with the tracked model drawn over them.

The model is drawn with the project's own geometry: the pose's capsules from the body model
(:meth:`gaitcap.body.model.BodyModel.capsules`), their ends projected through the session's
calibration with its lens distortion (:meth:`gaitcap.camera.Camera.project`, the video frames are
distorted), their radii as the tracker projects them (:func:`gaitcap.body.shape.project_capsules`),
filled with :func:`gaitcap.body.shape.draw_capsule`; the skeleton joins the tracker's points
(``/points_unfiltered``) projected the same way. Left red, right green (the clinical convention).

Each thumbnail is cropped around the drawn model (a portrait box with a margin), so that a subject
small in the image is still seen, and encoded as a small JPEG for the self-contained HTML.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from gaitcap.body.model import BodyModel
from gaitcap.body.recorded import recorded_model
from gaitcap.body.shape import ProjectedCapsules, draw_capsule, project_capsules
from gaitcap.camera import Camera
from gaitcap.errors import GaitcapError
from gaitcap.io.track_h5 import skip_frames_of
from gaitcap.report.fit import FitRecord, SheetFrame
from gaitcap.session import Session
from gaitcap.video import read_frames

log = logging.getLogger("gaitcap.report")

#: thumbnail height (pixels) and width / height of the crop box
THUMB_HEIGHT = 240
THUMB_ASPECT = 0.75
CROP_MARGIN = 0.15  # of the model's box, on every side
JPEG_QUALITY = 80
#: BGR colours: left red, right green (clinical convention), the trunk, head and pelvis blue
SIDE_COLOURS = {"left": (40, 40, 214), "right": (44, 160, 44), "centre": (230, 160, 30)}
FILL_ALPHA = 0.3
SKELETON = (
    ("pelvis", "hip_l"), ("pelvis", "hip_r"), ("hip_l", "knee_l"), ("hip_r", "knee_r"),
    ("knee_l", "ankle_l"), ("knee_r", "ankle_r"), ("ankle_l", "heel_l"), ("ankle_r", "heel_r"),
    ("heel_l", "toe_l"), ("heel_r", "toe_r"), ("ankle_l", "toe_l"), ("ankle_r", "toe_r"),
    ("pelvis", "thorax"), ("thorax", "neck"), ("neck", "head"), ("neck", "shoulder_l"), ("neck", "shoulder_r"),
    ("shoulder_l", "elbow_l"), ("shoulder_r", "elbow_r"), ("elbow_l", "wrist_l"), ("elbow_r", "wrist_r"),
)  # fmt: skip


@dataclass(frozen=True)
class SheetRow:
    """One frame of the sheet: the frame, a JPEG per camera (camera name, bytes)."""

    frame: SheetFrame
    images: tuple[tuple[str, bytes], ...]


@dataclass(frozen=True)
class ContactSheet:
    """The sheet's rows, or none and the sentence that says why; ``note`` says what is drawn."""

    rows: tuple[SheetRow, ...] = ()
    omitted: str = ""
    note: str = ""


def side_of(name: str) -> str:
    """``left``, ``right`` or ``centre`` from a segment or point name (``thigh_l``, ``knee_r``)."""
    return "left" if name.endswith("_l") else "right" if name.endswith("_r") else "centre"


def _as_tracked(session: Session, fit: FitRecord) -> Session:
    """``session`` with the frames the run skipped at the start of each camera's video (the
    ``skip_frames`` attribute of its trajectories.h5: session.yaml's, or those a run tracked again in
    step found, ``frame_sync``), not session.yaml's as it reads now; runs that do not record them keep
    session.yaml's."""
    skips = skip_frames_of(fit.record.attrs)
    return session if skips is None else replace(session, info=session.info.model_copy(update={"skip_frames": skips}))


def open_session(fit: FitRecord, override: Path | None = None) -> tuple[Session | None, str]:
    """The run's session (``override``, else the folder ``track.json`` or ``trajectories.h5``
    records, a relative one tried from the working folder and from the run's folder), or None and a
    sentence saying why it cannot be opened."""
    recorded = [override] if override is not None else [fit.track_json.get("session"), fit.record.attrs.get("session")]
    candidates = [Path(p) for p in recorded if p]
    if not candidates:
        return None, "this run does not record its session folder (give it with --session)"
    tried = []
    for path in candidates:
        for folder in (path,) if path.is_absolute() else (path, fit.run_dir / path):
            tried.append(str(folder))
            if folder.is_dir():
                try:
                    session = _as_tracked(Session.open(folder), fit)
                except GaitcapError as e:
                    return None, f"the session cannot be read ({e})"
                if override is not None:
                    _check_given_session(fit, folder)
                return session, ""
    where = ", ".join(dict.fromkeys(tried))
    if override is not None:
        return None, f"the session folder given with --session is not found ({where})"
    return None, f"the session folder is not found ({where}; give it with --session)"


def _check_given_session(fit: FitRecord, folder: Path) -> None:
    """Warn when the session given with --session is not the one the run recorded by name (a session
    moved keeps its name; another one draws the model over another room)."""
    recorded = fit.track_json.get("session") or fit.record.attrs.get("session")
    if recorded and Path(str(recorded)).name != folder.resolve().name:
        log.warning("--session %s: this run tracked %s (track.json): the model is drawn over another session's "
                    "videos", folder, recorded)  # fmt: skip


def tracked_model(fit: FitRecord) -> tuple[BodyModel | None, str]:
    """The body model the run tracked (:func:`gaitcap.body.recorded.recorded_model`), or None and why."""
    model, why = recorded_model(fit.record)
    return model, (f"{why}: the skeleton only is drawn" if model is None else "")


def project_model(camera: Camera, model: BodyModel, q: np.ndarray) -> ProjectedCapsules:
    """The capsules of pose ``q`` (D,) in ``camera``'s distorted image: ends a, b (K, 2), radii (K,)."""
    A, B, radii = model.capsules(q[None])
    pc = project_capsules(camera, A[0], B[0], radii)
    return replace(pc, a=camera.project(A[0]), b=camera.project(B[0]))


def draw_model(image: np.ndarray, pc: ProjectedCapsules, sides: list[str], thickness: int) -> None:
    """Fill each side's capsules translucent and outline them, in place on ``image`` (H, W, 3)."""
    h, w = image.shape[:2]
    for side in ("centre", "right", "left"):  # the left leg drawn last, on top
        mask = np.zeros((h, w), np.uint8)
        for k in (k for k, s in enumerate(sides) if s == side):
            draw_capsule(mask, pc.a[k], pc.b[k], float(pc.ra[k]), float(pc.rb[k]), 1)
        if not mask.any():
            continue
        colour = np.array(SIDE_COLOURS[side], np.float32)
        on = mask.astype(bool)
        image[on] = ((1 - FILL_ALPHA) * image[on] + FILL_ALPHA * colour).astype(np.uint8)
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        cv2.drawContours(image, contours, -1, SIDE_COLOURS[side], thickness, cv2.LINE_AA)


def draw_skeleton(image: np.ndarray, pixels: dict[str, np.ndarray], thickness: int) -> None:
    """Lines between the projected points ``name -> (2,)`` pixels, and dots at the joints, in place."""
    for a, b in SKELETON:
        pa, pb = pixels.get(a), pixels.get(b)
        if pa is None or pb is None or not (np.all(np.isfinite(pa)) and np.all(np.isfinite(pb))):
            continue
        colour = SIDE_COLOURS[side_of(b)]
        cv2.line(image, _pt(pa), _pt(pb), (255, 255, 255), 2 * thickness, cv2.LINE_AA)
        cv2.line(image, _pt(pa), _pt(pb), colour, thickness, cv2.LINE_AA)
    for name, p in pixels.items():
        if np.all(np.isfinite(p)):
            cv2.circle(image, _pt(p), thickness + 1, SIDE_COLOURS[side_of(name)], -1, cv2.LINE_AA)


def _pt(p: np.ndarray) -> tuple[int, int]:
    return int(round(float(p[0]))), int(round(float(p[1])))


def crop_box(pixels: np.ndarray, size: tuple[int, int]) -> tuple[int, int, int, int]:
    """A portrait box (x0, y0, x1, y1) around the finite ``pixels`` (N, 2) with a margin, of
    aspect :data:`THUMB_ASPECT`; the whole image (w, h) when there is none. May reach outside the
    image (padded by :func:`crop`)."""
    w, h = size
    ok = pixels[np.all(np.isfinite(pixels), axis=1)]
    if len(ok) == 0:
        return 0, 0, w, h
    (x0, y0), (x1, y1) = ok.min(axis=0), ok.max(axis=0)
    bh = max(y1 - y0, (x1 - x0) / THUMB_ASPECT, 16.0) * (1 + 2 * CROP_MARGIN)
    bh = min(bh, 2.0 * max(w, h))  # a model far outside the image: do not zoom out without end
    bw = bh * THUMB_ASPECT
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    return int(round(cx - bw / 2)), int(round(cy - bh / 2)), int(round(cx + bw / 2)), int(round(cy + bh / 2))


def crop(image: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    """``image`` (H, W, 3) cut to ``box``, grey where the box reaches outside it."""
    h, w = image.shape[:2]
    x0, y0, x1, y1 = box
    pad = max(0, -x0, -y0, x1 - w, y1 - h)
    if pad:
        image = cv2.copyMakeBorder(image, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=(96, 96, 96))
    return image[y0 + pad : y1 + pad, x0 + pad : x1 + pad]


def floor_below(points: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """(1, 3): the floor (z = 0) beneath the pelvis of ``points`` (P, 3); NaN without one. The crop
    reaches down to it, so a model drawn too small or floating still shows the person's feet, which
    stand on the floor, and how far off the model is."""
    if "pelvis" not in names:
        return np.full((1, 3), np.nan)
    x, y, _ = points[names.index("pelvis")]
    return np.array([[x, y, 0.0]])


def thumbnail(frame: np.ndarray, camera: Camera, model: BodyModel | None, q: np.ndarray,
              points: np.ndarray, names: tuple[str, ...]) -> bytes:  # fmt: skip
    """One camera's frame (H, W, 3) BGR with the pose drawn (capsules of ``q`` (D,) when ``model``
    is given, the skeleton of ``points`` (P, 3)), cropped around it and the floor beneath its pelvis
    (:func:`floor_below`), as JPEG bytes."""
    pixels = camera.project(points)
    outline = [pixels, camera.project(floor_below(points, names))]
    pc = None
    if model is not None and np.all(np.isfinite(q)):
        pc = project_model(camera, model, q)
        outline += [pc.a - pc.ra[:, None], pc.a + pc.ra[:, None], pc.b - pc.rb[:, None], pc.b + pc.rb[:, None]]
    box = crop_box(np.concatenate(outline), (frame.shape[1], frame.shape[0]))
    thick = max(1, round((box[3] - box[1]) / THUMB_HEIGHT))  # about one pixel of the thumbnail
    image = frame.copy()
    if pc is not None:
        draw_model(image, pc, [side_of(model.segments[s].name) for s in model.capsule_segment], thick)
    draw_skeleton(image, dict(zip(names, pixels, strict=True)), 2 * thick)
    cut = crop(image, box)
    size = (max(1, round(THUMB_HEIGHT * cut.shape[1] / max(cut.shape[0], 1))), THUMB_HEIGHT)
    small = cv2.resize(cut, size, interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return buf.tobytes()


def _session_frames(video: Path, indices: list[int], skip: int) -> dict[int, np.ndarray]:
    """Frames ``indices`` of the session from a camera's ``video`` whose first ``skip`` frames the session
    skips (``skip_frames``), keyed by the session's index."""
    read = read_frames(video, [i + skip for i in indices])
    return {i - skip: image for i, image in read.items()}


def contact_sheet(fit: FitRecord, frames: list[SheetFrame], session: Path | None = None) -> ContactSheet:
    """The contact sheet of ``frames``, or an empty one whose ``omitted`` says why (the session's
    videos or calibration cannot be read)."""
    ses, why = open_session(fit, session)
    if ses is None:
        return ContactSheet(omitted=f"The contact sheet is omitted: {why}.")
    model, note = tracked_model(fit)
    rec = fit.record
    wanted = [f.index for f in frames]
    try:
        videos = {cam: _session_frames(ses.videos[cam], wanted, ses.offsets[cam]) for cam in ses.rig.names}
    except GaitcapError as e:
        return ContactSheet(omitted=f"The contact sheet is omitted: the videos cannot be read ({e}).")
    rows = []
    for f in frames:
        images = tuple((cam.name, thumbnail(videos[cam.name][f.index], cam, model, rec.poses[f.index],
                                            rec.points[f.index], rec.names))
                       for cam in ses.rig if f.index in videos[cam.name])  # fmt: skip
        if images:
            rows.append(SheetRow(f, images))
    if not rows:
        return ContactSheet(omitted=f"The contact sheet is omitted: the videos in {ses.root} hold none of the "
                                    "tracked frames.")  # fmt: skip
    drawn = "the tracked body model (capsules) and its skeleton" if model is not None else "the tracked skeleton"
    where = f"Frames of {ses.root}, with {drawn} projected through its calibration."
    return ContactSheet(tuple(rows), note=f"{where} {note[:1].upper()}{note[1:]}." if note else where)
