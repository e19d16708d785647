"""The event log panel: what happened during the session, with wall-clock times.

Entries come from two places: the GUI's own observations (link lost/recovered from
:class:`bpms.gui.health.LinkHealth`, Reset Zero, logging started/stopped, filter switched,
another UDP sender, file warnings) via :meth:`EventLog.add`, and the session's notable events
(``LiveStatus.events``, already time-stamped) via :meth:`EventLog.merge_session_events`.
Warnings are shown in red; every entry is also logged through :mod:`logging`.

One clock: live, every entry has the wall-clock time (HH:MM:SS). In playback
(:meth:`EventLog.use_recording_clock`) every entry has the recording's time instead (m:ss.ss
into the file): a session event at the time it names ("… at 12.34 s"), anything else at the
playback position; never the wall clock of the recording day or of today beside it.
"""

from __future__ import annotations

import logging
import re
import time
from collections.abc import Callable

from PyQt6.QtCore import Qt
from PyQt6.QtGui import QColor
from PyQt6.QtWidgets import QListView, QListWidget, QListWidgetItem, QWidget

log = logging.getLogger(__name__)

#: At most this many entries are kept (the oldest go first).
MAX_ENTRIES = 2000
#: Session events not listed: what follows from the user's own seek or frame step in
#: playback (the filters pre-rolled at the new position), which would fill the log.
UNLISTED = ("filters re-initialised (seek)",)
_AT = re.compile(r" at (-?\d+(?:\.\d+)?) s\b")


def recording_clock(seconds: float) -> str:
    """Seconds into a recording → ``m:ss.ss``."""
    minutes, rest = divmod(max(0.0, seconds), 60.0)
    return f"{int(minutes)}:{rest:05.2f}"


class EventLog(QListWidget):
    """A list of ``HH:MM:SS  text`` entries, newest last (the view follows the newest)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setObjectName("event_log")
        self.setAlternatingRowColors(True)
        # long entries wrap at the panel's width: it never scrolls sideways
        self.setWordWrap(True)
        self.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.setResizeMode(QListView.ResizeMode.Adjust)
        self.setToolTip("Link lost/recovered, Reset Zero, logging, filter changes, file "
                        "warnings, with times")
        self.entries: list[tuple[str, str, str]] = []  # (time, level, text)
        self._session_seen: list[str] = []
        self._position: Callable[[], float] | None = None

    def use_recording_clock(self, position_s: Callable[[], float]) -> None:
        """Playback: entries are stamped with the recording's time (``position_s()``: s into
        the file now) instead of the wall clock."""
        self._position = position_s
        self.setToolTip("Reset Zero, filter changes, markers, file warnings, with their time "
                        "in the recording (m:ss.ss)")

    def add(self, text: str, level: str = "info", when: str | None = None) -> None:
        """Append an entry; ``level`` "info" or "warning"; ``when`` HH:MM:SS (default now)."""
        if self._position is not None:  # playback: the recording's clock only
            at = _AT.search(text)
            when = recording_clock(float(at.group(1)) if at else self._position())
        when = when or time.strftime("%H:%M:%S")
        self.entries.append((when, level, text))
        item = QListWidgetItem(f"{when}  {text}")
        if level == "warning":
            item.setForeground(QColor("#d62728"))
            log.warning("%s", text)
        else:
            log.info("%s", text)
        self.addItem(item)
        if self.count() > MAX_ENTRIES:
            self.takeItem(0)
            del self.entries[0]
        self.scrollToBottom()

    def merge_session_events(self, events: list[str], warnings: list[str] | tuple = ()
                             ) -> None:
        """Add the session's events not seen yet (``LiveStatus.events``: "HH:MM:SS text",
        newest last, a bounded list; those in ``warnings`` in red): the session's one event
        source (:mod:`bpms.pipeline.events`), the lines its recording and LSL stream hold."""
        if events == self._session_seen:
            return
        seen = self._session_seen
        # the newest seen entry's (last) position in the new list: what follows it is new
        positions = [k for k, entry in enumerate(events) if seen and entry == seen[-1]]
        start = positions[-1] + 1 if positions else 0
        warned = set(warnings)
        for entry in events[start:]:
            when, _, text = entry.partition(" ")
            if text.startswith(UNLISTED):
                continue
            self.add(text, "warning" if entry in warned else "info", when)
        self._session_seen = list(events)

    def texts(self) -> list[str]:
        """The entries' texts (without times), oldest first."""
        return [text for _, _, text in self.entries]
