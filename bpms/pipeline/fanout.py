"""Bounded deliveries to consumers: a slow consumer loses its oldest items, counted, and never
blocks the producer — unless it asked to wait (``wait=True``: a stream of a recording, which
can wait, must lose nothing; the producer then waits for room, at most :data:`WAIT_LIMIT_S`
per item, so a consumer that died cannot hold it for good)."""

from __future__ import annotations

import threading
from collections import deque
from typing import Generic, TypeVar

T = TypeVar("T")
#: Longest a waiting subscription holds its producer for one item, s (then it drops it).
WAIT_LIMIT_S = 10.0


class Subscription(Generic[T]):
    """A bounded mailbox. ``put`` never blocks; when full, the oldest item is dropped and
    counted in :attr:`dropped`."""

    def __init__(self, maxlen: int = 500, wait: bool = False) -> None:
        self._items: deque[T] = deque(maxlen=maxlen)
        self._cond = threading.Condition()
        self.dropped = 0
        self.delivered = 0
        self.closed = False
        self.wait = wait

    def put(self, item: T) -> None:
        with self._cond:
            if self.wait and len(self._items) == self._items.maxlen:
                self._cond.wait_for(lambda: self.closed or len(self._items) <
                                    self._items.maxlen, WAIT_LIMIT_S)
            if len(self._items) == self._items.maxlen:
                self.dropped += 1
            self._items.append(item)
            self.delivered += 1
            self._cond.notify()

    def drain(self) -> list[T]:
        """Everything waiting, oldest first (never blocks)."""
        with self._cond:
            items = list(self._items)
            self._items.clear()
            self._cond.notify_all()
            return items

    def get(self, timeout: float) -> T | None:
        """The oldest item, waiting up to ``timeout`` s; None on timeout or when closed."""
        with self._cond:
            if not self._items and not self.closed:
                self._cond.wait(timeout)
            item = self._items.popleft() if self._items else None
            if self.wait:
                self._cond.notify_all()
            return item

    def close(self) -> None:
        with self._cond:
            self.closed = True
            self._cond.notify_all()


class Fanout(Generic[T]):
    """Publishes each item to every current subscription."""

    def __init__(self) -> None:
        self._subs: list[Subscription[T]] = []
        self._lock = threading.Lock()

    def subscribe(self, maxlen: int = 500, wait: bool = False) -> Subscription[T]:
        sub: Subscription[T] = Subscription(maxlen, wait)
        with self._lock:
            self._subs = [*self._subs, sub]
        return sub

    def unsubscribe(self, sub: Subscription[T]) -> None:
        sub.close()
        with self._lock:
            self._subs = [s for s in self._subs if s is not sub]

    def publish(self, item: T) -> None:
        for sub in self._subs:  # copy-on-write list: no lock needed here
            sub.put(item)

    @property
    def dropped(self) -> int:
        """Deliveries dropped across all current subscriptions."""
        return sum(s.dropped for s in self._subs)
