"""The one road for run-time settings into the processing thread.

The GUI, the CLI and the API change settings while frames are being filtered. Nobody writes
the processor's options directly: each change is made as its typed event
(:mod:`bpms.io.event_types`: :class:`~bpms.io.event_types.Gains`,
:class:`~bpms.io.event_types.FilterChoice`, :class:`~bpms.io.event_types.ResetZero`,
:class:`~bpms.io.event_types.Alignment`), which checks its values in the caller's thread (a
value outside :data:`bpms.io.options.VALID_RANGES` raises
:class:`bpms.io.options.OptionRangeError` there, naming the range, and nothing is queued).
The processing thread hands every queued change, between two frames, to
:meth:`bpms.filter.processor.BodyPoseProcessor.apply_event` (:meth:`SettingsQueue.apply`) —
the function replay and re-analysis give the recorded events to — so it holds from the next
frame on. The processor owns the values in force (``options.filter``, each filter's own), so
switching filter and back keeps run-time gains.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from typing import Any

from bpms.io.event_types import Change, ResetZero
from bpms.io.session_events import SessionEvent


class SettingsQueue:
    """Checked, queued settings changes for one processor (thread-safe)."""

    def __init__(self) -> None:
        self._queue: queue.SimpleQueue[Change] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self._queued = 0  # changes put (any thread, under the lock)
        self._applied = 0  # changes taken and applied (the one consumer only)

    @property
    def pending(self) -> int:
        """Changes queued and not applied yet (until then the processor's values in force
        are about to change)."""
        return self._queued - self._applied

    def put(self, change: Change) -> None:
        """Queue a typed change (already checked when it was made)."""
        with self._lock:
            self._queued += 1
            self._queue.put(change)

    def reset_zero(self, source: str = "manual") -> None:
        """Queue a Reset Zero capture (``source``: who asked, e.g. ``3d-view``)."""
        self.put(ResetZero(source))

    def apply(self, processor: Any, on_error: Callable[[str], None] | None = None
              ) -> list[SessionEvent]:
        """Apply every queued change to ``processor`` (a BodyPoseProcessor,
        :meth:`~bpms.filter.processor.BodyPoseProcessor.apply_event`), in order; call from
        the processing thread between two frames. A change that fails (e.g. the vqf package
        missing) is reported through ``on_error`` and the others still apply. Returns the
        session events of the changes applied (no frame yet: they hold from the next frame;
        a Reset Zero becomes an event when it is captured)."""
        done: list[SessionEvent] = []
        while not self._queue.empty():  # (checked first: no exception per frame; one consumer)
            change = self._queue.get_nowait()
            applied = processor.apply_event(change, on_error)
            self._applied += 1  # (after it is applied: pending until then)
            if applied is not None and not isinstance(change, ResetZero):
                done.append(applied)
        return done


__all__ = ["SettingsQueue"]
