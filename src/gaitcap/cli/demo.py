"""``gaitcap demo``: the whole pipeline on the embedded walk (synth -> track -> eval -> report)."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import click

from gaitcap.cli.options import handle_errors
from gaitcap.track_summary import format_verdict


def _f(v: float | None, digits: int = 1) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{v:.{digits}f}"


@click.command("demo")
@click.option("-o", "--output", "out", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Folder for the demo (default: a new temporary folder, kept afterwards).")
@click.option("--max-frames", type=click.IntRange(min=1), default=None,
              help="Track only the first N frames (a quicker, partial demo).")
@click.pass_context
@handle_errors
def command(ctx: click.Context, out: Path | None, max_frames: int | None) -> None:
    """Run the pipeline end to end on the embedded Plug-in-Gait walk.

    Renders a synthetic 2-camera session from the real walk (gaitcap synth), tracks it with the
    default settings (gaitcap track), compares the result with the ground truth (gaitcap eval)
    and writes the gait report (gaitcap report), printing the main errors and where each result
    is. Takes about half a minute on two cores. Exit code 1 when the tracking's verdict is failed.

    \b
    Example:
        gaitcap demo
        gaitcap demo -o /tmp/gaitcap-demo
    """
    from gaitcap.demo import run_demo

    root = out or Path(tempfile.mkdtemp(prefix="gaitcap-demo-"))
    r = run_demo(root, max_frames=max_frames, progress=not ctx.obj.get("quiet"))
    ev = r.evaluation
    lower = ev.positions.get("lower_limb") or {}
    knee = [ev.angles_rmse_deg.get(f"knee_flexion_{s}") for s in "lr"]
    e = ev.events or {}
    p = r.report.analysis.parameters
    click.echo(f"tracked {r.track.n_frames} frames ({r.track.n_flagged} flagged) in {r.track.seconds:.0f} s; "
               f"verdict: {format_verdict(r.track.verdict, r.track.verdict_reasons)}")
    click.echo(f"lower-limb MPJPE {_f(lower.get('mpjpe_mm'))} mm; knee flexion RMSE left {_f(knee[0])} deg, "
               f"right {_f(knee[1])} deg")  # fmt: skip
    if e:
        click.echo(f"gait events: {e['n_matched']} of {e['n_reference']} matched, |error| mean "
                   f"{_f(e['mean_abs_ms'], 0)} ms, max {_f(e['max_abs_ms'], 0)} ms")  # fmt: skip
    else:
        click.echo("gait events: not compared (" + ("; ".join(ev.notes) or "no gait analysis") + ")")
    if not p.ok:
        click.echo(f"gait report: {p.reason}")
    click.echo(f"session: {r.session}")
    click.echo(f"tracking: {r.track.out}")
    click.echo(f"evaluation: {r.eval_path}")
    click.echo(f"report: {r.report_html}")
    if r.track.verdict == "failed":  # a smoke test that did not track the subject fails
        click.echo("Error: the demo's tracking verdict is failed", err=True)
        raise SystemExit(1)
