"""The main window's display tick and status: the table, plots and link light at every
tick, the status numbers four times a second, and the events that counters and recordings
deserve (:class:`StatusDisplay`, the slots of :class:`~bpms.gui.model.SessionModel`'s
signals)."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from bpms.gui.angle_readout import ContinuousAngles
from bpms.gui.columns import shown_angles
from bpms.gui.health import Health, stale_text
from bpms.gui.model import SessionModel
from bpms.gui.modes import SessionRunner
from bpms.gui.plot_data import BlockHistory, TickBlock
from bpms.gui.window.dynamic_docks import ViewDocks
from bpms.gui.window.mode_wiring import ModeControls
from bpms.gui.window.panels import WindowPanels
from bpms.pipeline.session import LiveStatus

#: Status numbers are refreshed this often, s (the link light at every display tick).
TEXT_PERIOD_S = 0.25


class StatusDisplay:
    """Slots of :class:`~bpms.gui.model.SessionModel`'s ``samplesArrived``
    (:meth:`on_samples`), ``healthChanged`` (:meth:`show_stale`) and ``statusChanged``
    (:meth:`on_status`). ``history``: the plots' window of blocks, extended at each tick;
    ``readout``: the continuous angles shown (one per window: table and plots agree);
    ``update_toolbar``: called at each status and when logging stops. ``tick_times_s``: GUI
    time per display tick (bench/gui.py)."""

    def __init__(self, model: SessionModel, runner: SessionRunner, panels: WindowPanels,
                 views: ViewDocks, mode: ModeControls, history: BlockHistory,
                 readout: ContinuousAngles, update_toolbar: Callable[[], None]) -> None:
        self._model = model
        self._runner = runner
        self._panels = panels
        self._views = views
        self._mode = mode
        self.history = history
        self.readout = readout
        self._update_toolbar = update_toolbar
        self.tick_times_s: list[float] = []
        self._last_recording: object | None = None
        self._error_said_of: object | None = None  # the recording whose error is logged
        self._counters: dict[str, int] = {}
        self._texts_at = -1e9
        self._last_state = ""
        self._source_warning = ""
        self._reinit_count = 0
        self._disturbed: tuple[int, int] | None = None  # IMUs (mag, acc) disturbed now

    def on_samples(self, samples: list) -> None:
        """A display tick's frames: the readout, the history, the tables and the plots."""
        start = time.perf_counter()
        self._views.prune()
        last = samples[-1]
        panels = self._panels
        model = panels.table_model
        # the continuous readout of the angles shown (one per window: table and plots agree)
        angles = np.array([shown_angles(s, model.show_output)[0] for s in samples])
        euler = self.readout.feed(angles, np.array([s.index for s in samples]))
        block = TickBlock.from_samples(samples, model.calibration, model.show_output, euler)
        self.history.extend(block)
        model.update(last, np.any([s.errors for s in samples], axis=0), euler=euler[-1])
        if last.mag_disturbed is not None and last.acc_disturbed is not None:
            self._disturbed = (int(np.count_nonzero(last.mag_disturbed)),
                               int(np.count_nonzero(last.acc_disturbed)))
        if panels.joint_table.isVisible():
            panels.joint_model.update(samples[-1])
        for plot in self._views.plot_windows:
            plot.append(block)
        self.tick_times_s.append(time.perf_counter() - start)
        del self.tick_times_s[:-20000]

    def show_stale(self, health: Health) -> None:
        """Every view marks data that is not live (3D views do it themselves)."""
        text = stale_text(health)
        self._views.prune()  # (a plot closed since the last tick)
        self._panels.table.stale.show_text(text)
        self._panels.joint_table.stale.show_text(text)
        for plot in self._views.plot_windows:
            plot.stale.show_text(text)

    def refresh_texts(self) -> None:
        """The next status refreshes the numbers, however soon it comes."""
        self._texts_at = -1e9

    def on_status(self, st: LiveStatus) -> None:
        """The link light, the numbers (4 times a second), the events, the mode's panels and
        the toolbar."""
        now = time.monotonic()
        panels = self._panels
        log = panels.event_log
        # the model evaluated the link rule for this tick (a paused or ended replay: grey)
        health = self._model.last_health
        if health.transition == "lost":
            log.add(f"link lost: no frame for {self._model.health.silent_s:g} s "
                    f"({st.source.description})", "warning")
        elif health.transition == "recovered":
            log.add("link recovered")
        panels.health_panel.set_colour(health.colour)
        # Text changes re-lay out their panels: the numbers are refreshed 4 times a second,
        # the light at every tick (and at once when the state changes).
        if now - self._texts_at >= TEXT_PERIOD_S or health.state != self._last_state:
            self._texts_at, self._last_state = now, health.state
            panels.health_panel.show_health(health, st, now)
            panels.health_panel.show_disturbance(*(self._disturbed or (None, None)))
            panels.status_panel.show_status(st, health.state if self._runner.data_on
                                            else None)
            panels.file_panel.show_status(st)
        # the processor's values in force (once the changes queued are applied)
        panels.gains_panel.show_settings(st.filter_settings, st.settings_pending)
        log.merge_session_events(st.events, st.event_warnings)
        self._watch_counters(st)
        self._watch_recording(st)
        self._mode.show_status(st)
        self._update_toolbar()

    def _watch_counters(self, st: LiveStatus) -> None:
        """What deserves an event when it appears or grows: another UDP sender (the source's
        warning, or its ``foreign`` counter growing while no warning is shown), each filter
        re-initialisation by the state guard (``reinit_count``)."""
        warning = st.source.warning
        foreign = st.source.counters.get("foreign", 0)
        grew = foreign > self._counters.get("foreign", 0)
        self._counters["foreign"] = foreign
        log = self._panels.event_log
        if warning and warning != self._source_warning:
            log.add(f"UDP: {warning}" if "sender" in warning else warning, "warning")
        elif grew and not warning:
            log.add(f"UDP: another sender on this port ({foreign} datagrams ignored)",
                    "warning")
        self._source_warning = warning
        if st.reinit_count < self._reinit_count:  # a new session (UDP client restarted)
            self._reinit_count = 0
        # the session's own line for this count (rate-limited) says it already
        said = any(e.endswith(f"; {st.reinit_count} so far") and "re-initialised" in e
                   for e in st.events[-5:])
        if st.reinit_count > self._reinit_count and not said:
            new = st.reinit_count - self._reinit_count
            log.add(f"filter re-initialised by the state guard ({new} "
                    f"re-initialisation{'s' if new > 1 else ''}, {st.reinit_count} so far)",
                    "warning")
        self._reinit_count = st.reinit_count

    def _watch_recording(self, st: LiveStatus) -> None:
        rec = st.recording
        if rec is not None and rec is not self._last_recording:
            names = ", ".join(str(p) for p in (rec.raw_path, rec.filtered_path) if p)
            self._panels.event_log.add(f"logging started: {names}")
        if rec is not None and rec.error and rec is not self._error_said_of:
            self._panels.event_log.add(f"file warning: {rec.error}", "warning")
            self._error_said_of = rec
        self._last_recording = rec

    def logging_stopped(self, rec) -> None:
        """The files a stopped logging wrote, in the event log."""
        if rec is None:
            return
        parts = []
        if rec.raw_path is not None:
            parts.append(f"{rec.raw_path.name} ({rec.raw_records} frames)")
        if rec.filtered_path is not None:
            parts.append(rec.filtered_path.name)
        self._panels.event_log.add("logging stopped: " + ", ".join(parts))
        self._update_toolbar()
