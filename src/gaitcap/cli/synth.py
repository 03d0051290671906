"""``gaitcap synth``: render a synthetic session from a real marker-based walk."""

from __future__ import annotations

import logging
from pathlib import Path

import click

from gaitcap.cli.options import (FiniteFloatRange, force_option, handle_errors, mapping_option, seed_option,
                                 static_option, subject_option)  # fmt: skip
from gaitcap.data import embedded_walk
from gaitcap.io.video_write import CODECS
from gaitcap.synth.session import SynthOptions, synthesize

log = logging.getLogger("gaitcap")


#: the sides --size takes, pixels (beyond, the frames and masks held while rendering fill the memory)
SIZE_RANGE = (64, 8192)

#: the highest --fps (a walk of a few seconds at 1e9 fps asked for terabytes and was killed)
MAX_FPS = 1000.0


def parse_size(_ctx: click.Context, _param: click.Parameter, value: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in value.lower().split("x"))
    except ValueError:
        raise click.BadParameter(f"{value!r}: expected WIDTHxHEIGHT, e.g. 640x480") from None
    lo, hi = SIZE_RANGE
    if not (lo <= w <= hi and lo <= h <= hi):
        raise click.BadParameter(f"{value!r}: width and height must be {lo} to {hi} pixels")
    if w % 2 or h % 2:  # the codecs drop an odd last row or column: videos, calibration and masks would differ
        raise click.BadParameter(f"{value!r}: width and height must be even (video codecs need them so)")
    return w, h


def parse_floats(_ctx: click.Context, _param: click.Parameter, value: str | None) -> tuple[float, ...] | None:
    if value is None:
        return None
    try:
        return tuple(float(v) for v in value.split(","))
    except ValueError:
        raise click.BadParameter(f"{value!r}: expected comma-separated numbers, e.g. 90,-45") from None


@click.command("synth")
@click.argument("motion", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", "out", required=True, type=click.Path(path_type=Path), help="Session folder to create.")
@click.option("--cameras", default=2, show_default=True, type=click.IntRange(1, 8), help="Number of cameras.")
@click.option("--size", default="640x480", show_default=True, callback=parse_size, help="Image size WIDTHxHEIGHT, pixels.")
@click.option("--fps", default=25.0, show_default=True, type=FiniteFloatRange(1, MAX_FPS), help="Video frame rate, frames per second.")
@click.option("--shadow/--no-shadow", default=True, show_default=True, help="Cast the lights' shadows on the floor.")
@click.option("--distortion/--no-distortion", default=True, show_default=True, help="Lens distortion (drawn per seed).")
@click.option("--azimuths", default=None, callback=parse_floats,
              help="Camera azimuths in degrees from the walking direction (left positive), e.g. 90,-45 "
                   "(default: a layout drawn from the seed).")
@click.option("--height", "height_m", type=FiniteFloatRange(0.5, 2.6, min_open=True, max_open=True), default=None,
              help="The recorded subject's height (m) when the motion file has none.")
@click.option("--subject-height", "subject_height_m", type=FiniteFloatRange(0.8, 2.2), default=None,
              help="Scale the walk to a subject of this height (m), e.g. 1.1 for a child.")
@click.option("--codec", default="mp4v", show_default=True, type=click.Choice(sorted(CODECS)),
              help="mp4v (.mp4, lossy), ffv1 (.mkv, lossless) or mjpg (.avi).")
@mapping_option
@subject_option
@static_option
@seed_option
@force_option
@click.pass_context
@handle_errors
def command(ctx: click.Context, motion: Path | None, out: Path, cameras: int, size: tuple[int, int], fps: float,
            shadow: bool, distortion: bool, azimuths: tuple[float, ...] | None, height_m: float | None,
            subject_height_m: float | None, codec: str, mapping: str | None, subject: str | None,
            static: Path | None, seed: int, force: bool) -> None:
    """Render a synthetic session with ground truth from a real walk (C3D or TRC).

    MOTION defaults to the embedded Plug-in-Gait walk. The person (build, clothes, skin, hair),
    the room, the lights and the camera placement are drawn from --seed, so that seeds give
    different sessions; the person is a mannequin of its own, not gaitcap's tracking model. The
    session gets calibration.toml, videos/, background/, session.yaml and truth.h5 (true joint
    centres, events, masks, and the drawn conditions).

    \b
    Example:
        gaitcap synth -o sessions/demo
        gaitcap synth subject01_walk1.trc -o sessions/opensim --cameras 3 --seed 7 --subject-height 1.2
    """
    if azimuths is not None and len(azimuths) != cameras:
        raise click.BadParameter(f"{len(azimuths)} azimuths for {cameras} cameras", param_hint="--azimuths")
    options = SynthOptions(
        cameras=cameras, size=size, fps=fps, shadow=shadow, distortion=distortion, azimuths_deg=azimuths,
        codec=codec, seed=seed, height_m=height_m, subject_height_m=subject_height_m,
    )  # fmt: skip
    result = synthesize(motion or embedded_walk(), out, options, force=force, progress=not ctx.obj.get("quiet"),
                        mapping=mapping, subject=subject, static=static)  # fmt: skip
    residual = {k: round(v * 1000, 1) for k, v in result.fit.residual_m.items()}
    log.info("session %s: %d frames x %d cameras (%s)", result.session, result.n_frames, len(result.cameras),
             ", ".join(result.cameras))
    log.info("body fit residual to the marker joint centres (mm): %s", residual)
    log.info("drawn conditions: %s", ", ".join(f"{k} {v}" for k, v in result.look.describe().items()))
