from __future__ import annotations

import logging

import numba

from gaitcap import jit


def test_cached_njit_compiles_without_the_cache_when_numba_has_nowhere_to_keep_it(monkeypatch, caplog):
    calls = []

    def njit(**options):
        calls.append(options)
        if options["cache"]:
            raise RuntimeError("cannot cache function 'f': no locator available for file 'f.py'")
        return numba.njit(**options)

    monkeypatch.setattr(jit, "njit", njit)
    monkeypatch.setattr(jit, "_warned", set())
    with caplog.at_level(logging.WARNING, logger="gaitcap.jit"):
        f = jit.cached_njit(nogil=True)(lambda x: 2 * x)
        g = jit.cached_njit()(lambda x: x + 1)
    assert f(3) == 6 and g(3) == 4
    assert calls == [{"cache": True, "nogil": True}, {"cache": False, "nogil": True}, {"cache": True}, {"cache": False}]
    assert caplog.text.count("no writable cache folder") == 1  # once per module
