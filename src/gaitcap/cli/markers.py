"""``gaitcap markers``: which marker mapping fits a .c3d/.trc file, and why (not)."""

from __future__ import annotations

from pathlib import Path

import click

from gaitcap.cli.options import handle_errors, mapping_option, static_option, subject_option


@click.command("markers")
@click.argument("motion", type=click.Path(dir_okay=False, path_type=Path))
@mapping_option
@subject_option
@static_option
@handle_errors
def command(motion: Path, mapping: str | None, subject: str | None, static: Path | None) -> None:
    """Show how gaitcap reads a marker file: the mapping that fits, where each joint centre comes
    from, which markers are missing and why the other mappings do not fit.

    Exit code 0 when the (given or best) mapping fits, 1 when it does not.

    \b
    Example:
        gaitcap markers walk.c3d
        gaitcap markers walk.c3d --mapping my_lab.yaml
    """
    from gaitcap.markers.inspect import describe_file

    text = describe_file(motion, mapping, subject, static)
    click.echo(text)
    if "does NOT fit" in text.splitlines()[1]:
        raise SystemExit(1)
