"""The prefetch thread of ``gaitcap track``: order, bounded look-ahead, errors, early stop."""

from __future__ import annotations

import threading
import time

import pytest

from gaitcap.errors import InputError
from gaitcap.prefetch import Prefetched


def test_items_come_in_order():
    with Prefetched(iter(range(50)), depth=2) as items:
        assert list(items) == list(range(50))


def test_the_worker_stays_at_most_depth_items_ahead():
    produced = []

    def source():
        for i in range(100):
            produced.append(i)
            yield i

    with Prefetched(source(), depth=2) as items:
        assert next(items) == 0
        time.sleep(0.3)
        # one consumed, two queued, one in the worker's hands waiting for room
        assert len(produced) <= 4


def test_an_error_in_the_worker_is_raised_by_the_consumer_with_its_message():
    def source():
        yield 1
        raise InputError("cam1.avi: decoding failed at frame 1")

    items = Prefetched(source(), depth=2)
    assert next(items) == 1
    with pytest.raises(InputError) as e:
        next(items)
    assert str(e.value) == "cam1.avi: decoding failed at frame 1"
    with pytest.raises(StopIteration):  # finished: no further item, no hang
        next(items)


def test_closing_early_stops_the_worker_and_closes_the_source():
    closed = threading.Event()

    def source():
        try:
            i = 0
            while True:
                yield i
                i += 1
        finally:
            closed.set()

    with Prefetched(source(), depth=2) as items:
        assert next(items) == 0
    assert closed.wait(5.0)
    assert not any(t.name == "gaitcap-prefetch" and t.is_alive() for t in threading.enumerate())


def test_depth_below_one_is_rejected():
    with pytest.raises(ValueError, match="depth must be at least 1, got 0"):
        Prefetched(iter(()), depth=0)
