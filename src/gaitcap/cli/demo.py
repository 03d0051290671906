"""``gaitcap demo``: the whole pipeline, as far as it goes today, on the embedded walk."""

from __future__ import annotations

import logging
import tempfile
from pathlib import Path

import click

from gaitcap.cli.options import handle_errors
from gaitcap.data import embedded_walk
from gaitcap.synth.checks import truth_inside_masks
from gaitcap.synth.session import SynthOptions, synthesize

log = logging.getLogger("gaitcap")


@click.command("demo")
@click.option("-o", "--output", "out", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Folder for the demo (default: a new temporary folder, kept afterwards).")
@click.pass_context
@handle_errors
def command(ctx: click.Context, out: Path | None) -> None:
    """Run the pipeline end to end on the embedded Plug-in-Gait walk.

    Renders a synthetic 2-camera session from the real walk (gaitcap synth) and runs every
    stage that exists after it, printing where the results are.

    \b
    Example:
        gaitcap demo
        gaitcap demo -o /tmp/gaitcap-demo
    """
    root = out or Path(tempfile.mkdtemp(prefix="gaitcap-demo-"))
    session = root / "session"
    log.info("1/1 synth: rendering a 2-camera session from %s", embedded_walk().name)
    result = synthesize(embedded_walk(), session, SynthOptions(), force=True, progress=not ctx.obj.get("quiet"))
    inside = truth_inside_masks(session)
    log.info("    %d frames x %d cameras; truth points inside the rendered silhouettes: %s", result.n_frames,
             len(result.cameras), ", ".join(f"{k} {100 * v:.1f} %" for k, v in inside.items()))
    log.info("stopped after synth: silhouettes, tracking and the gait report are not available yet")
    click.echo(f"session: {session}")
