"""``gaitcap calibrate``: intrinsics, extrinsics, stereo, check, import and export."""

from __future__ import annotations

import logging
import shutil
from pathlib import Path

import click
import cv2
import numpy as np

from gaitcap.calibration import extrinsics as ext
from gaitcap.calibration.boards import Board, parse_board_size, parse_length
from gaitcap.calibration.formats import read_opencv_camera, read_opencv_error, read_qualisys, write_opencv_camera
from gaitcap.calibration.intrinsics import MIN_VIEWS, calibrate_intrinsics
from gaitcap.calibration.quality import MAX_ERROR_PX, camera_error, check_rig
from gaitcap.calibration.views import IMAGE_SUFFIXES, VIDEO_SUFFIXES, detect_views, paired_views
from gaitcap.camera import Camera, CameraRig
from gaitcap.cli.options import force_option, handle_errors
from gaitcap.config import load_yaml_model
from gaitcap.errors import CalibrationError, InputError, OutputError
from gaitcap.io.atomic import refuse_existing
from gaitcap.io.calibration_toml import read_calibration, read_calibration_metadata, write_calibration
from gaitcap.session import CALIBRATION_FILE, VIDEOS_DIR, VIDEO_EXTENSIONS, find_per_camera

log = logging.getLogger("gaitcap.cli.calibrate")

#: a video step is a count of frames (0 would read none: a division by zero); a threshold in px or
#: a fraction of a square is above 0 (at or below it every view or camera is refused)
_STEP = click.IntRange(min=1)
_POSITIVE = click.FloatRange(min=0, min_open=True)


def board_options(func):
    """--board, --square, --charuco, --marker, --dictionary."""
    for opt in reversed([
        click.option("--board", "board_size", default="9x6", show_default=True, help="Inner corners COLSxROWS (ChArUco: squares)."),
        click.option("--square", default="25mm", show_default=True, help="Square side, e.g. 25mm, 2.5cm, 0.025m."),
        click.option("--charuco", is_flag=True, help="A ChArUco board instead of a checkerboard."),
        click.option("--marker", default=None, help="ChArUco marker side, e.g. 18mm, 1.8cm, 0.018m; a bare number is mm (default 3/4 of the square)."),
        click.option("--dictionary", default="DICT_4X4_50", show_default=True, help="ChArUco ArUco dictionary."),
    ]):
        func = opt(func)
    return func


def make_board(board_size: str, square: str, charuco: bool, marker: str | None, dictionary: str) -> Board:
    cols, rows = parse_board_size(board_size)
    return Board(cols, rows, parse_length(square), "charuco" if charuco else "checkerboard",
                 parse_length(marker) if marker else None, dictionary)


def read_cameras(path: Path) -> list[Camera]:
    """Cameras from calibration.toml, OpenCV .yml/.yaml/.xml or Qualisys .qca.txt."""
    name = path.name.lower()
    if name.endswith(".toml"):
        return list(read_calibration(path))
    if name.endswith((".yml", ".yaml", ".xml")) and not name.endswith(".qca.txt"):
        return [read_opencv_camera(path)]
    if name.endswith((".qca.txt", ".qca")):
        return list(read_qualisys(path))
    raise CalibrationError(f"{path}: unknown calibration format (expected .toml, .yml, .xml or .qca.txt)")


#: the files ``-o`` may name: gaitcap's calibration.toml, or an OpenCV file of one camera
OUTPUT_SUFFIXES = (".toml", ".yml", ".yaml", ".xml")


def check_new(path: Path, force: bool) -> None:
    """Refuse an output of an unknown type, or an existing one unless ``force``: called before the work too, so that
    nothing computed is lost."""
    if path.suffix.lower() not in OUTPUT_SUFFIXES:
        raise OutputError(f"{path}: unknown calibration file type: name a .toml (gaitcap) "
                          "or .yml/.yaml/.xml (OpenCV) file")
    refuse_existing(path, force)


def keep_previous(path: Path) -> Path | None:
    """Copy an existing ``path`` to ``path.bak`` (or, when that exists, the first free ``path.bak2``,
    ``path.bak3``...: no earlier copy is replaced) before it is overwritten; returns the copy (None:
    nothing to keep)."""
    if not path.exists():
        return None
    backup = path.with_name(path.name + ".bak")
    k = 2
    while backup.exists():
        backup, k = path.with_name(f"{path.name}.bak{k}"), k + 1
    try:
        shutil.copy2(path, backup)
    except OSError as e:
        raise OutputError(f"{backup}: cannot keep the previous {path.name} ({e.strerror}); nothing written") from e
    return backup


def write_cameras(path: Path, rig: CameraRig, metadata: dict, force: bool) -> None:
    check_new(path, force)
    if path.suffix.lower() in (".yml", ".yaml", ".xml"):
        if len(rig) != 1:
            raise OutputError(f"{path}: an OpenCV file holds one camera; use `gaitcap calibrate export` for a rig")
        write_opencv_camera(path, rig[0], metadata)
    else:
        write_calibration(path, rig, metadata)


@click.group("calibrate")
def command() -> None:
    """Calibrate cameras: intrinsics, extrinsics, checks, and conversions of calibration files.

    \b
    Example:
        gaitcap calibrate intrinsics calib/left*.jpg --board 9x6 --square 25mm -o left.toml
        gaitcap calibrate extrinsics sessions/walk01 --board 9x6 --square 120mm --intrinsics cams.toml
        gaitcap calibrate check sessions/walk01
    """


@command.command("intrinsics")
@click.argument("inputs", nargs=-1, required=True, type=click.Path(path_type=Path))
@board_options
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True, help="calibration.toml, or OpenCV .yml/.xml.")
@click.option("--name", default=None, help="Camera name (default: the output file stem).")
@click.option("--fix-aspect-ratio", is_flag=True, help="Force fx = fy.")
@click.option("--fix-k3", is_flag=True, help="Estimate k1, k2, p1, p2 only (few views or a small board).")
@click.option("--max-views", type=click.IntRange(min=MIN_VIEWS), default=25, show_default=True, help="Use at most this many well-spread views.")
@click.option("--video-step", type=_STEP, default=10, show_default=True, help="Read every n-th video frame.")
@click.option("--max-blur", type=_POSITIVE, default=0.25, show_default=True, help="Reject views whose edges are blurred over this fraction of a square.")
@force_option
@handle_errors
def intrinsics_cmd(inputs, board_size, square, charuco, marker, dictionary, output, name, fix_aspect_ratio, fix_k3, max_views, video_step, max_blur, force):
    """Calibrate one camera from images or a video of a board.

    \b
    Example:
        gaitcap calibrate intrinsics calib/left*.jpg --board 9x6 --square 25mm --fix-aspect-ratio -o left.toml
        gaitcap calibrate intrinsics cam01_board.mp4 --board 4x7 --square 60mm -o cam01.toml
    """
    check_new(output, force)
    board = make_board(board_size, square, charuco, marker, dictionary)
    views = detect_views(inputs, board, video_step=video_step, max_blur=max_blur)
    for source, reason in views.rejected.items():
        log.info("  rejected %s: %s", source, reason)
    name = name or output.name.split(".")[0]
    views.require(MIN_VIEWS, f"camera {name!r}")
    res = calibrate_intrinsics(views.detections, board, name, fix_aspect_ratio, fix_k3, max_views=max_views)
    K = res.camera.matrix
    click.echo(f"{name}: {len(res.per_view_px)} views used, {len(views.rejected)} rejected, image {res.camera.width}x{res.camera.height}")
    click.echo(f"  fx {K[0, 0]:.3f}  fy {K[1, 1]:.3f}  cx {K[0, 2]:.3f}  cy {K[1, 2]:.3f}")
    click.echo("  distortion " + " ".join(f"{v:.5f}" for v in res.camera.dist))
    click.echo(f"  RMS reprojection error {res.rms_px:.4f} px; image coverage {res.coverage:.0%}")
    for source, err in res.per_view_px.items():
        click.echo(f"    {source:<28} {err:.4f} px")
    write_cameras(output, CameraRig((res.camera,)), res.metadata(), force)
    click.echo(f"wrote {output}")


def _default_views(session: Path, name: str) -> Path:
    folder = session / "extrinsics"
    for cand in [folder / name] + [folder / f"{name}{ext}" for ext in IMAGE_SUFFIXES + VIDEO_SUFFIXES]:
        if cand.exists():
            return cand
    raise InputError(f"{folder}: no board view for camera {name!r} (give --views {name}=PATH)")


@command.command("extrinsics")
@click.argument("session", type=click.Path(path_type=Path, file_okay=False))
@board_options
@click.option("--intrinsics", "intrinsics_files", multiple=True, type=click.Path(path_type=Path, dir_okay=False),
              help="Camera intrinsics (.toml/.yml/.xml, repeatable); default: the session's calibration.toml.")
@click.option("--views", "views_opt", multiple=True, metavar="CAMERA=PATH",
              help="Board image, video or image folder of a camera (repeatable); default SESSION/extrinsics/<camera>.*")
@click.option("--points", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Scene calibration instead of a board: a YAML file with 'points' (name: [x, y, z], metres, z up, "
                   "floor z = 0; at least 4) and 'pixels' (camera: {name: [u, v], or null where not seen}).")
@click.option("--video-step", type=_STEP, default=1, show_default=True, help="Read every n-th video frame.")
@click.option("--no-adjust", is_flag=True, help="Skip the joint refinement (bundle adjustment).")
@click.option("--max-error", type=_POSITIVE, default=MAX_ERROR_PX, show_default=True,
              help="Largest reprojection RMS (px) of a camera for calibration.toml to be written.")
@handle_errors
def extrinsics_cmd(session, board_size, square, charuco, marker, dictionary, intrinsics_files, views_opt, points, video_step, no_adjust, max_error):
    """Place every camera in the floor frame (metres, z up, floor z = 0) and write calibration.toml
    (an existing one is kept as calibration.toml.bak, or .bak2, .bak3... when that exists). Nothing
    is written when fewer than two cameras are calibrated or a camera's reprojection RMS is above
    --max-error (with --points, its worst points are named).

    With a board lying on the floor: origin at its first corner, x along its rows. With --points:
    the frame of the given coordinates.

    \b
    Example:
        gaitcap calibrate extrinsics sessions/walk01 --board 9x6 --square 120mm --intrinsics cams.toml \\
            --views cam1=floor/cam1.png --views cam2=floor/cam2.png
        gaitcap calibrate extrinsics sessions/walk01 --points scene_points.yaml
    """
    target = session / CALIBRATION_FILE
    cams: list[Camera] = []
    carried: dict[str, dict] = {}  # the intrinsics' own quality (calibrate intrinsics' [metadata]), kept
    for f in intrinsics_files or [target]:
        read = read_cameras(f)
        cams.extend(read)
        _carry_intrinsics_quality(f, [c.name for c in read], carried)
    if points is not None:
        scene = load_yaml_model(ext.ScenePoints, points)
        res = ext.calibrate_from_points(cams, scene, str(points))
    else:
        board = make_board(board_size, square, charuco, marker, dictionary)
        given = {}
        for item in views_opt:
            if "=" not in item:
                raise click.BadParameter(f"{item!r}: expected CAMERA=PATH", param_hint="--views")
            k, v = item.split("=", 1)
            given[k] = Path(v)
        unknown = sorted(set(given) - {c.name for c in cams})
        if unknown:
            raise click.BadParameter(f"unknown camera(s) {', '.join(unknown)}", param_hint="--views")
        frames = {}
        for cam in cams:
            where = given.get(cam.name) or _default_views(session, cam.name)
            vs = detect_views([where], board, video_step=video_step)
            if not vs.detections:  # named here: the solver knows the camera, not the file
                raise CalibrationError(f"{where}: camera {cam.name!r}: the {board.describe()} is not found in any of "
                                       f"its {len(vs.frames)} view(s)")  # fmt: skip
            if vs.image_size != cam.size:
                raise InputError(f"camera {cam.name!r}: board views are {vs.image_size[0]}x{vs.image_size[1]}, "
                                 f"its intrinsics are for {cam.width}x{cam.height}")
            frames[cam.name] = vs.frames
        res = ext.calibrate_from_board(cams, frames, board, adjust=not no_adjust)
    for cam in res.rig:
        c = cam.center
        click.echo(f"{cam.name}: position {c[0]:.3f} {c[1]:.3f} {c[2]:.3f} m, reprojection RMS {res.rms_px[cam.name]:.3f} px")
    if np.isfinite(res.check_mm):
        click.echo(f"3D check: {res.check_mm:.2f} mm RMS ({res.method}, {res.n_positions} position(s), "
                   f"adjusted={res.adjusted})")  # fmt: skip
    _refuse_poor_extrinsics(res, target, max_error, scene if points is not None else None)
    kept = keep_previous(target)
    write_calibration(target, res.rig, {**res.metadata(), **carried})
    click.echo(f"wrote {target}" + (f" (the previous one kept as {kept.name})" if kept else ""))


def _carry_intrinsics_quality(path: Path, names: list[str], carried: dict[str, dict]) -> None:
    """Add the ``intrinsics_*`` tables of a gaitcap calibration file's ``[metadata]`` (its cameras
    ``names``) to ``carried``, so that ``calibrate check`` still sees the intrinsics' error."""
    if path.suffix.lower() != ".toml":
        return
    for key, table in read_calibration_metadata(path).items():
        if key.startswith("intrinsics_") and isinstance(table, dict):
            carried.setdefault(key, {}).update({n: v for n, v in table.items() if n in names})


def _refuse_poor_extrinsics(res: ext.ExtrinsicsResult, target: Path, max_error: float,
                            scene: ext.ScenePoints | None) -> None:  # fmt: skip
    """Refuse to write a result of fewer than two cameras, or with a camera's reprojection RMS above
    ``max_error`` px (with ``scene``, each such camera's worst points named, each point's error taken
    against the pose of the points that agree: :func:`gaitcap.calibration.extrinsics.scene_point_errors`)."""
    if len(res.rig) < 2:
        raise CalibrationError(f"{target}: not written: only {', '.join(res.rig.names)} calibrated; tracking needs "
                               "two or more cameras (give every camera's intrinsics)")  # fmt: skip
    poor = {name: rms for name, rms in res.rms_px.items() if rms > max_error}
    if not poor:
        return
    residuals = ext.scene_point_errors(res.rig, scene) if scene is not None else {}
    lines = []
    for name, rms in poor.items():
        worst = sorted(residuals.get(name, {}).items(), key=lambda item: -item[1])[:3]
        lines.append(f"camera {name!r}: reprojection RMS {rms:.2f} px > {max_error:g} px"
                     + (" (worst points, each against the pose the points that agree give: "
                        + ", ".join(f"{n} {d:.1f} px" for n, d in worst) + ")" if worst else ""))
    raise CalibrationError(f"{target}: not written: a poor calibration:\n  " + "\n  ".join(lines)
                           + "\n  check those points' pixels (or the board views), or give --max-error to accept it")


@command.command("stereo")
@click.argument("left", nargs=1, type=click.Path(path_type=Path))
@click.argument("right", nargs=1, type=click.Path(path_type=Path))
@board_options
@click.option("--fix-aspect-ratio", is_flag=True, help="Force fx = fy for each camera.")
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True, help="calibration.toml of the pair.")
@click.option("--max-error", type=_POSITIVE, default=MAX_ERROR_PX, show_default=True,
              help="Largest stereo reprojection RMS (px) for the result to be written.")
@force_option
@handle_errors
def stereo_cmd(left, right, board_size, square, charuco, marker, dictionary, fix_aspect_ratio, output, max_error, force):
    """Calibrate a synchronised pair: intrinsics of each, then their relative pose (LEFT is the frame).

    LEFT and RIGHT are folders (or videos) of views taken together: paired by the number in their
    names (left05.jpg with right05.jpg; a video's frame index), or in order when they have none.

    \b
    Example:
        gaitcap calibrate stereo pairs/left pairs/right --board 9x6 --square 25mm -o stereo.toml
    """
    check_new(output, force)
    if left.resolve() == right.resolve():
        raise click.BadParameter(f"{left}: given as both LEFT and RIGHT", param_hint="RIGHT")
    board = make_board(board_size, square, charuco, marker, dictionary)
    vl, vr = detect_views([left], board), detect_views([right], board)
    pairs = paired_views(vl, vr)  # before the intrinsics: a missing partner is named at once
    cl = calibrate_intrinsics(vl.detections, board, "left", fix_aspect_ratio).camera
    cr = calibrate_intrinsics(vr.detections, board, "right", fix_aspect_ratio).camera
    res = ext.calibrate_stereo(cl, cr, pairs, board)
    click.echo(f"{res.n_pairs} pairs: RMS {res.rms_px:.4f} px, baseline {res.baseline_m * 1000:.2f} mm, "
               f"mean epipolar error {res.epipolar_px:.4f} px")
    if res.rms_px > max_error:
        raise CalibrationError(f"{output}: not written: stereo reprojection RMS {res.rms_px:.2f} px > {max_error:g} px "
                               "(are the views paired right? give --max-error to accept it)")  # fmt: skip
    write_cameras(output, res.rig, {"error": round(res.rms_px, 4), "baseline_m": res.baseline_m,
                                    "epipolar_px": res.epipolar_px}, force)
    click.echo(f"wrote {output}")


def _frame_sizes(session: Path, names: list[str]) -> dict[str, tuple[int, int]]:
    sizes = {}
    for name, path in find_per_camera(session / VIDEOS_DIR, names, VIDEO_EXTENSIONS, required=False).items():
        cap = cv2.VideoCapture(str(path))
        ok, frame = cap.read()
        cap.release()
        if ok:
            sizes[name] = (frame.shape[1], frame.shape[0])
    return sizes


@command.command("check")
@click.argument("target", type=click.Path(path_type=Path, exists=True))
@click.option("--max-error", type=_POSITIVE, default=MAX_ERROR_PX, show_default=True, help="Largest acceptable reprojection RMS, px.")
@handle_errors
def check_cmd(target, max_error):
    """Print each camera's intrinsics, position, the distances between cameras and the
    reprojection summary; exit with code 1 when the calibration is poor.

    TARGET is a session folder or a calibration file.

    \b
    Example:
        gaitcap calibrate check sessions/walk01
    """
    path = target / CALIBRATION_FILE if target.is_dir() else target
    if path.name.lower().endswith(".toml"):
        rig, meta = read_calibration(path), read_calibration_metadata(path)
    else:
        rig, meta = CameraRig(tuple(read_cameras(path))), {}
    sizes = _frame_sizes(target, rig.names) if target.is_dir() else {}
    rep = check_rig(rig, meta, sizes, max_error)
    if target.is_dir() and len(rig) < 2:
        rep.problems.append(f"one camera ({rig.names[0]}): tracking needs two or more")
    click.echo(f"{path}: {len(rig)} camera(s)")
    for line in rep.lines:
        click.echo(line)
    for note in rep.notes:
        click.echo(f"note: {note}")
    if not rep.ok:
        raise CalibrationError(f"{path}: poor calibration:\n  " + "\n  ".join(rep.problems))
    click.echo("calibration OK")


@command.command("import-qualisys")
@click.argument("qca", type=click.Path(path_type=Path, dir_okay=False))
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True, help="calibration.toml to write.")
@force_option
@handle_errors
def import_qualisys_cmd(qca, output, force):
    """Convert a Qualisys .qca.txt calibration to calibration.toml (metres, lab frame).

    \b
    Example:
        gaitcap calibrate import-qualisys Calib.qca.txt -o sessions/demo/calibration.toml
    """
    rig = read_qualisys(qca)
    write_cameras(output, rig, {"source": str(qca.name), "error": -1.0}, force)  # -1: not measured here
    click.echo(f"{len(rig)} cameras ({', '.join(rig.names)}) -> {output}")


@command.command("import-opencv")
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path, dir_okay=False))
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True, help="calibration.toml to write.")
@force_option
@handle_errors
def import_opencv_cmd(files, output, force):
    """Gather OpenCV YAML/XML camera files (one camera each) into calibration.toml.

    \b
    Example:
        gaitcap calibrate import-opencv left_intrinsics.yml right_intrinsics.yml -o calibration.toml
    """
    rig = CameraRig(tuple(read_opencv_camera(f) for f in files))
    errors = {cam.name: e for cam, f in zip(rig, files) if (e := read_opencv_error(f)) is not None}
    write_cameras(output, rig, {"error": -1.0, **({"intrinsics_rms_px": errors} if errors else {})},
                  force)  # -1: the extrinsics not measured here; the files' own errors kept  # fmt: skip
    click.echo(f"{len(rig)} camera(s) -> {output}")


@command.command("export")
@click.argument("calibration", type=click.Path(path_type=Path, dir_okay=False))
@click.option("-o", "--output", type=click.Path(path_type=Path, file_okay=False), required=True, help="Folder to write.")
@click.option("--format", "fmt", type=click.Choice(["yml", "xml", "toml"]), default="yml", show_default=True)
@force_option
@handle_errors
def export_cmd(calibration, output, fmt, force):
    """Write a calibration (.toml, .yml, .xml, .qca.txt) as one OpenCV file per camera or as calibration.toml.

    \b
    Example:
        gaitcap calibrate export sessions/walk01/calibration.toml -o opencv/ --format yml
    """
    rig = CameraRig(tuple(read_cameras(calibration)))
    meta = read_calibration_metadata(calibration) if calibration.suffix == ".toml" else {}
    targets = [output / CALIBRATION_FILE] if fmt == "toml" else [output / f"{c.name}.{fmt}" for c in rig]
    for t in targets:
        refuse_existing(t, force)
    if fmt == "toml":
        write_calibration(targets[0], rig, meta)
    else:
        for cam, t in zip(rig, targets):  # each camera's own error, none when not measured (not 0)
            error = camera_error(meta, cam.name)
            write_opencv_camera(t, cam, {} if error is None else {"avg_reprojection_error": error})
    for t in targets:
        click.echo(f"wrote {t}")
