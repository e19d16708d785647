"""What depends on the session's mode: the playback panel's numbers and frame steps, the Data
menu's playback entries and the drift check (file playback), the UDP server panel's numbers
(suit, simulated suit) and the nominal rate.

:class:`ModeControls` holds no state of its own; the panels it drives are
:class:`~bpms.gui.window.panels.WindowPanels`' (``playback_panel``, ``udp_panel``).
"""

from __future__ import annotations

from PyQt6.QtCore import Qt
from PyQt6.QtGui import QAction
from PyQt6.QtWidgets import QMainWindow, QMenu

from bpms.gui.modes import SessionRunner
from bpms.gui.window.commands import SessionCommands
from bpms.gui.window.panels import WindowPanels
from bpms.pipeline.session import LiveStatus


def nominal_hz(runner: SessionRunner) -> float | None:
    """The rate frames should arrive at, Hz: 50 live, 50 × the speed in playback, None when
    a recording plays as fast as it can."""
    replay = runner.replay
    if replay is None:
        return 50.0
    return None if replay.speed is None else 50.0 * replay.speed


class ModeControls:
    """The mode's panels in ``window``: numbers at each status, the end of a recording, frame
    steps, playback menu entries and the drift check."""

    def __init__(self, window: QMainWindow, runner: SessionRunner, panels: WindowPanels,
                 commands: SessionCommands) -> None:
        self._window = window
        self._runner = runner
        self._panels = panels
        self._commands = commands

    def add_playback_actions(self, menu: QMenu, actions: dict[str, QAction]) -> None:
        """File playback: the frame steps and the drift check in the Data menu."""
        if self._runner.replay is None:
            return
        menu.addSeparator()
        for key in ("step_back", "step_fwd", "step_back10", "step_fwd10"):
            menu.addAction(actions[key])
        menu.addSeparator()
        menu.addAction(actions["drift"])
        from bpms.gui.compare_panel import add_compare_action  # docs/compare.md

        add_compare_action(self._window, menu)

    def show_status(self, st: LiveStatus) -> None:
        """The playback and UDP server panels' numbers; the end of a played recording stops
        the data."""
        playback, udp = self._panels.playback_panel, self._panels.udp_panel
        runner = self._runner
        if playback is not None:
            playback.show_status(st)
            if runner.replay is not None and runner.replay.ended and runner.data_on:
                self._commands.set_data(False)
                self._window.statusBar().showMessage("end of the recording", 5000)
                self._panels.event_log.add("end of the recording")
        if udp is not None:
            udp.show_status(st)

    def step_frames(self, n: int) -> None:
        """Playback, paused: move ``n`` frames (the frame is shown in every view)."""
        playback = self._panels.playback_panel
        if playback is not None and not self._runner.replay.playing:
            playback.step(n)

    def open_drift_check(self):
        """A dock with the drift check of the recording being played (computed in the
        background with the playback's calibration, options and filter); None when no
        recording is played."""
        from bpms.gui.drift_panel import drift_dock

        runner = self._runner
        if runner.replay is None or not runner.config.path:
            return None
        dock, panel = drift_dock(self._window)
        self._window.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, dock)
        panel.start(runner.config.path, runner.playback_calibration, runner.playback_options,
                    runner.playback_filter)
        return panel
