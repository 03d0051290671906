"""Run an iterator in a background thread, a bounded number of items ahead of its consumer.

``gaitcap track`` reads the videos and extracts the silhouettes of frame t + 1 while frame t is
tracked: the compiled kernels and OpenCV release the GIL, so the two overlap on two cores. The
queue holds at most ``depth`` items, so memory does not grow with the video.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator
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
