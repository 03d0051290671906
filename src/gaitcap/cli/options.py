"""Options and helpers shared by several commands."""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click

from gaitcap.errors import GaitcapError

F = TypeVar("F", bound=Callable[..., Any])

log = logging.getLogger("gaitcap")


def handle_errors(func: F) -> F:
    """Turn gaitcap's typed errors into one clear message and exit code 1 (Click uses 2 for usage); a
    Ctrl-C that a compiled kernel wrapped (numba raises ``SystemError`` from the ``KeyboardInterrupt``)
    into the interruption it is, which Click reports as "Aborted!"."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except GaitcapError as e:
            raise click.ClickException(str(e)) from e
        except SystemError as e:
            if isinstance(e.__cause__ or e.__context__, KeyboardInterrupt):
                raise KeyboardInterrupt from None
            raise

    return wrapper  # type: ignore[return-value]


class FiniteFloatRange(click.FloatRange):
    """A float option in a range that also refuses NaN and infinities: ``nan`` passes Click's own
    bound checks (every comparison with it is false), so ``--height nan`` or ``--max-mpjpe-mm nan``
    (a threshold that can never be exceeded) went through as values."""

    name = "float range"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        return number


def force_option(func: F) -> F:
    return click.option("--force", is_flag=True, help="Overwrite existing outputs.")(func)


def mapping_option(func: F) -> F:
    """``--mapping``: a shipped marker mapping name or a mapping YAML (for .c3d/.trc inputs)."""
    return click.option("--mapping", "mapping", default=None, metavar="NAME|FILE.yaml",
                        help="Marker mapping for a .c3d/.trc input: a shipped name or your own YAML "
                             "(default: the shipped mapping that fits; see `gaitcap markers FILE`).")(func)  # fmt: skip


def subject_option(func: F) -> F:
    """``--subject``: which subject of a marker file holding several (label prefix)."""
    return click.option("--subject", default=None, metavar="NAME",
                        help="Subject of a marker file with several (label prefix, e.g. A22; "
                             "default: the one with the most markers).")(func)  # fmt: skip


def static_option(func: F) -> F:
    """``--static``: the static trial of a marker file whose mapping needs one."""
    return click.option("--static", "static", default=None, metavar="FILE",
                        type=click.Path(exists=True, dir_okay=False, path_type=Path),
                        help="The static trial of a .c3d/.trc input whose mapping needs one (its cluster rules; "
                             "default: the file the mapping names beside it, e.g. *_static.trc).")(func)  # fmt: skip


def seed_option(func: F) -> F:
    return click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True, help="Random seed.")(func)
