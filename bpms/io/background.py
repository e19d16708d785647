"""Work handed to one worker thread, in order, while the caller goes on: :class:`InBackground`.

A whole-recording command filters a chunk while the rows of the chunk before are formatted and
written: on a computer with two cores the two overlap (the filters' compiled loops and numpy's
array operations release Python's interpreter lock while they run), and the command takes about
the longer of the two instead of their sum. At most ``depth`` calls wait, so memory stays
bounded; an exception raised by a call is raised again in the caller, by the next
:meth:`InBackground.submit` or by :meth:`InBackground.close`.
"""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Callable
from typing import Any

_DONE = object()


class InBackground:
    """Calls run one after the other in a worker thread (``with InBackground() as later:
    later.submit(write, rows)``)."""

    def __init__(self, depth: int = 2, name: str = "bpms-background") -> None:
        self._calls: queue.Queue = queue.Queue(maxsize=max(1, depth))
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            call = self._calls.get()
            if call is _DONE:
                return
            if self._error is None:  # after a failure the rest is not run
                fn, args, kwargs = call
                try:
                    fn(*args, **kwargs)
                except BaseException as exc:  # raised again in the caller's thread
                    self._error = exc

    def _raise(self) -> None:
        if self._error is not None:
            error, self._error = self._error, None
            raise error

    def submit(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
        """Run ``fn(*args, **kwargs)`` after the calls before it (waits while ``depth`` calls
        are waiting). The arguments must not change afterwards."""
        self._raise()
        self._calls.put((fn, args, kwargs))

    def close(self) -> None:
        """Wait for every call; raise the first call's exception, if one failed."""
        if self._thread.is_alive():
            self._calls.put(_DONE)
            self._thread.join()
        self._raise()

    def __enter__(self) -> InBackground:
        return self

    def __exit__(self, kind: object, *exc: object) -> None:
        if kind is None:
            self.close()
        else:  # the caller's own error goes first; the worker still stops
            with contextlib.suppress(BaseException):
                self.close()
