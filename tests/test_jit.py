from __future__ import annotations

import atexit
import importlib.util
import logging
import os
import shutil
from pathlib import Path
from types import ModuleType

import numba
import pytest
from numba.core import caching

from gaitcap import jit

KERNEL_SOURCE = """
from gaitcap.jit import cached_njit


@cached_njit()
def twice(x):
    return 2 * x
"""


def _load(path: Path, name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _refuse(self: object) -> None:
    raise PermissionError(13, "Permission denied (read-only)")


@pytest.fixture
def shipped_package(tmp_path, monkeypatch) -> Path:
    """A module whose kernel is compiled into its package's __pycache__ (as the wheel's build does),
    then that folder made unwritable (numba's in-tree locator refused: the tests run as root, whom
    file modes do not stop), no NUMBA_CACHE_DIR, and the user-wide cache folder under tmp_path."""
    monkeypatch.setattr(numba.config, "CACHE_DIR", "")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "home-cache"))
    monkeypatch.setattr(jit, "_private_dir", "", raising=False)
    monkeypatch.setattr(jit, "_private_kernels", [], raising=False)
    monkeypatch.setattr(atexit, "register", lambda func: None)
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "kernels.py").write_text(KERNEL_SOURCE)
    built = _load(pkg / "kernels.py", f"gaitcap_jit_probe_{tmp_path.name}_build")
    assert built.twice(3) == 6 and sum(built.twice.stats.cache_misses.values()) == 1
    assert list((pkg / "__pycache__").glob("kernels.twice-*.nbc"))
    monkeypatch.setattr(caching.InTreeCacheLocator, "ensure_cache_path", _refuse)
    return pkg


def test_a_read_only_package_loads_its_kernels_through_the_user_cache(shipped_package, tmp_path):
    # found installing the wheel read-only (chmod -R a-w site-packages/gaitcap, run by another
    # account): numba cached in HOME's folder and compiled every kernel there at the first run
    mod = _load(shipped_package / "kernels.py", f"gaitcap_jit_probe_{tmp_path.name}_user")
    assert mod.twice(3) == 6
    stats = mod.twice.stats
    assert Path(stats.cache_path).is_relative_to(tmp_path / "home-cache")
    assert sum(stats.cache_hits.values()) == 1 and not any(stats.cache_misses.values())


def test_no_writable_folder_at_all_still_loads_the_shipped_kernels(shipped_package, tmp_path, monkeypatch, caplog):
    # the same with HOME=/nonexistent: numba had no folder at all, so every kernel compiled at every run
    monkeypatch.setattr(caching.UserWideCacheLocator, "ensure_cache_path", _refuse)
    mod = _load(shipped_package / "kernels.py", f"gaitcap_jit_probe_{tmp_path.name}_private")
    assert mod.twice(3) == 6
    stats = mod.twice.stats
    assert Path(stats.cache_path).is_relative_to(jit._private_dir)
    assert sum(stats.cache_hits.values()) == 1 and not any(stats.cache_misses.values())
    private = jit._private_dir
    with caplog.at_level(logging.WARNING, logger="gaitcap.jit"):
        jit._report_private_cache()
    assert caplog.text == ""  # nothing compiled, nothing to say
    assert not Path(private).exists()


def test_what_compiles_without_a_writable_folder_is_reported_at_exit(shipped_package, tmp_path, monkeypatch, caplog):
    monkeypatch.setattr(caching.UserWideCacheLocator, "ensure_cache_path", _refuse)
    mod = _load(shipped_package / "kernels.py", f"gaitcap_jit_probe_{tmp_path.name}_other")
    assert mod.twice(1.5) == 3.0  # a signature the package did not compile
    with caplog.at_level(logging.WARNING, logger="gaitcap.jit"):
        jit._report_private_cache()
    assert "1 kernels compiled this run" in caplog.text and ".twice" in caplog.text
    assert "NUMBA_CACHE_DIR" in caplog.text


def test_cached_njit_compiles_without_the_cache_when_numba_has_nowhere_to_keep_it(monkeypatch, caplog):
    calls = []

    def njit(**options):
        calls.append(options)
        if options["cache"]:
            raise RuntimeError("cannot cache function 'f': no locator available for file 'f.py'")
        return numba.njit(**options)

    monkeypatch.setattr(jit, "njit", njit)
    monkeypatch.setattr(jit, "_warned", set())
    monkeypatch.setattr(jit, "_private_dir", "", raising=False)
    monkeypatch.setattr(jit, "_private_kernels", [], raising=False)
    monkeypatch.setattr(atexit, "register", lambda func: None)
    with caplog.at_level(logging.WARNING, logger="gaitcap.jit"):
        f = jit.cached_njit(nogil=True)(lambda x: 2 * x)
        g = jit.cached_njit()(lambda x: x + 1)
    assert f(3) == 6 and g(3) == 4
    # the default folders, then a private one, then no cache
    assert [c["cache"] for c in calls] == [True, True, False, True, True, False]
    assert calls[2] == {"cache": False, "nogil": True}
    assert caplog.text.count("no writable cache folder") == 1  # once per module
    assert "NUMBA_CACHE_DIR" in caplog.text
    shutil.rmtree(jit._private_dir, ignore_errors=True)


def test_the_user_cache_is_refreshed_from_a_newer_install_only(shipped_package, tmp_path):
    """An install newer than the user's copy (an upgrade: pip does not keep the files' times) replaces
    it; a copy newer than the install (kernels the user compiled since) is kept."""
    mod = _load(shipped_package / "kernels.py", f"gaitcap_jit_probe_{tmp_path.name}_first")
    shipped = next((shipped_package / "__pycache__").glob("kernels.twice-*.nbi"))
    copy = Path(mod.twice.stats.cache_path) / shipped.name
    assert copy.read_bytes() == shipped.read_bytes()
    copy.write_bytes(b"an older install's")
    os.utime(copy, (shipped.stat().st_mtime - 60,) * 2)
    _load(shipped_package / "kernels.py", f"gaitcap_jit_probe_{tmp_path.name}_upgraded")
    assert copy.read_bytes() == shipped.read_bytes()
    copy.write_bytes(b"the user's own")
    os.utime(copy, (shipped.stat().st_mtime + 60,) * 2)
    _load(shipped_package / "kernels.py", f"gaitcap_jit_probe_{tmp_path.name}_again")
    assert copy.read_bytes() == b"the user's own"
