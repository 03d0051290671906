"""``cached_njit``: numba's ``njit`` with its on-disk cache, or without it where it cannot be kept.

numba looks for a writable place for a cached function's cache when the function is decorated
(the package's ``__pycache__``, else its user-wide cache folder) and raises RuntimeError when there
is none: a read-only install used by an account without a writable home would fail on import.
Then the kernels are compiled at every run instead (logged once per module)."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from numba import njit

log = logging.getLogger(__name__)
_warned: set[str] = set()


def cached_njit(**options: Any) -> Callable[[Callable], Callable]:
    """``numba.njit(cache=True, **options)``, falling back to ``cache=False`` when numba finds no
    writable cache folder."""

    def decorate(func: Callable) -> Callable:
        try:
            return njit(cache=True, **options)(func)
        except RuntimeError as e:  # "cannot cache function ...: no locator available"
            if func.__module__ not in _warned:
                _warned.add(func.__module__)
                log.warning("%s: numba has no writable cache folder (%s); its kernels compile at every run",
                            func.__module__, e)  # fmt: skip
            return njit(cache=False, **options)(func)

    return decorate
