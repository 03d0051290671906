"""The ``gaitcap`` command group."""

from __future__ import annotations

import importlib
import logging

import click

from gaitcap import __version__


class _ClickHandler(logging.Handler):
    """Log records to stderr through Click, so CliRunner captures them."""

    def emit(self, record: logging.LogRecord) -> None:
        prefix = "" if record.levelno == logging.INFO else f"{record.levelname.lower()}: "
        click.echo(prefix + record.getMessage(), err=True)


def _setup_logging(verbose: int, quiet: bool) -> None:
    level = logging.WARNING if quiet else (logging.DEBUG if verbose else logging.INFO)
    logger = logging.getLogger("gaitcap")
    logger.handlers[:] = [_ClickHandler()]
    logger.setLevel(level)
    logger.propagate = False


class _LazyGroup(click.Group):
    """The commands of :data:`COMMAND_MODULES`, each module imported when its command is looked up:
    ``gaitcap track`` does not import what synth, calibrate or report need (scipy.optimize, the
    renderer, matplotlib), and ``gaitcap --help`` only the command modules (which defer their own
    heavy imports to the command's body)."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMAND_MODULES)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in self.commands and name in COMMAND_MODULES:
            self.add_command(importlib.import_module(f"gaitcap.cli.{name}").command, name)
        return self.commands.get(name)


@click.group(cls=_LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", prog_name="gaitcap")
@click.option("-v", "--verbose", count=True, help="More detail (repeat for debug output).")
@click.option("-q", "--quiet", is_flag=True, help="Only warnings and errors.")
@click.pass_context
def cli(ctx: click.Context, verbose: int, quiet: bool) -> None:
    """Markerless 3D gait analysis from two or more calibrated cameras.

    \b
    Example:
        gaitcap demo
        gaitcap synth walk.c3d -o sessions/walk01
    """
    ctx.ensure_object(dict)
    ctx.obj["quiet"] = quiet
    _setup_logging(verbose, quiet)


# the command modules (gaitcap.cli.NAME, each defining ``command``), in the order of the pipeline
COMMAND_MODULES: list[str] = ["calibrate", "markers", "synth", "silhouettes", "track", "report", "eval", "demo"]
