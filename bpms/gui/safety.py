"""Safe controls: a mouse wheel never changes a live setting by accident, a double click never
undoes a destructive toggle, and slow work never runs on the GUI thread.

- :func:`guard_wheel`: the control takes keyboard focus only by click or Tab (StrongFocus) and
  ignores wheel events until it has focus (the wheel then scrolls the panel under it instead);
- :func:`debounce`: a button's ``clicked`` goes through only if the previous accepted click
  was at least :data:`DEBOUNCE_S` ago;
- :func:`set_enabled_keeping_focus`: disabling a focused control leaves the focus (and the
  scroll position of the panel) where it is;
- :class:`BackgroundTask`: run a blocking call (closing files, joining threads) in a worker
  thread, ``done(result, error)`` back on the GUI thread.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from PyQt6.QtCore import QEvent, QObject, Qt, QTimer
from PyQt6.QtWidgets import QAbstractButton, QApplication, QWidget

#: A second click on a destructive toggle within this time is ignored, s.
DEBOUNCE_S = 0.5


class _WheelGuard(QObject):
    """Event filter: wheel events reach the control only when it has keyboard focus."""

    def eventFilter(self, obj: QObject | None, event: QEvent | None) -> bool:
        if event is not None and event.type() == QEvent.Type.Wheel \
                and isinstance(obj, QWidget) and not obj.hasFocus():
            event.ignore()  # propagates to the parent (the scroll area scrolls)
            return True
        return False


_GUARD: _WheelGuard | None = None


def guard_wheel(*widgets: QWidget) -> None:
    """Make every widget in ``widgets`` wheel-safe (StrongFocus + the wheel filter)."""
    global _GUARD
    if _GUARD is None:
        _GUARD = _WheelGuard()
    for widget in widgets:
        widget.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        widget.installEventFilter(_GUARD)


def set_enabled_keeping_focus(enabled: bool, holder: QWidget, *widgets: QWidget) -> None:
    """Enable or disable ``widgets``; when one being disabled has the keyboard focus, the focus
    goes to ``holder`` first. Otherwise Qt hands it to the next widget in the focus chain,
    and a scroll area around that one scrolls to show it (Start Data made the playback
    panel jump to the Name field, its slider out of view)."""
    if not enabled:
        focus = QApplication.focusWidget()
        if focus is not None and any(w is focus or w.isAncestorOf(focus) for w in widgets):
            if holder.focusPolicy() == Qt.FocusPolicy.NoFocus:
                holder.setFocusPolicy(Qt.FocusPolicy.ClickFocus)
            holder.setFocus(Qt.FocusReason.OtherFocusReason)
    for widget in widgets:
        if widget.isEnabled() != enabled:
            widget.setEnabled(enabled)


def debounce(button: QAbstractButton, slot: Callable[[], Any],
             interval_s: float = DEBOUNCE_S) -> None:
    """Connect ``button.clicked`` to ``slot``, ignoring a click within ``interval_s`` of the
    last accepted one (a double click toggles once, not on and off)."""
    last = [-1e9]

    def clicked(*_args: object) -> None:
        now = time.monotonic()
        if now - last[0] < interval_s:
            return
        last[0] = now
        slot()

    button.clicked.connect(clicked)


class BackgroundTask:
    """``fn()`` in a daemon thread; ``done(result, error)`` is called on the GUI thread (polled
    by a 20 ms timer owned by ``parent``)."""

    def __init__(self, parent: QObject, fn: Callable[[], Any],
                 done: Callable[[Any, BaseException | None], None],
                 name: str = "bpms-gui-task") -> None:
        self.result: Any = None
        self.error: BaseException | None = None
        self._fn = fn
        self._done = done
        self._thread = threading.Thread(target=self._run, daemon=True, name=name)
        self._timer = QTimer(parent)
        self._timer.setInterval(20)
        self._timer.timeout.connect(self._poll)
        self._thread.start()
        self._timer.start()

    def _run(self) -> None:
        try:
            self.result = self._fn()
        except BaseException as exc:  # reported on the GUI thread
            self.error = exc

    def _poll(self) -> None:
        if self._thread.is_alive():
            return
        self._timer.stop()
        self._done(self.result, self.error)

    @property
    def running(self) -> bool:
        return self._thread.is_alive() or self._timer.isActive()

    def wait(self, timeout: float | None = None) -> None:
        """Block until the thread ends (for shutdown only), then deliver ``done``."""
        self._thread.join(timeout)
        if not self._thread.is_alive() and self._timer.isActive():
            self._poll()
