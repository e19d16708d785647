"""The recording reproduces the session, in the desktop app (issue 25; pytest-qt, offscreen): a
session on the simulated suit with Reset Zero, a gain change and a marker, recorded raw and
filtered; then GUI playback of that raw recording, recording a filtered file: it equals the
one written live (the recorded events applied at their frames). The labels beside the numbers
come from the processor that made them."""

from __future__ import annotations

import numpy as np
from gui_start import open_main_window
from waiting import wait_until

from bpms.gui.main_window import MainWindow
from bpms.gui.startup import StartupWindow
from bpms.io.filtered_file.reader import read_filtered
from bpms.io.rawfile import read_raw

TOL = 1e-9  # rad: the two files hold the same numbers to their 10 significant digits



def _rows(window: MainWindow) -> int:
    recording = window.runner.session.status().recording
    return recording.filtered_rows if recording is not None else 0


def _start_logging(qtbot, window: MainWindow, name: str, raw: bool) -> None:
    panel = window.panels.file_panel
    panel.name_edit.setText(name)
    if panel.raw_box.isEnabled():
        panel.raw_box.setChecked(raw)
    panel.filtered_box.setChecked(True)
    panel.log_button.click()
    assert panel.logging


def _stop_logging(qtbot, window: MainWindow):
    panel = window.panels.file_panel
    qtbot.wait(600)  # (a second click within 0.5 s is ignored)
    panel.log_button.click()
    qtbot.waitUntil(lambda: not panel.busy and not panel.logging, timeout=15000)
    return panel.last_recording


def _quiet(window: MainWindow) -> bool:
    """No frame came for 0.3 s (the suit heard Stop Data)."""
    before = window.runner.session.status().frames
    return not wait_until(lambda: window.runner.session.status().frames != before, 0.3)


def test_gui_playback_records_the_filtered_file_written_live(qtbot, tmp_path):
    startup = StartupWindow(recording_dir=str(tmp_path))
    qtbot.addWidget(startup)
    startup.select_mode("sim")
    window = open_main_window(qtbot, startup)  # the simulated suit streams at once
    session = window.runner.session
    qtbot.waitUntil(lambda: session.status().processed > 60, timeout=15000)
    # labels from the processor: the calibration, options and filter it runs with
    panel = window.panels.status_panel
    proc = session.processor
    qtbot.waitUntil(lambda: panel.labels["reset_zero"].text().startswith("automatic at "),
                    timeout=15000)
    assert panel.labels["calibration"].text() == proc.calibration_source
    assert panel.labels["filter"].text() == "mahony"
    # logging from the start of a run of the stream: Stop Data, Start Logging, Start Data
    window.commands.set_data(False)
    assert wait_until(lambda: _quiet(window), 10)
    _start_logging(qtbot, window, "guilive", raw=True)
    qtbot.wait(600)
    window.commands.set_data(True)
    qtbot.waitUntil(lambda: _rows(window) >= 100, timeout=15000)
    window.commands.reset_zero()
    qtbot.waitUntil(lambda: panel.labels["reset_zero"].text().startswith("manual at "),
                    timeout=10000)
    qtbot.waitUntil(lambda: _rows(window) >= 200, timeout=15000)
    window.panels.gains_panel.edits["kp_yaw"].setText("0.5")
    window.panels.gains_panel.edits["kp_yaw"].editingFinished.emit()
    qtbot.waitUntil(lambda: proc.options.filter.kp_yaw == 0.5, timeout=5000)
    qtbot.waitUntil(lambda: _rows(window) >= 300, timeout=15000)
    window.commands.add_marker("the subject waves")
    qtbot.waitUntil(lambda: _rows(window) >= 350, timeout=15000)
    live_rec = _stop_logging(qtbot, window)
    window.commands.set_data(False)
    texts = window.panels.event_log.texts()
    assert any(t.startswith("Reset Zero (manual) at ") for t in texts), texts
    assert any("marker at" in t and "the subject waves" in t for t in texts), texts
    window.close()
    raw = read_raw(live_rec.raw_path)
    kinds = [e.kind for _, e in raw.events]
    assert {"reset_zero", "gains", "marker", "filters"} <= set(kinds)
    live = read_filtered(live_rec.filtered_path)
    assert len(live.t) == len(raw) and live.t[0] == 0.0

    # playback of that recording, recording the filtered file as it plays
    startup.select_mode("file")
    startup.file_edit.setText(str(live_rec.raw_path))
    player = open_main_window(qtbot, startup)
    assert player.panels.status_panel.labels["calibration"].text() == "recording header"
    replay = player.runner.replay
    player.panels.playback_panel.speed_combo.setCurrentIndex(6)  # as fast as possible
    _start_logging(qtbot, player, "guiplayback", raw=False)
    qtbot.wait(600)
    player.commands.set_data(True)
    qtbot.waitUntil(lambda: replay.ended and _rows(player) == len(raw), timeout=30000)
    played_rec = _stop_logging(qtbot, player)
    player.commands.set_data(False)
    assert any(t.startswith("Reset Zero (manual) at ") for t in player.panels.event_log.texts())
    player.close()
    played = read_filtered(played_rec.filtered_path)
    np.testing.assert_array_equal(played.t, live.t)
    np.testing.assert_allclose(played.euler, live.euler, rtol=0, atol=TOL)
    np.testing.assert_allclose(played.joint_angles, live.joint_angles, rtol=0, atol=TOL)
    for group in ("corrected", "mag_disturbed", "acc_disturbed"):
        np.testing.assert_array_equal(played.groups[group], live.groups[group])
