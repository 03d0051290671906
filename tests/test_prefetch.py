"""The prefetch thread of ``gaitcap track``: order, bounded look-ahead, errors, early stop; the head of
first frames read on demand."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from functools import partial

import pytest

from gaitcap.errors import InputError
from gaitcap.prefetch import Head, Prefetched


def _recorded(produced: list[int], n: int = 100) -> Iterator[int]:
    """0 .. n-1, each appended to ``produced`` as the worker reads it."""
    for i in range(n):
        produced.append(i)
        yield i


def test_items_come_in_order():
    with Prefetched(iter(range(50)), depth=2) as items:
        assert list(items) == list(range(50))


def test_the_worker_stays_at_most_depth_items_ahead():
    produced: list[int] = []
    source = partial(_recorded, produced)

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


def test_a_smaller_depth_holds_the_worker_back_once_the_queue_drains():
    produced: list[int] = []
    source = partial(_recorded, produced)

    with Prefetched(source(), depth=10) as items:
        time.sleep(0.3)
        assert len(produced) >= 10  # read ahead while nothing is consumed
        items.set_depth(1)
        taken = [next(items) for _ in range(12)]
        time.sleep(0.3)
        assert taken == list(range(12))
        assert len(produced) <= 12 + 2  # one queued, one in the worker's hands
        with pytest.raises(ValueError, match="at least 1"):
            items.set_depth(0)


def test_the_head_reads_only_what_is_asked_and_keeps_it():
    read = []

    def source():
        for i in range(10):
            read.append(i)
            yield i

    src = source()
    sizes = []
    head = Head(src, limit=4, on_read=sizes.append)
    assert head.take(2) == [0, 1] and read == [0, 1]
    assert list(head) == [0, 1, 2, 3]  # iteration reads on, up to the limit
    assert list(head) == [0, 1, 2, 3] and read == [0, 1, 2, 3]  # and again from the start, nothing re-read
    assert head.take(9) == [0, 1, 2, 3]
    assert sizes == [1, 2, 3, 4]
    assert next(src) == 4  # the items after the head stay in the source


def test_a_head_longer_than_its_source_ends_with_it():
    head = Head(iter(range(3)), limit=5)
    assert head.take(5) == [0, 1, 2] and list(head) == [0, 1, 2]
    with pytest.raises(ValueError, match="at least 1"):
        Head(iter([]), limit=0)
