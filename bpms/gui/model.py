"""The Qt face of a live session: polls a Qt-free :class:`LiveSession` on a display timer.

The pipeline runs in its own threads; nothing here filters or does I/O. Every ``1/refresh_hz``
seconds the model drains its bounded subscription and emits what arrived, so widgets redraw at
the display rate (≈ 20 Hz), never at the 50 Hz frame rate, and a burst of frames (Bluetooth,
UDP flood) costs one redraw.

Views connect to:
- ``samplesArrived(list[PoseSample])``: the samples since the last tick, oldest first;
- ``statusChanged(LiveStatus)``: a status snapshot each tick;
- ``sessionChanged(object)``: a new session (or None) was attached;
- ``healthChanged(Health)``: the link light's evaluation each tick (:mod:`bpms.gui.health`),
  emitted before ``statusChanged``; every view marks its data stale from it
  (:func:`bpms.gui.health.stale_text`).
``latest`` is the newest sample (or None); ``health`` the one :class:`LinkHealth` of the
window (Start/Stop Data go through :meth:`set_data_on`); ``nominal_hz`` returns the frame
rate expected now (None: any, e.g. a replay at maximum speed).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from PyQt6.QtCore import QObject, Qt, QTimer, pyqtSignal

from bpms.gui.health import Health, LinkHealth
from bpms.io.options import Options
from bpms.pipeline.fanout import Subscription
from bpms.pipeline.session import LiveSession, LiveStatus, PoseSample


class SessionModel(QObject):
    samplesArrived = pyqtSignal(list)
    statusChanged = pyqtSignal(object)
    sessionChanged = pyqtSignal(object)
    healthChanged = pyqtSignal(object)

    def __init__(self, options: Options | None = None, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.options = options or Options()
        self.session: LiveSession | None = None
        self.latest: PoseSample | None = None
        self.last_status: LiveStatus | None = None
        self.health = LinkHealth()
        self.last_health: Health | None = None
        self.nominal_hz: Callable[[], float | None] = lambda: 50.0
        self._sub: Subscription[PoseSample] | None = None
        self._timer = QTimer(self)
        # Precise: a late tick does not push every later one back (a coarse timer drifts by
        # the lateness, so a busy GUI thread would redraw below the configured rate).
        self._timer.setTimerType(Qt.TimerType.PreciseTimer)
        self._timer.timeout.connect(self.tick)
        self.set_refresh_hz(self.options.display.refresh_hz)

    def set_refresh_hz(self, hz: float) -> None:
        """Redraw rate of every view attached to this model, Hz."""
        self._timer.setInterval(max(1, round(1000.0 / hz)))

    def set_data_on(self, on: bool) -> None:
        """Start Data / Stop Data pressed: the link rule's clock restarts or stops (grey)."""
        if on:
            self.health.start()
        else:
            self.health.stop()

    def attach(self, session: LiveSession | None) -> None:
        """Show ``session`` (already started or not; data counts as on until
        :meth:`set_data_on` says otherwise); None detaches."""
        if self.session is not None and self._sub is not None:
            self.session.unsubscribe(self._sub)
        self.session = session
        self.latest = None
        self._sub = session.subscribe(maxlen=3000) if session is not None else None
        if session is None:
            self._timer.stop()
        else:
            self.health.start()
            self._timer.start()
        self.sessionChanged.emit(session)

    def tick(self) -> None:
        """Drain the subscription and notify the views (runs on the display timer)."""
        if self.session is None or self._sub is None:
            return
        samples = self._sub.drain()
        now = time.monotonic()
        if samples:
            self.latest = samples[-1]
            self.health.frames_arrived(now)
            self.samplesArrived.emit(samples)
        st = self.last_status = self.session.status()
        self.last_health = self.health.evaluate(now, st.rate_hz, st.error_bits, st.source.state,
                                                self.nominal_hz())
        self.healthChanged.emit(self.last_health)
        self.statusChanged.emit(st)

    def stop(self) -> None:
        """Stop and detach the session (threads joined, files closed)."""
        session = self.session
        self.attach(None)
        if session is not None:
            session.stop()
