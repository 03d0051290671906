"""``gaitcap eval``: accuracy of a tracking output against a synthetic truth or another run."""

from __future__ import annotations

from pathlib import Path

import click

from gaitcap.cli.options import force_option, handle_errors

#: exit code when a threshold is exceeded (1, like an error: CI fails either way)
EXIT_THRESHOLD = 1


@click.command("eval")
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--truth", type=click.Path(path_type=Path), default=None,
              help="truth.h5 of a synthetic session (or the session folder holding it).")
@click.option("--reference", type=click.Path(path_type=Path), default=None,
              help="Another tracking output (folder or trajectories.h5) to compare with.")
@click.option("-o", "--output", type=click.Path(path_type=Path), default=None,
              help="Where to write the JSON results (default: OUT/eval.json, or eval.json beside a file).")
@click.option("--max-mpjpe-mm", type=click.FloatRange(min=0), default=None, help="Fail above this MPJPE (all points).")
@click.option("--max-angle-rmse-deg", type=click.FloatRange(min=0), default=None,
              help="Fail when the RMSE of hip/knee flexion or ankle dorsiflexion (either side) is above this.")
@click.option("--max-event-error-frames", type=click.FloatRange(min=0), default=None,
              help="Fail when a gait event of OUT is further than this from the reference's (frames).")
@force_option
@handle_errors
def command(
    out: Path, truth: Path | None, reference: Path | None, output: Path | None,
    max_mpjpe_mm: float | None, max_angle_rmse_deg: float | None, max_event_error_frames: float | None, force: bool,
) -> None:  # fmt: skip
    """Compare the trajectories of OUT with a ground truth (--truth) or another run (--reference).

    Reports position errors (MPJPE over all points, lower limb, heel/toe, per point; frames NaN
    in OUT are flagged and excluded), left/right swaps, joint-angle RMSE, gait event timing and
    gait parameter differences; writes them to OUT/eval.json.

    Exit codes: 0 done (and every threshold given is met); 1 a threshold is exceeded, or an error;
    2 usage.

    \b
    Example:
        gaitcap eval OUT --truth sessions/walk01/truth.h5 --max-mpjpe-mm 40
        gaitcap eval OUT --reference OUT_previous
    """
    from gaitcap.evaluation import Thresholds, check_thresholds, evaluate
    from gaitcap.evaluation.report import (
        EVAL_FILE, format_evaluation, read_tracked, read_truth_trajectory, tracked_path, write_evaluation,
    )  # fmt: skip

    if (truth is None) == (reference is None):
        raise click.UsageError("give exactly one of --truth and --reference")
    tracked = read_tracked(out)
    ref_path = truth if truth is not None else tracked_path(reference)  # type: ignore[arg-type]
    ref = read_truth_trajectory(truth) if truth is not None else read_tracked(reference)  # type: ignore[arg-type]
    ev = evaluate(tracked, ref, out_source=str(tracked_path(out)), reference_source=str(ref_path))
    ev.failures = check_thresholds(ev, Thresholds(max_mpjpe_mm, max_angle_rmse_deg, max_event_error_frames))
    target = output or (out / EVAL_FILE if out.is_dir() else out.parent / EVAL_FILE)
    write_evaluation(target, ev, force=force)
    click.echo(format_evaluation(ev))
    click.echo(f"\nwrote {target}")
    if ev.failures:
        click.echo("threshold exceeded: " + "; ".join(ev.failures), err=True)
        raise SystemExit(EXIT_THRESHOLD)
