"""The hand-off from the acquisition thread to the processing thread: a bounded queue that
costs one C-level put and get per frame (``queue.SimpleQueue``), where ``queue.Queue`` builds
a Python condition and a lock per blocking get.

One producer (the acquisition thread), one consumer (the processing thread). The bound is
checked by the producer; a producer waiting for room (a file source, which can wait) is woken
by the consumer's next get.
"""

from __future__ import annotations

import queue
import threading
import time
from typing import Generic, TypeVar

T = TypeVar("T")


class Handoff(Generic[T]):
    """A bounded single-producer / single-consumer queue (``maxsize`` items)."""

    def __init__(self, maxsize: int) -> None:
        self.maxsize = maxsize
        self._items: queue.SimpleQueue[T] = queue.SimpleQueue()
        self._room = threading.Event()
        self._waiting = False

    def qsize(self) -> int:
        return self._items.qsize()

    def put(self, item: T) -> None:
        """Put whatever the size (end markers)."""
        self._items.put(item)

    def put_nowait(self, item: T) -> None:
        """Put, or raise ``queue.Full`` when ``maxsize`` items wait."""
        if self._items.qsize() >= self.maxsize:
            raise queue.Full
        self._items.put(item)

    def put_wait(self, item: T, timeout: float) -> None:
        """Put, waiting up to ``timeout`` s for room; raise ``queue.Full`` after that."""
        deadline = time.monotonic() + timeout
        while self._items.qsize() >= self.maxsize:
            self._room.clear()
            self._waiting = True
            if self._items.qsize() < self.maxsize:
                break
            left = deadline - time.monotonic()
            if left <= 0 or not self._room.wait(left):
                self._waiting = False
                raise queue.Full
        self._waiting = False
        self._items.put(item)

    def get(self, timeout: float) -> T:
        """The oldest item, waiting up to ``timeout`` s; raise ``queue.Empty`` after that."""
        item = self._items.get(timeout=timeout)
        if self._waiting:
            self._room.set()
        return item

    def get_nowait(self) -> T:
        item = self._items.get_nowait()
        if self._waiting:
            self._room.set()
        return item
