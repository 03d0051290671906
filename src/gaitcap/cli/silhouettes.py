"""``gaitcap silhouettes``: background subtraction of a session's (or plain) videos."""

from __future__ import annotations

import logging
from pathlib import Path

import click

from gaitcap.cli.options import force_option, handle_errors
from gaitcap.silhouette.config import SilhouetteConfig
from gaitcap.silhouette.run import run_silhouettes, sources_from_session, sources_from_videos
from gaitcap.sync_check import SyncRecorder
from gaitcap.video import probe_video

log = logging.getLogger("gaitcap.cli.silhouettes")


@click.command("silhouettes")
@click.argument("session", required=False, type=click.Path(path_type=Path))
@click.option(
    "--video", "videos", multiple=True, type=click.Path(path_type=Path),
    help="A video file or a folder of videos instead of a session (repeatable; no calibration needed).",
)
@click.option("-o", "--out", required=True, type=click.Path(path_type=Path), help="Output folder.")
@click.option("-c", "--config", "config_path", type=click.Path(path_type=Path), help="silhouette.yaml to use.")
@click.option("--png", is_flag=True, help="Also write OUT/silhouettes/<camera>/<frame:06d>.png.")
@click.option("--overlay", is_flag=True, help="Also write OUT/overlay/<camera>.mp4 to look at.")
@click.option("--no-shadow", is_flag=True, help="Turn shadow suppression off (overrides the config).")
@click.option("--max-frames", type=click.IntRange(min=1), help="Only the first N frames of each video.")
@force_option
@handle_errors
def command(
    session: Path | None,
    videos: tuple[Path, ...],
    out: Path,
    config_path: Path | None,
    png: bool,
    overlay: bool,
    no_shadow: bool,
    max_frames: int | None,
    force: bool,
) -> None:
    """Extract the person's silhouette in every frame of every camera.

    Writes OUT/silhouettes.h5 (masks, per-frame quality) and OUT/silhouettes_quality.csv
    (foreground fraction and flags: empty, border, too_large, no_background per frame).
    The background is the session's plate (background/<camera>.png) when there is one,
    else a temporal median of frames sampled across the video.

    \b
    Examples:
        gaitcap silhouettes sessions/walk01 -o out/walk01 --overlay
        gaitcap silhouettes --video walk.mp4 -o out/walk --png
    """
    if session is None and not videos:
        raise click.UsageError("give a SESSION folder or --video files/folders")
    if session is not None and videos:
        raise click.UsageError("give a SESSION folder or --video files/folders, not both")
    config = SilhouetteConfig.load(config_path)
    if no_shadow:
        config.shadow.enabled = False
    sources = sources_from_session(session) if session is not None else sources_from_videos(videos)
    sync = SyncRecorder([s.calibration for s in sources]) if all(s.calibration for s in sources) else None
    summaries = run_silhouettes(sources, out, config, png=png, overlay=overlay, force=force, max_frames=max_frames,
                                on_masks=None if sync is None else sync.add)  # fmt: skip
    if sync is not None and (note := sync.note(probe_video(sources[0].video).fps, {s.camera: s.video for s in sources},
                                                {s.camera: s.skip for s in sources})):  # fmt: skip
        log.warning("%s", note)
    for s in summaries:  # an unusable background was warned about when fitted: named again, not repeated
        flags = ", ".join(f"{k} {v}" for k, v in s.flag_counts.items() if v) or "none"
        usable = "" if s.background.usable else " (unusable: the masks are unreliable, see the warning above)"
        log.log(logging.INFO if s.background.usable else logging.WARNING,
                "%s: %d frames, mean foreground %.2f%%, background from %s%s; flagged frames: %s",
                s.camera, s.frames, 100 * s.mean_fraction, s.background.source, usable, flags)  # fmt: skip
    log.info("wrote %s", out)
