"""The ``gaitcap`` command group."""

from __future__ import annotations

import atexit
import importlib
import logging
import os
import sys
import threading
from typing import NoReturn

import click

from gaitcap import __version__

# the command line names an unreadable video in its own words (the file, what is wrong); OpenCV's and
# FFmpeg's messages about it ("moov atom not found", a cap.cpp warning) only come before that as noise.
# Set before any command imports OpenCV; a user's own settings of these variables are kept
os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # FFmpeg's AV_LOG_QUIET


class _ClickHandler(logging.Handler):
    """Log records to stderr through Click, so CliRunner captures them. Once stderr is a pipe whose
    reader has gone (``gaitcap track ... 2>&1 | head``), the records are dropped: the command goes on
    and writes its outputs (the console is for reading along, not the run's record)."""

    closed = False

    def emit(self, record: logging.LogRecord) -> None:
        if self.closed:
            return
        prefix = "" if record.levelno == logging.INFO else f"{record.levelname.lower()}: "
        try:
            click.echo(prefix + record.getMessage(), err=True)
        except BrokenPipeError:
            self.closed = True


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


def main(args: list[str] | None = None) -> NoReturn:
    """The ``gaitcap`` program (the console script and ``python -m gaitcap``): :func:`cli`, then the
    process ends without the interpreter's teardown of its modules.

    Freeing numba's, scipy's and OpenCV's modules one object at a time takes 0.3-0.5 s after every
    command (about a fifth of the fixed cost #30 allows a run), and none of it is the command's work:
    every output is already written and renamed (temporary name, then rename). So once the command
    has returned or failed cleanly, and if no thread but daemons is left running, the exit handlers
    run (``atexit``), the logs and the standard streams are flushed, as a normal exit does, and the
    process ends there (``os._exit``) with the command's status. With a thread still running, or an
    error Click does not handle (its traceback), the process exits the normal way.
    """
    try:
        cli.main(args=args, prog_name="gaitcap")  # standalone: always ends in SystemExit
        code: int | str | None = 0
    except SystemExit as done:
        code = done.code
    if any(t is not threading.current_thread() and not t.daemon for t in threading.enumerate()):
        sys.exit(code)  # the normal exit joins them
    _exit_now(code)


def _exit_now(code: int | str | None) -> NoReturn:
    """End the process with ``code`` (SystemExit's meaning: None 0, a text printed and 1) after the
    exit handlers and the flushes that a normal exit does."""
    if isinstance(code, str):
        print(code, file=sys.stderr)
        code = 1
    atexit._run_exitfuncs()
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe or stream: what was left could not be written
            code = code or 1
    os._exit(code or 0)
