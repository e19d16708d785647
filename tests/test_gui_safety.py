"""Safe controls (issue 15.3): the wheel changes nothing it is not focused on, a double click
toggles once, an empty UDP target is refused, and stopping a recording never blocks the GUI."""

from __future__ import annotations

import threading

from PyQt6.QtCore import QPoint, QPointF, Qt
from PyQt6.QtGui import QWheelEvent
from PyQt6.QtWidgets import QApplication, QScrollArea

from bpms.gui.controls import GainsPanel
from bpms.gui.main_window import MainWindow
from bpms.gui.modes import ModeConfig, SessionRunner
from bpms.gui.safety import DEBOUNCE_S
from bpms.io.options import Options


def _wheel(widget, steps: int = -3) -> None:
    """A real wheel event (120 units per notch) over the widget's centre."""
    centre = QPointF(widget.rect().center())
    event = QWheelEvent(centre, QPointF(widget.mapToGlobal(centre.toPoint())), QPoint(),
                        QPoint(0, 120 * steps), Qt.MouseButton.NoButton,
                        Qt.KeyboardModifier.NoModifier, Qt.ScrollPhase.NoScrollPhase, False)
    QApplication.sendEvent(widget, event)


def test_wheel_over_an_unfocused_control_changes_nothing(qtbot):
    panel = GainsPanel(Options().filter)
    scroll = QScrollArea()
    scroll.setWidget(panel)
    qtbot.addWidget(scroll)
    scroll.show()
    qtbot.waitExposed(scroll)
    combo, edit = panel.filter_combo, panel.edits["kp_yaw"]
    filters: list[str] = []
    gains: list[dict] = []
    panel.filterChanged.connect(filters.append)
    panel.gainsChanged.connect(gains.append)
    before = (combo.currentText(), edit.text())
    for widget in (combo, edit):
        assert not widget.hasFocus()
        _wheel(widget, -3)
        _wheel(widget, +3)
    assert (combo.currentText(), edit.text()) == before
    assert filters == [] and gains == []
    # the same wheel on a focused control does change it (the event really reaches it)
    combo.setFocus()
    qtbot.waitUntil(combo.hasFocus, timeout=2000)
    _wheel(combo, -1)
    assert combo.currentText() != before[0] and filters


def _sim_window(qtbot, tmp_path) -> MainWindow:
    runner = SessionRunner(ModeConfig(mode="sim", recording_dir=str(tmp_path)), Options())
    runner.prepare()
    window = MainWindow(runner)
    qtbot.addWidget(window)
    window.show()
    return window


def test_double_click_toggles_once_and_an_empty_target_is_refused(qtbot, tmp_path):
    window = _sim_window(qtbot, tmp_path)
    try:
        panel = window.panels.udp_panel
        panel.targets_edit.setText("   ")
        panel.button.click()
        assert not panel.on and window.runner.session.status().forwarding == []
        assert "no target" in panel.status_label.text()
        qtbot.wait(int(DEBOUNCE_S * 1000) + 100)
        panel.targets_edit.setText("127.0.0.1:9")
        panel.button.click()
        panel.button.click()  # the second click of a double click
        assert panel.on and window.runner.session.status().forwarding == ["127.0.0.1:9"]
        qtbot.wait(int(DEBOUNCE_S * 1000) + 100)  # a deliberate second click, later
        panel.button.click()
        assert not panel.on
        # Start Data double-clicked: data stays on
        window.panels.status_panel.data_button.click()
        window.panels.status_panel.data_button.click()
        assert window.runner.data_on
    finally:
        window.close()


def test_stopping_a_recording_closes_the_files_off_the_gui_thread(qtbot, tmp_path):
    window = _sim_window(qtbot, tmp_path)
    try:
        window.commands.set_data(True)
        session = window.runner.session
        threads: list[str] = []
        stop = session.stop_logging

        def watched_stop():
            threads.append(threading.current_thread().name)
            return stop()

        session.stop_logging = watched_stop
        panel = window.panels.file_panel
        panel.name_edit.setText("bg")
        panel.log_button.click()
        qtbot.waitUntil(lambda: session.status().recording.raw_records > 20, timeout=15000)
        qtbot.wait(int(DEBOUNCE_S * 1000) + 100)
        threads.clear()  # (start_logging closes any previous recording itself)
        panel.log_button.click()
        qtbot.waitUntil(lambda: not panel.busy and panel.last_recording is not None,
                        timeout=15000)
        assert threads == ["bpms-stop-logging"]
        assert panel.log_button.text() == "Start Logging" and panel.log_button.isEnabled()
        rec = panel.last_recording
        assert rec.raw_path.exists() and rec.raw_records > 20
    finally:
        window.close()
