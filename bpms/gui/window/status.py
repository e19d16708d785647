"""The main window's display tick and status: the table, plots and link light at every
tick, the status numbers four times a second, and the events that counters and recordings
deserve. Mixed into :class:`bpms.gui.main_window.MainWindow`."""

from __future__ import annotations

import time

import numpy as np

from bpms.gui.columns import shown_angles
from bpms.gui.health import Health, stale_text
from bpms.gui.plot_data import TickBlock
from bpms.io.frames import FRAME_PERIOD_S
from bpms.pipeline.session import LiveStatus

#: Status numbers are refreshed this often, s (the link light at every display tick).
TEXT_PERIOD_S = 0.25


class StatusDisplay:
    """Slots of :class:`~bpms.gui.model.SessionModel`'s ``samplesArrived`` and
    ``statusChanged``."""

    def _on_samples(self, samples: list) -> None:
        start = time.perf_counter()
        self._prune()
        last = samples[-1]
        model = self.table_model
        # the continuous readout of the angles shown (one per window: table and plots agree)
        angles = np.array([shown_angles(s, model.show_output)[0] for s in samples])
        euler = self.readout.feed(angles, np.array([s.index for s in samples]))
        block = TickBlock.from_samples(samples, model.calibration, model.show_output, euler)
        self.history.extend(block)
        model.update(last, np.any([s.errors for s in samples], axis=0), euler=euler[-1])
        if last.mag_disturbed is not None and last.acc_disturbed is not None:
            self._disturbed = (int(np.count_nonzero(last.mag_disturbed)),
                               int(np.count_nonzero(last.acc_disturbed)))
        if self.joint_table.isVisible():
            self.joint_model.update(samples[-1])
        window = max(2, round(self.options.pose.reset_window_s / FRAME_PERIOD_S))
        self._recent_R.extend(s.R for s in samples[-window:])
        del self._recent_R[:-window]
        for plot in self.plot_windows:
            plot.append(block)
        self.tick_times_s.append(time.perf_counter() - start)
        del self.tick_times_s[:-20000]

    def _show_stale(self, health: Health) -> None:
        """Every view marks data that is not live (3D views do it themselves)."""
        text = stale_text(health)
        self._prune()  # (a plot closed since the last tick)
        self.table.stale.show_text(text)
        self.joint_table.stale.show_text(text)
        for plot in self.plot_windows:
            plot.stale.show_text(text)

    def _on_status(self, st: LiveStatus) -> None:
        now = time.monotonic()
        # the model evaluated the link rule for this tick (a paused or ended replay: grey)
        health = self.model.last_health
        if health.transition == "lost":
            self.event_log.add(f"link lost: no frame for {self.model.health.silent_s:g} s "
                               f"({st.source.description})", "warning")
        elif health.transition == "recovered":
            self.event_log.add("link recovered")
        self.health_panel.set_colour(health.colour)
        # Text changes re-lay out their panels: the numbers are refreshed 4 times a second,
        # the light at every tick (and at once when the state changes).
        if now - self._texts_at >= TEXT_PERIOD_S or health.state != self._last_state:
            self._texts_at, self._last_state = now, health.state
            self.health_panel.show_health(health, st, now)
            self.health_panel.show_disturbance(*(self._disturbed or (None, None)))
            self.status_panel.show_status(st, health.state if self.runner.data_on else None)
            self.file_panel.show_status(st)
        self.event_log.merge_session_events(st.events)
        self._watch_counters(st)
        self._watch_recording(st)
        self._show_mode_status(st)
        self._update_toolbar()

    def _watch_counters(self, st: LiveStatus) -> None:
        """What deserves an event when it appears or grows: another UDP sender (the source's
        warning, or its ``foreign`` counter growing while no warning is shown), each filter
        re-initialisation by the state guard (``reinit_count``)."""
        warning = st.source.warning
        foreign = st.source.counters.get("foreign", 0)
        grew = foreign > self._counters.get("foreign", 0)
        self._counters["foreign"] = foreign
        if warning and warning != self._source_warning:
            self.event_log.add(f"UDP: {warning}" if "sender" in warning else warning,
                               "warning")
        elif grew and not warning:
            self.event_log.add(f"UDP: another sender on this port ({foreign} datagrams "
                               "ignored)", "warning")
        self._source_warning = warning
        if st.reinit_count < self._reinit_count:  # a new session (UDP client restarted)
            self._reinit_count = 0
        # the session's own line for this count (rate-limited) says it already
        said = any(e.endswith(f"; {st.reinit_count} so far") and "re-initialised" in e
                   for e in st.events[-5:])
        if st.reinit_count > self._reinit_count and not said:
            new = st.reinit_count - self._reinit_count
            self.event_log.add(f"filter re-initialised by the state guard ({new} "
                               f"re-initialisation{'s' if new > 1 else ''}, "
                               f"{st.reinit_count} so far)", "warning")
        self._reinit_count = st.reinit_count

    def _watch_recording(self, st: LiveStatus) -> None:
        rec = st.recording
        if rec is not None and rec is not self._last_recording:
            names = ", ".join(str(p) for p in (rec.raw_path, rec.filtered_path) if p)
            self.event_log.add(f"logging started: {names}")
        if rec is not None and rec.error and not getattr(rec, "_logged_error", False):
            self.event_log.add(f"file warning: {rec.error}", "warning")
            rec._logged_error = True  # type: ignore[attr-defined]
        self._last_recording = rec

    def _logging_stopped(self, rec) -> None:
        if rec is None:
            return
        parts = []
        if rec.raw_path is not None:
            parts.append(f"{rec.raw_path.name} ({rec.raw_records} frames)")
        if rec.filtered_path is not None:
            parts.append(rec.filtered_path.name)
        self.event_log.add("logging stopped: " + ", ".join(parts))
        self._update_toolbar()
