"""``gaitcap report``: gait events, parameters, joint angles and an HTML report."""

from __future__ import annotations

import math
from pathlib import Path

import click

from gaitcap.cli.options import handle_errors, mapping_option, static_option, subject_option
from gaitcap.config import load_yaml_model
from gaitcap.gait.options import GaitOptions

#: exit code when the analysis ran but found less than one complete gait cycle
EXIT_NOT_ENOUGH_STEPS = 3
#: exit code when the analysis ran but withheld implausible values
EXIT_IMPLAUSIBLE = 4


@click.command("report")
@click.argument("source", type=click.Path(path_type=Path))
@click.option("-o", "--out", "out_dir", type=click.Path(path_type=Path), default=None,
              help="Output folder (default: SOURCE/gait, or gait/ beside a file).")
@click.option("--config", "config", type=click.Path(path_type=Path), default=None,
              help="YAML file of gait options (see gaitcap.gait.options.GaitOptions).")
@click.option("--session", "session", type=click.Path(path_type=Path), default=None,
              help="The session folder of a tracking run (videos, calibration), for the contact sheet, when it is "
                   "no longer where track.json says.")  # fmt: skip
@mapping_option
@subject_option
@static_option
@click.option("--recorded-events", is_flag=True,
              help="Use the gait events a marker file records (its EVENT group, or its force plates) for the "
                   "parameters, cycles and C3D instead of detecting them.")  # fmt: skip
@handle_errors
def command(source: Path, out_dir: Path | None, config: Path | None, session: Path | None, mapping: str | None,
            subject: str | None, static: Path | None, recorded_events: bool) -> None:  # fmt: skip
    """Gait events, spatio-temporal parameters, joint angles and report.html from trajectories.

    SOURCE is a tracking output folder holding trajectories.h5, a trajectories.h5 file, or a
    marker-based .c3d/.trc file (its joint centres are computed from the markers). For a tracking
    run, report.html opens with the run's verdict (track.json) and shows how the model fits the
    videos: the fit and uncertainty per frame and a contact sheet of video frames with the tracked
    model drawn over them (omitted, with the reason, when the session's videos cannot be read).

    Exit codes: 0 done; 1 error; 2 usage; 3 the analysis ran but found less than one complete gait
    cycle ("not enough steps": parameters.json has status not_enough_steps, the reason, and the
    step-level values it could measure); 4 the analysis ran but values outside their plausible
    range were withheld (status implausible; parameters.json names them under "implausible").

    \b
    Example:
        gaitcap report OUT
        gaitcap report OUT --session sessions/walk01
        gaitcap report walk.c3d -o walk_report
        gaitcap report walk.c3d --mapping my_lab.yaml
        gaitcap report walk.c3d --recorded-events
        gaitcap report subject01_walk1.trc --static subject01_static.trc
    """
    from gaitcap.gait.parameters import STATUS_IMPLAUSIBLE, STATUS_NOT_ENOUGH_STEPS
    from gaitcap.report.pipeline import run_report

    options = load_yaml_model(GaitOptions, config) if config is not None else None
    result = run_report(source, out_dir, options, mapping, subject, session, static, recorded_events)
    if result.verdict is not None:
        click.echo(result.verdict.line())
    p = result.analysis.parameters
    click.echo(f"{len(result.analysis.events)} events, {p.overall['n_strides']} complete cycles -> {result.out_dir}")
    o = p.overall
    click.echo(f"cadence {_value(o['cadence_steps_per_min'], '.1f')} steps/min, speed {_value(o['speed_m_s'], '.2f')} m/s, "
               f"stride {_value(o['stride_length_m'], '.3f')} m, step {_value(o['step_length_m'], '.3f')} m")  # fmt: skip
    if p.status == STATUS_NOT_ENOUGH_STEPS:
        raise SystemExit(EXIT_NOT_ENOUGH_STEPS)
    if p.status == STATUS_IMPLAUSIBLE:
        raise SystemExit(EXIT_IMPLAUSIBLE)


def _value(v: float, fmt: str) -> str:
    """A summary value, or ``-`` where it was not measured or was withheld."""
    return format(v, fmt) if math.isfinite(v) else "-"
