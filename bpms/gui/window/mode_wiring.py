"""What depends on the session's mode: the playback panel and its frame steps, Data menu
entries and drift check (file playback), the UDP server panel (suit, simulated suit), the
listening address (UDP client) and the nominal rate. Mixed into
:class:`bpms.gui.main_window.MainWindow`."""

from __future__ import annotations

from PyQt6.QtCore import Qt
from PyQt6.QtWidgets import QMenu

from bpms.gui.controls import PlaybackPanel, UdpServerPanel
from bpms.pipeline.session import LiveStatus


class ModeWiring:
    """``playback_panel`` (None unless a file plays), ``udp_panel`` (None unless a suit)."""

    def _build_mode_panels(self) -> None:
        runner = self.runner
        self.playback_panel = PlaybackPanel(runner) if runner.replay is not None else None
        if self.playback_panel is not None:  # a paused seek redraws the plots' whole window
            self.playback_panel.window_frames = self.history.buffer.capacity
        self.udp_panel = UdpServerPanel(runner) if runner.mode in ("suit", "sim") else None

    def _add_playback_actions(self, menu: QMenu) -> None:
        """File playback: the frame steps and the drift check in the Data menu."""
        if self.runner.replay is None:
            return
        acts = self.actions_by_name
        menu.addSeparator()
        for key in ("step_back", "step_fwd", "step_back10", "step_fwd10"):
            menu.addAction(acts[key])
        menu.addSeparator()
        menu.addAction(acts["drift"])
        from bpms.gui.compare_panel import add_compare_action  # docs/compare.md

        add_compare_action(self, menu)

    def _listening(self) -> str | None:
        """The UDP client's listening address (host:port), else None."""
        source = self.runner.session.source if self.runner.session is not None else None
        udp = getattr(source, "udp", None)
        return str(udp.listening) if udp is not None and hasattr(udp, "listening") else None

    def _nominal_hz(self) -> float | None:
        replay = self.runner.replay
        if replay is None:
            return 50.0
        return None if replay.speed is None else 50.0 * replay.speed

    def _show_mode_status(self, st: LiveStatus) -> None:
        """The playback and UDP server panels' numbers; the end of a played recording stops
        the data."""
        if self.playback_panel is not None:
            self.playback_panel.show_status(st)
            if self.runner.replay is not None and self.runner.replay.ended \
                    and self.runner.data_on:
                self.set_data(False)
                self.statusBar().showMessage("end of the recording", 5000)
                self.event_log.add("end of the recording")
        if self.udp_panel is not None:
            self.udp_panel.show_status(st)

    def step_frames(self, n: int) -> None:
        """Playback, paused: move ``n`` frames (the frame is shown in every view)."""
        if self.playback_panel is not None and not self.runner.replay.playing:
            self.playback_panel.step(n)

    def open_drift_check(self):
        """A dock with the drift check of the recording being played (computed in the
        background with the playback's calibration, options and filter); None when no
        recording is played."""
        from bpms.gui.drift_panel import drift_dock

        if self.runner.replay is None or not self.runner.config.path:
            return None
        dock, panel = drift_dock(self)
        self.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, dock)
        runner = self.runner
        panel.start(runner.config.path, runner.playback_calibration, runner.playback_options,
                    runner.options.filter.algorithm)
        return panel
