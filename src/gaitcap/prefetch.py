"""Run an iterator in a background thread, a bounded number of items ahead of its consumer.

``gaitcap track`` reads the videos and extracts the silhouettes of frame t + 1 while frame t is
tracked: the compiled kernels and OpenCV release the GIL, so the two overlap on two cores. The
queue holds at most ``depth`` items, so memory does not grow with the video. :class:`Head` keeps
the first frames (initialisation, shape calibration), read as they are first asked for: work on
the first ones starts while the next ones are still being read.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterator
from types import TracebackType
from typing import Generic, TypeVar

T = TypeVar("T")

_ITEM, _END, _ERROR = range(3)
_POLL_S = 0.1  # how often a worker blocked on a full queue checks whether it was stopped


class Prefetched(Generic[T]):
    """Iterate over ``source``, consumed in a worker thread at most ``depth`` items ahead.

    An exception raised by ``source`` in the worker is raised again, the same object (same type
    and message), by the consumer's ``next()`` at the point where the item would have come.
    :meth:`close` (or leaving the ``with`` block) stops the worker, closes ``source`` (a generator's
    ``finally`` blocks run, so its files are closed) and waits for the worker.

    Example:
        >>> with Prefetched(iter(range(3)), depth=2) as items:
        ...     list(items)
        [0, 1, 2]
    """

    def __init__(self, source: Iterator[T], depth: int = 2, name: str = "gaitcap-prefetch") -> None:
        if depth < 1:
            raise ValueError(f"depth must be at least 1, got {depth}")
        self._queue: queue.Queue[tuple[int, object]] = queue.Queue(maxsize=depth)
        self._stop = threading.Event()
        self._finished = False
        self._thread = threading.Thread(target=self._run, args=(source,), name=name, daemon=True)
        self._thread.start()

    def _put(self, kind: int, value: object) -> bool:
        """Queue one entry, waiting for room unless stopped; False when stopped."""
        while not self._stop.is_set():
            try:
                self._queue.put((kind, value), timeout=_POLL_S)
                return True
            except queue.Full:
                continue
        return False

    def _run(self, source: Iterator[T]) -> None:
        try:
            for item in source:
                if not self._put(_ITEM, item):
                    return
            self._put(_END, None)
        except BaseException as e:  # noqa: BLE001 - handed to the consumer, which raises it
            self._put(_ERROR, e)
        finally:
            close = getattr(source, "close", None)
            if close is not None:
                close()

    def __iter__(self) -> Prefetched[T]:
        return self

    def __next__(self) -> T:
        if self._finished:
            raise StopIteration
        kind, value = self._queue.get()
        if kind == _ITEM:
            return value  # type: ignore[return-value]
        self._finished = True
        self._thread.join()
        if kind == _ERROR:
            raise value  # type: ignore[misc]
        raise StopIteration

    def set_depth(self, depth: int) -> None:
        """Hold at most ``depth`` items ahead from now on (the items already queued stay)."""
        if depth < 1:
            raise ValueError(f"depth must be at least 1, got {depth}")
        with self._queue.mutex:
            self._queue.maxsize = depth
            self._queue.not_full.notify_all()

    def close(self) -> None:
        """Stop the worker (it finishes the item in hand), close the source, wait for both."""
        self._finished = True
        self._stop.set()
        self._thread.join()

    def __enter__(self) -> Prefetched[T]:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:  # fmt: skip
        self.close()


class Head(Generic[T]):
    """The first ``limit`` items of ``source``, read when first asked for and kept.

    :meth:`take` and iteration read on from where the last read stopped, never past ``limit``;
    the items after the head stay in ``source``. Each iteration starts again at the first item,
    so several readers can look at the head. ``on_read(n)`` is called with the number of items
    kept after each read (e.g. to shrink the queue of a :class:`Prefetched` source as the head fills).

    Example:
        >>> head = Head(iter(range(10)), limit=4)
        >>> head.take(2), list(head), head.take(9)
        ([0, 1], [0, 1, 2, 3], [0, 1, 2, 3])
    """

    def __init__(self, source: Iterator[T], limit: int, on_read: Callable[[int], None] | None = None) -> None:
        if limit < 1:
            raise ValueError(f"limit must be at least 1, got {limit}")
        self.source, self.limit, self.on_read = source, limit, on_read
        self.items: list[T] = []
        self._ended = False

    def _read_one(self) -> bool:
        """Read one more item into the head; False when the head is full or the source ended."""
        if self._ended or len(self.items) >= self.limit:
            return False
        item = next(self.source, _MISSING)
        if item is _MISSING:
            self._ended = True
            return False
        self.items.append(item)  # type: ignore[arg-type]
        if self.on_read is not None:
            self.on_read(len(self.items))
        return True

    def take(self, n: int) -> list[T]:
        """The first ``n`` items (fewer when the source ends first; at most ``limit``)."""
        while len(self.items) < n and self._read_one():
            pass
        return self.items[:n]

    def __iter__(self) -> Iterator[T]:
        i = 0
        while i < len(self.items) or self._read_one():
            yield self.items[i]
            i += 1


_MISSING = object()
