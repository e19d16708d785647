"""The one source of a live session's events: :class:`SessionEvents`.

Everything notable that happens in a session goes through here, once: a Reset Zero (with its
source, window, result and the motion measured), the alignment switched, the filter or a gain
changed, the filters re-initialised, a marker note, logging started or stopped, and warnings.
From here each event goes to

- the raw recording (the session's raw logger subscribes and writes it between the frame
  records, at the slot of the frame it names, docs/raw-format.md);
- the event log: :meth:`SessionEvents.lines` (``LiveStatus.events``: the GUI's event log, the
  ``event:`` lines of ``bpms record``) and the Python log;
- the LSL event stream (:class:`bpms.pipeline.lsl.LslBridge` subscribes).

An event that changes numbers from the next frame on (a gain, the alignment, a marker typed
now) waits in :meth:`SessionEvents.at_next_frame` until the processing thread knows which frame
that is (:meth:`SessionEvents.frame_reached`).
"""

from __future__ import annotations

import logging
import threading
import time

from bpms.io.event_types import Note
from bpms.io.frames import FRAME_PERIOD_S
from bpms.io.session_events import SessionEvent
from bpms.io.timebase import plausible_host_time
from bpms.pipeline.fanout import Fanout, Subscription

log = logging.getLogger(__name__)

#: Event lines kept for the status display.
KEPT_LINES = 50


class SessionEvents:
    """Emits :class:`bpms.io.session_events.SessionEvent` objects to every subscriber and keeps
    the last :data:`KEPT_LINES` as ``HH:MM:SS text`` lines (thread-safe)."""

    def __init__(self, dt: float = FRAME_PERIOD_S) -> None:
        self.dt = dt
        self._fanout: Fanout[SessionEvent] = Fanout()
        self._lock = threading.Lock()
        self._lines: list[str] = []
        self._warned: list[str] = []  # the kept lines that are warnings
        self._waiting: list[tuple[SessionEvent, bool]] = []
        self.count = 0
        #: called with every event, in the emitting thread, in order (the raw logger's queue:
        #: an event then follows the frames queued before it)
        self.sinks: list = []

    def subscribe(self, maxlen: int = 1000) -> Subscription[SessionEvent]:
        """Every event from now on (a bounded mailbox)."""
        return self._fanout.subscribe(maxlen)

    def unsubscribe(self, sub: Subscription[SessionEvent]) -> None:
        self._fanout.unsubscribe(sub)

    def emit(self, event: SessionEvent, warning: bool = False) -> SessionEvent:
        """Publish ``event`` (its time set to now when unknown), log it and keep its line."""
        if event.time != event.time:  # NaN: not stamped yet
            event = SessionEvent(event.kind, event.frame, time.time(), event.data)
        text = event.describe(self.dt)
        (log.warning if warning else log.info)("%s", text)
        with self._lock:
            stamp = (time.strftime("%H:%M:%S", time.localtime(event.time))
                     if plausible_host_time(event.time) else "--:--:--")
            line = f"{stamp} {text}"
            self._lines = [*self._lines[-(KEPT_LINES - 1):], line]
            if warning:
                self._warned = [*self._warned[-(KEPT_LINES - 1):], line]
            self.count += 1
            sinks = list(self.sinks)
        for sink in sinks:
            sink(event)
        self._fanout.publish(event)
        return event

    def note(self, text: str, frame: int = -1, warning: bool = True) -> SessionEvent:
        """A line for the event log (and the recording): a warning by default."""
        return self.emit(SessionEvent.of(Note(text), frame), warning)

    def at_next_frame(self, event: SessionEvent, warning: bool = False) -> None:
        """Emit ``event`` when the next frame is processed, naming that frame."""
        with self._lock:
            self._waiting.append((event, warning))

    @property
    def waiting(self) -> bool:
        return bool(self._waiting)

    def frame_reached(self, frame: int) -> None:
        """The processing thread is at source frame ``frame``: what waited is emitted at it."""
        with self._lock:
            waiting, self._waiting = self._waiting, []
        for event, warning in waiting:
            self.emit(event.at(frame), warning)

    def lines(self) -> list[str]:
        """The kept ``HH:MM:SS text`` lines, newest last."""
        with self._lock:
            return list(self._lines)

    def warning_lines(self) -> list[str]:
        """Those of :meth:`lines` that are warnings."""
        with self._lock:
            return [w for w in self._warned if w in self._lines]


__all__ = ["KEPT_LINES", "SessionEvents"]
