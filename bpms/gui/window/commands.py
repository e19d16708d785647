"""The main window's session commands: Start/Stop Data, Reset Zero, markers, the filter and
its gains (typed events for the session, which owns the values in force), LSL, the angle
unit and which angles are shown.

:class:`SessionCommands` is what the menus, toolbar and panels ask of the session; it holds
no state of its own beyond the references it is given.
"""

from __future__ import annotations

from PyQt6.QtCore import QObject, pyqtSignal
from PyQt6.QtWidgets import QMainWindow

from bpms.gui.angle_readout import ContinuousAngles
from bpms.gui.model import SessionModel
from bpms.gui.modes import ModeError, SessionRunner
from bpms.gui.window.panels import WindowPanels, listening_address
from bpms.io.event_types import FilterChoice, Gains
from bpms.io.options import Options


class SessionCommands(QObject):
    """The session's commands. ``window``: where messages show (its status bar) and the
    parent of the marker dialog; ``readout``: the continuous angles shown (restarted when
    other angles are shown). ``dataSwitched(on)`` after Start/Stop Data was asked (on: the
    data is on now)."""

    dataSwitched = pyqtSignal(bool)

    def __init__(self, window: QMainWindow, runner: SessionRunner, model: SessionModel,
                 options: Options, panels: WindowPanels, readout: ContinuousAngles) -> None:
        super().__init__(window)
        self._window = window
        self.runner = runner
        self.model = model
        self.options = options
        self._panels = panels
        self._readout = readout

    def _say(self, text: str, ms: int) -> None:
        self._window.statusBar().showMessage(text, ms)

    def set_data(self, on: bool) -> None:
        """Start Data / Stop Data."""
        if on == self.runner.data_on:
            return
        panels = self._panels
        if on:
            try:
                session = self.runner.start_data()
            except ModeError as exc:
                self._say(str(exc), 10000)
                panels.event_log.add(f"cannot start data: {exc}", "warning")
                return
            if session is not self.model.session:
                self.model.attach(session)
                panels.health_panel.set_listening(listening_address(self.runner))
            self.model.set_data_on(True)
            panels.event_log.add("data started")
        else:
            self.runner.stop_data()
            self.model.set_data_on(False)
            panels.event_log.add("data stopped")
        panels.status_panel.set_streaming(self.runner.data_on)
        self.dataSwitched.emit(self.runner.data_on)

    def reset_zero(self, source: str = "manual") -> None:
        """Reset Zero at the next frame (stand in the calibration pose). The session's event
        says when it was captured and how much the subject moved during its window (a
        warning when too much), in the event log, the recording and the LSL stream."""
        if self.runner.session is None or not self.runner.data_on:
            return
        self.runner.session.reset_zero(source)
        self._say("Reset Zero requested", 3000)

    def add_marker(self, text: str | None = None) -> None:
        """A marker note at the next frame (in the recording, the event log and the LSL event
        stream); without ``text`` it is asked for."""
        if self.runner.session is None:
            return
        if text is None:
            from PyQt6.QtWidgets import QInputDialog

            text, ok = QInputDialog.getText(self._window, "Marker", "Marker note:")
            if not ok:
                return
        if text.strip():
            self.runner.session.marker(text.strip())

    def show_sensor_angles(self, sensor: bool) -> None:
        """View ▸ Sensor angles (uncorrected): the table and the angle plots show ``euler``
        (``sensor``) or the output angles ``euler_output`` (not, the default)."""
        self._panels.table_model.set_show_output(not sensor)
        self._readout.reset()  # other angles: their continuous readout starts again
        self._say("angles shown: " + ("sensor angles (uncorrected)" if sensor
                                      else "output angles (after Reset Zero)"), 3000)

    def set_corrected_output(self, on: bool) -> None:
        """The original's v key: the session's output angles corrected by Reset Zero or not
        (what is shown, recorded and streamed), from the next frame. The session owns it: a
        new session (UDP restarted) starts with the one in force (SessionRunner)."""
        if self.runner.session is not None:  # the session's event says it, at its frame
            self.runner.session.set_corrected_output(on)

    def set_lsl(self, on: bool) -> bool:
        """Stream to LSL on/off (SessionRunner.set_lsl), the reason when it cannot start;
        whether it streams now."""
        why = self.runner.set_lsl(on)
        if why:
            self._say(f"LSL: {why}", 10000)
            self._panels.event_log.add(f"LSL streaming not started: {why}", "warning")
            return False
        self._panels.event_log.add("LSL streaming " + ("on" if self.runner.lsl_on else "off"))
        return self.runner.lsl_on

    def set_gains(self, change: Gains) -> None:
        """A :class:`Gains` the panel made (checked when made: the one check) for the
        session, which owns the values in force; the panel then shows what it reports."""
        self._send(change)

    def select_filter(self, change: FilterChoice) -> None:
        """A :class:`FilterChoice`: all 18 IMUs switch filter (Reset Zero is kept)."""
        self._send(change)
        self._say(f"filter: {change.algorithm}", 3000)  # (the event: the session)

    def _send(self, change: Gains | FilterChoice) -> None:
        session = self.runner.session
        if session is not None:
            session.change(change)  # applied before the next frame
            st = session.status()
            self._panels.gains_panel.show_settings(st.filter_settings, st.settings_pending)

    def set_angle_unit(self, unit: str) -> None:
        self._panels.table_model.set_angle_unit(unit)
        self._panels.joint_model.set_angle_unit(unit)
        self.options.display.angle_unit = unit

    def toggle_unit(self) -> None:
        """deg ⇄ rad (through the unit box, which says it)."""
        combo = self._panels.unit_combo
        combo.setCurrentText("rad" if combo.currentText() == "deg" else "deg")
