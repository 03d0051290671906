"""``gaitcap track``: silhouettes and tracking, for one session or a folder of sessions."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import click

from gaitcap.batch import any_failed, find_sessions, format_summary, is_session, run_batch, write_batch_json
from gaitcap.cli.options import FiniteFloatRange, force_option, handle_errors
from gaitcap.pipeline import TRACKERS, run_track

log = logging.getLogger("gaitcap")


@click.command("track")
@click.argument("source", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("-o", "--output", "out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Output folder (for a folder of sessions: one sub-folder per session).")
@click.option("--tracker", type=click.Choice(sorted(TRACKERS)), default=None,
              help="Override the configuration's tracker (default factored-ipf; ipf and condensation are the "
                   "method's baselines, two to three times less accurate).")
@click.option("-c", "--config", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="Tracking configuration YAML (default: the shipped configs/tracking.yaml).")
@click.option("--silhouette-config", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="Silhouette configuration YAML (default: the shipped configs/silhouette.yaml), as "
                   "`gaitcap silhouettes -c` takes it.")
@click.option("--height", "height_m", type=FiniteFloatRange(0.5, 2.6, min_open=True, max_open=True), default=None,
              help="Subject height in metres (default: session.yaml, else estimated).")
@click.option("--body", type=click.Path(exists=True, path_type=Path), default=None,
              help="Track with the body of an earlier run of the same subject (its output folder, or its "
                   "trajectories.h5): its height and calibrated proportions, without calibrating the shape again. "
                   "Not with --height.")
@click.option("--max-frames", type=click.IntRange(min=1), default=None, help="Track only the first N frames.")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Override the configuration's seed of the tracker's random streams (a run is the same for the "
                   "same seed; another seed draws another run: the spread of the results).")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=1, show_default=True,
              help="Sessions tracked in parallel (folders of sessions).")
@click.option("--scheduler", default=None,
              help="Run the sessions on a Dask cluster: tcp://HOST:8786, or 'local' (needs gaitcap[distributed]).")
@click.option("--save-masks", is_flag=True, default=False,
              help="Also save the full-resolution silhouettes to OUT/silhouettes.h5 (streamed frame by frame; "
                   "gaitcap eval reports their IoU against a truth's masks).")
@force_option
@click.pass_context
@handle_errors
def command(ctx: click.Context, source: Path, out: Path, tracker: str | None, config: Path | None,
            silhouette_config: Path | None, height_m: float | None, body: Path | None, max_frames: int | None,
            seed: int | None,
            jobs: int, scheduler: str | None, save_masks: bool, force: bool) -> None:
    """Track the subject in a session (or every session of a folder).

    Writes OUT/trajectories.h5 (points, per-point uncertainty, poses, likelihood, quality),
    OUT/track.json (with the run's verdict: ok, doubtful or failed, and why),
    OUT/joints.csv (metres, NaN where flagged) and OUT/joints.trc (OpenSim, mm); with --save-masks
    also OUT/silhouettes.h5 (the masks the tracker saw, as gaitcap silhouettes writes them). A folder of
    sessions gives OUT/<session>/..., a log per session and a summary; finished sessions are
    skipped unless --force. The exit code is 1 when a session failed or its run's verdict is
    failed (the outputs are written, to look at, not to use).

    The subject's proportions are calibrated on the first frames of each session; for more clips
    of the same subject, --body OUT1 reuses those of an earlier run (a shorter run: no calibration).

    \b
    Example:
        gaitcap track sessions/walk01 -o results/walk01
        gaitcap track sessions/walk02 -o results/walk02 --body results/walk01
        gaitcap track sessions/ -o results/ --jobs 2
    """
    if body is not None and height_m is not None:  # a usage error (exit 2), before any work
        raise click.UsageError("give --height or --body, not both: the body carries the subject's height")
    quiet = bool(ctx.obj.get("quiet"))
    kwargs = {"config": config, "tracker": tracker, "height_m": height_m, "max_frames": max_frames,
              "save_masks": save_masks, "body": body, "silhouette_config": silhouette_config, "seed": seed}
    if is_session(source) and scheduler is None:
        summary = run_track(source, out, force=force, progress=not quiet, **kwargs)  # logs its verdict and notes
        log.info("%s", summary.message)
        if not quiet:
            click.echo(f"results: {out}")
        if summary.verdict == "failed":  # written for a look, not for use
            click.echo(f"Error: the run's verdict is failed: the results in {out} must not be used", err=True)
            sys.exit(1)
        return
    if quiet:  # -q: no progress bars (in one process the batch shows them by default)
        kwargs["progress"] = False
    summaries = run_batch(find_sessions(source), out, jobs=jobs, force=force, scheduler=scheduler, **kwargs)
    click.echo(format_summary(summaries))
    write_batch_json(out, summaries)
    if any_failed(summaries):
        sys.exit(1)
