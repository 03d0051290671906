"""``gaitcap eval``: accuracy of a tracking output against a synthetic truth or another run."""

from __future__ import annotations

from pathlib import Path

import click

from gaitcap.cli.options import FiniteFloatRange, force_option, handle_errors
from gaitcap.errors import OutputError
from gaitcap.io.atomic import refuse_existing

#: exit code when a threshold is exceeded (an error is 1, a usage error 2: a CI job tells a regression apart)
EXIT_THRESHOLD = 3


@click.command("eval")
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--truth", type=click.Path(path_type=Path), default=None,
              help="A truth folder (joints.csv, optional events.csv, parameters.json, masks.h5: layout above), "
                   "or truth.h5 of a synthetic session (or the session folder holding it).")
@click.option("--reference", type=click.Path(path_type=Path), default=None,
              help="Another tracking output (folder or trajectories.h5) to compare with.")
@click.option("-o", "--output", type=click.Path(path_type=Path), default=None,
              help="Where to write the JSON results (default: OUT/eval.json, or eval.json beside a file).")
@click.option("--max-mpjpe-mm", type=FiniteFloatRange(min=0), default=None, help="Fail above this MPJPE (all points).")
@click.option("--max-lower-limb-mpjpe-mm", type=FiniteFloatRange(min=0), default=None,
              help="Fail above this MPJPE of the lower limb (hips, knees, ankles: the README's accuracy figure).")
@click.option("--max-angle-rmse-deg", type=FiniteFloatRange(min=0), default=None,
              help="Fail when the RMSE of hip/knee flexion or ankle dorsiflexion (either side) is above this.")
@click.option("--max-event-error-frames", type=FiniteFloatRange(min=0), default=None,
              help="Fail when a gait event of OUT is further than this from the reference's (frames), or a "
                   "reference event is not detected. Frames of OUT's rate: 1 frame is 40 ms at 25 fps, 20 ms at "
                   "50 fps; --max-event-error-ms is the same limit at every frame rate.")
@click.option("--max-event-error-ms", type=FiniteFloatRange(min=0), default=None,
              help="As --max-event-error-frames, in milliseconds.")
@click.option("--min-compared-fraction", type=FiniteFloatRange(min=0, max=1), default=None,
              help="Fail when fewer than this fraction (0-1) of OUT's frames are compared (flagged frames, or "
                   "frames the reference does not cover, are not); with --reference, the reference run's frames "
                   "that OUT lacks count as not compared too.")
@click.option("--require-verdict", type=click.Choice(["ok", "doubtful"]), default=None,
              help="Fail when the run's own verdict (track.json) is worse than this, or missing.")
@force_option
@handle_errors
def command(
    out: Path, truth: Path | None, reference: Path | None, output: Path | None,
    max_mpjpe_mm: float | None, max_lower_limb_mpjpe_mm: float | None, max_angle_rmse_deg: float | None,
    max_event_error_frames: float | None, max_event_error_ms: float | None, min_compared_fraction: float | None,
    require_verdict: str | None, force: bool,
) -> None:  # fmt: skip
    """Compare the trajectories of OUT with a ground truth (--truth) or another run (--reference).

    Reports the run's own verdict (OUT's track.json: ok, doubtful or failed, and why), position errors (MPJPE over all points, lower limb, heel/toe, per point; frames NaN
    in OUT are flagged and excluded), left/right swaps, joint-angle RMSE, gait event timing and
    gait parameter differences, and, when OUT holds silhouettes.h5 (gaitcap track --save-masks)
    and the truth has masks, the silhouette IoU per camera; writes them to OUT/eval.json.

    A truth folder is gaitcap's own output formats, so a lab can export its marker-based joint
    centres and check gaitcap against its own system:

    \b
      joints.csv       frame,time_s,<point>_x,<point>_y,<point>_z,... metres, the calibration's
                       world frame (z up), uniform rate, NaN = missing; points named as gaitcap's
                       (pelvis, hip_l, knee_r, ankle_l, heel_r, toe_l, ...)
      events.csv       optional: side,event,frame,time_s (left/right, foot_strike/foot_off)
      parameters.json  optional: {"overall": {...}, "left": {...}, "right": {...}} with the names
                       of gaitcap's parameters.json (cadence_steps_per_min, stride_length_m, ...)
      masks.h5         optional: one dataset per camera, (frames, H, W) uint8 0/1, as many
                       frames as joints.csv has rows

    eval.json also records the thresholds checked ("thresholds": {"max_lower_limb_mpjpe_mm": 40, ...}, the
    options given), those exceeded ("thresholds_failed": one sentence each, with the value, the limit and the
    worst point or event) and whether all passed ("passed": true or false).

    Exit codes: 0 done (and every threshold given is met); 1 an error (a bad truth folder names
    the file; with --force, an earlier eval.json is removed first, so none is left to misread);
    2 usage; 3 a threshold is exceeded (eval.json written).

    \b
    Example:
        gaitcap eval OUT --truth sessions/walk01/truth.h5 --max-lower-limb-mpjpe-mm 40 --require-verdict ok
        gaitcap eval OUT --truth external_sessions/ktk_e/truth
        gaitcap eval OUT --reference OUT_previous
    """
    from gaitcap.evaluation import Thresholds, check_thresholds
    from gaitcap.evaluation.report import (TruthReference, format_evaluation, read_tracked, read_truth_reference,
                                           tracked_path, write_evaluation)  # fmt: skip
    from gaitcap.evaluation.run import evaluate_output
    from gaitcap.track_summary import EVAL_FILE

    if (truth is None) == (reference is None):
        raise click.UsageError("give exactly one of --truth and --reference")
    target = output or (out / EVAL_FILE if out.is_dir() else out.parent / EVAL_FILE)
    if target.is_dir():
        raise OutputError(f"{target}: is a folder; -o names the JSON file to write")
    refuse_existing(target, force)  # before the work, so that no result is computed and then refused
    if force and target.is_file():  # replaced whatever this run gives: never left to pass for its result
        target.unlink()
    if truth is not None:
        ref = read_truth_reference(truth)
    else:
        ref = TruthReference(tracked_path(reference), read_tracked(reference))  # type: ignore[arg-type]
    ev = evaluate_output(out, ref, truth)
    ev.failures = check_thresholds(ev, Thresholds(max_mpjpe_mm, max_angle_rmse_deg, max_event_error_frames,
                                                  max_lower_limb_mpjpe_mm, min_compared_fraction, require_verdict,
                                                  max_event_error_ms))
    write_evaluation(target, ev, force=force)
    click.echo(format_evaluation(ev))
    click.echo(f"\nwrote {target}")
    if ev.failures:
        click.echo("threshold exceeded: " + "; ".join(ev.failures), err=True)
        raise SystemExit(EXIT_THRESHOLD)
    if ev.thresholds:  # one line in a CI's log that says what was checked and passed
        click.echo("thresholds met: " + ", ".join(f"--{k.replace('_', '-')} {v:g}" if isinstance(v, float)
                                                  else f"--{k.replace('_', '-')} {v}" for k, v in ev.thresholds.items()))
