"""``cached_njit``: numba's ``njit`` with its on-disk cache, and the package's own cache used even
where the package's folder is read-only.

numba looks for a writable place for a cached function's cache when the function is decorated: the
package's ``__pycache__`` (where ``pip install .`` ships the kernels compiled by the wheel's build,
:mod:`gaitcap.tracking.precompile`), else ``NUMBA_CACHE_DIR``'s or the user-wide cache folder (under
HOME), and raises RuntimeError when there is none. It reads a cache only where it can write, so a
read-only install (a site-wide one, a read-only container) would compile every kernel again (about
25 s) although the package holds them:

- when numba picks a folder other than the package's, the package's entries of the function are
  copied there first (when that folder has none, or older ones than the package's), so the first
  run compiles nothing when they match (the same CPU, numba and Python);
- when numba finds no writable folder at all (read-only package, no writable HOME, no
  ``NUMBA_CACHE_DIR``), a private temporary folder of this process takes the copies instead, and is
  removed at exit: what matches is loaded, what is compiled cannot be kept, and a warning at exit
  says how many kernels were compiled and names NUMBA_CACHE_DIR (a warning at once when no temporary
  folder can be made either: then every kernel compiles at every run).
"""

from __future__ import annotations

import atexit
import glob
import inspect
import logging
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba
from numba import njit

log = logging.getLogger(__name__)
_warned: set[str] = set()
#: the private cache folder of this process, when numba has no writable one ("" until needed)
_private_dir: str = ""
#: the kernels cached in the private folder (their compilations are reported at exit)
_private_kernels: list[Any] = []


def cached_njit(**options: Any) -> Callable[[Callable], Callable]:
    """``numba.njit(cache=True, **options)``, reading the package's shipped cache wherever numba
    keeps it (see the module's doc); ``cache=False`` when no folder at all can be written."""

    def decorate(func: Callable) -> Callable:
        try:
            kernel = njit(cache=True, **options)(func)
        except RuntimeError as e:  # "cannot cache function ...: no locator available"
            kernel = _with_private_cache(func, options)
            if kernel is None:
                if func.__module__ not in _warned:
                    _warned.add(func.__module__)
                    log.warning("%s: numba has no writable cache folder (%s); its kernels compile at every run "
                                "(set NUMBA_CACHE_DIR to a writable folder to keep them)", func.__module__, e)  # fmt: skip
                return njit(cache=False, **options)(func)
        _seed_from_package(kernel, func)
        return kernel

    return decorate


def _with_private_cache(func: Callable, options: dict[str, Any]) -> Any:
    """``njit(cache=True)`` of ``func`` cached in this process's private temporary folder, or None
    when that cannot be made or used."""
    global _private_dir
    try:
        if not _private_dir:
            _private_dir = tempfile.mkdtemp(prefix="gaitcap-numba-")
            atexit.register(_report_private_cache)
        config: Any = numba.config
        saved = config.CACHE_DIR
        config.CACHE_DIR = _private_dir  # read when the function is decorated, for it alone
        try:
            kernel = njit(cache=True, **options)(func)
        finally:
            config.CACHE_DIR = saved
    except (OSError, RuntimeError):
        return None
    _private_kernels.append(kernel)
    return kernel


def _report_private_cache() -> None:
    """At exit: say what was compiled and not kept (the private folder), then remove the folder."""
    compiled = sorted({f"{k.py_func.__module__}.{k.__name__}" for k in _private_kernels if _cache_misses(k)})
    if compiled:
        log.warning("numba had no writable cache folder (the package's is read-only, HOME's not writable): "
                    "%d kernels compiled this run and will compile again at the next (%s); set NUMBA_CACHE_DIR "
                    "to a writable folder to keep them", len(compiled), ", ".join(compiled))  # fmt: skip
    shutil.rmtree(_private_dir, ignore_errors=True)


def _cache_misses(kernel: Any) -> int:
    try:
        return sum(kernel.stats.cache_misses.values())
    except AttributeError:
        return 0


def _seed_from_package(kernel: Any, func: Callable) -> None:
    """Copy the package's cache entries of ``func`` (``__pycache__`` beside its source) into the folder
    numba chose for it, when that is another folder holding none of them or older ones."""
    try:
        target = Path(kernel._cache._cache_path)
        index_name = kernel._cache._cache_file._index_name
    except AttributeError:  # another numba's internals: numba's own cache only
        return
    shipped = Path(inspect.getfile(func)).parent / "__pycache__"
    src_index = shipped / index_name
    try:
        if not src_index.is_file() or target.resolve() == shipped.resolve():
            return
        dst_index = target / index_name
        if dst_index.is_file() and dst_index.stat().st_mtime >= src_index.stat().st_mtime:
            return
        data = sorted(shipped.glob(glob.escape(index_name[: -len(".nbi")]) + ".*.nbc"))
        for src in [*data, src_index]:  # the index last: it refers to the data files
            fd, tmp = tempfile.mkstemp(dir=target, prefix=".seed-")
            try:
                with os.fdopen(fd, "wb") as out, src.open("rb") as inp:
                    shutil.copyfileobj(inp, out)
                os.replace(tmp, target / src.name)
            except BaseException:
                Path(tmp).unlink(missing_ok=True)
                raise
    except OSError as e:  # numba compiles at first use as it would have
        log.debug("%s: the package's numba cache not copied to %s: %s", func.__module__, target, e)
