"""Whole GUI sessions (pytest-qt, offscreen): start-up → GO → Start Data → Reset Zero →
select cells → plot → logging raw + filtered → stop, in simulated-suit, file and UDP modes."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from gui_start import open_main_window
from PyQt6.QtCore import Qt

from bpms.firmware.sim.session import simulate
from bpms.gui.columns import COLUMNS
from bpms.gui.main_window import MainWindow
from bpms.gui.startup import StartupWindow
from bpms.io.filtered_file.reader import read_filtered
from bpms.io.rawfile import read_raw

ROOT = Path(__file__).resolve().parents[1]
SIX_CELLS = [(0, 13), (4, 4), (5, 8), (8, 0), (12, 1), (17, 2)]  # raw, cal, euler


@pytest.fixture(scope="module")
def recording_path(tmp_path_factory) -> Path:
    rec = simulate(duration_s=12.0, seed=2)
    path = tmp_path_factory.mktemp("rec") / "Raw_sim_001.bpmsraw"
    return rec.save_raw(path, notes="simulated")



def _frames(window: MainWindow) -> int:
    status = window.model.last_status
    return status.processed if status is not None else 0


def _rows(window: MainWindow) -> int:
    recording = window.runner.session.status().recording
    return recording.filtered_rows if recording is not None else 0


def _plot_six(qtbot, window: MainWindow):
    window.panels.table.select_cells(SIX_CELLS)
    assert window.panels.table.selected_cells() == SIX_CELLS
    plot = window.views.plot_selection()
    labels = [c.name() for c in plot.curves]
    assert labels[0] == "Right Leg raw acc x [counts]"
    assert labels[1] == "Right Arm acc x [m/s²]"
    assert labels[3] == "Spine roll [deg]"
    qtbot.waitUntil(lambda: len(plot.buffer) > 20, timeout=10000)
    x, y = plot.curves[3].getData()
    assert len(x) > 20 and np.isfinite(y[-5:]).all()
    return plot


def _log(qtbot, window: MainWindow, raw: bool, name: str):
    panel = window.panels.file_panel
    panel.name_edit.setText(name)
    panel.raw_box.setChecked(raw)
    panel.filtered_box.setChecked(True)
    panel.log_button.click()
    assert panel.logging
    qtbot.waitUntil(lambda: _rows(window) >= 60, timeout=15000)
    panel.log_button.click()  # the files close in the background
    qtbot.waitUntil(lambda: not panel.busy and not panel.logging, timeout=15000)
    return panel.last_recording


def test_simulated_suit_session(qtbot, tmp_path):
    startup = StartupWindow(recording_dir=str(tmp_path))
    qtbot.addWidget(startup)
    startup.select_mode("sim")
    window = open_main_window(qtbot, startup)
    assert not startup.isVisible()
    assert window.panels.udp_panel is not None and window.panels.playback_panel is None
    # the simulated suit streams at once (one click on GO shows live data)
    assert window.runner.data_on and window.panels.status_panel.reset_button.isEnabled()
    qtbot.waitUntil(lambda: _frames(window) > 25, timeout=15000)
    assert window.model.last_status.source.battery_v == pytest.approx(3.35, abs=0.05)
    window.panels.status_panel.reset_button.click()
    # the table shows the newest sample, units in the headers
    model = window.panels.table_model
    # the output angles after Reset Zero: the segment angles, and the header says so
    qtbot.waitUntil(lambda: model.headerData(0, Qt.Orientation.Horizontal)
                    == "roll (segment) [deg]", timeout=10000)
    window.panels.unit_combo.setCurrentText("rad")
    assert COLUMNS[0].label(model.angle_unit) == "roll [rad]"
    assert abs(model.value(8, 0)) < 2 * np.pi
    window.panels.unit_combo.setCurrentText("deg")
    _plot_six(qtbot, window)
    joints = window.views.open_joint_plot()
    assert len(joints.curves) == 28
    # gains at run time reach the filter bank (applied between two frames)
    window.panels.gains_panel.edits["kp_yaw"].setText("0.5")
    window.panels.gains_panel.edits["kp_yaw"].editingFinished.emit()
    bank = window.runner.session.processor.bank
    qtbot.waitUntil(lambda: bank.params[2] == 0.5, timeout=5000)
    # UDP server: the live stream goes to the configured target
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sink:
        sink.bind(("127.0.0.1", 0))
        sink.settimeout(5.0)
        window.panels.udp_panel.targets_edit.setText(f"127.0.0.1:{sink.getsockname()[1]}")
        window.panels.udp_panel.button.click()
        assert len(sink.recv(2048)) > 340
        qtbot.wait(600)  # a second click within 0.5 s would be ignored (debounced)
        window.panels.udp_panel.button.click()
        assert not window.panels.udp_panel.on
    rec = _log(qtbot, window, raw=True, name="guisim")
    window.panels.status_panel.data_button.click()  # Stop Data
    assert not window.runner.data_on
    raw = read_raw(rec.raw_path)
    filtered = read_filtered(rec.filtered_path)
    assert rec.raw_path.name == "Raw_guisim_1.bpmsraw"
    assert len(raw) == rec.raw_records >= 60
    assert len(filtered.t) >= 60
    # the simulated suit's frames, in order: consecutive motion samples
    motion = window.runner.sim.arbiter.source
    frames = raw.frames.tobytes()
    first = next(j for j in range(len(motion)) if motion.frame(j) == frames[:340])
    assert frames == b"".join(motion.frame(first + j) for j in range(len(raw)))
    window.close()
    assert window.runner.session is not None and not window.runner.session.running
    assert startup.isVisible()  # back to the start-up window


def test_file_mode_session(qtbot, tmp_path, recording_path):
    startup = StartupWindow(recording_dir=str(tmp_path))
    qtbot.addWidget(startup)
    startup.select_mode("file")
    startup.file_edit.setText(str(recording_path))
    window = open_main_window(qtbot, startup)
    panel = window.panels.playback_panel
    assert panel is not None and window.panels.udp_panel is None
    assert not window.panels.file_panel.raw_box.isEnabled()  # raw recording disabled in file mode
    panel.slider.setValue(100)  # seek to 2 s while stopped: that frame is shown
    qtbot.waitUntil(lambda: window.model.latest is not None, timeout=10000)
    assert window.model.latest.index == 100
    assert window.panels.table_model.has_data and window.panels.table_model.data(
        window.panels.table_model.index(0, 13)) == str(window.model.latest.raw[0, 0])
    window.panels.status_panel.data_button.click()  # play
    qtbot.waitUntil(lambda: not panel.slider.isEnabled(), timeout=5000)
    assert not panel.speed_combo.isEnabled()
    qtbot.waitUntil(lambda: window.model.latest is not None, timeout=10000)
    assert window.model.latest.index >= 100
    window.panels.status_panel.reset_button.click()
    plot = _plot_six(qtbot, window)
    data = plot.buffer.view()  # time axis: frame index × 20 ms; the paused seek to 2 s drew
    assert data[0, 0] == 0.0 and data[-1, 0] >= 2.0  # the plots' window from the file start
    qtbot.wait(600)  # (a second click within 0.5 s is ignored)
    window.panels.status_panel.data_button.click()  # pause
    assert not window.runner.replay.playing
    qtbot.waitUntil(lambda: panel.slider.isEnabled(), timeout=5000)
    panel.speed_combo.setCurrentIndex(6)  # max
    assert window.runner.replay.speed is None
    rec = _log_during_play(qtbot, window)
    assert rec.raw_path is None
    filtered = read_filtered(rec.filtered_path)
    assert len(filtered.t) >= 60
    # the time column is the file's frame index × 20 ms: rows of this recording
    assert filtered.t[0] >= 2.0 and filtered.t[-1] <= 12.0
    window.close()


def _log_during_play(qtbot, window: MainWindow):
    panel = window.panels.file_panel
    panel.filtered_box.setChecked(True)
    panel.name_edit.setText("guifile")
    panel.log_button.click()
    qtbot.wait(600)  # (a second click within 0.5 s is ignored)
    window.panels.status_panel.data_button.click()  # play on
    qtbot.waitUntil(lambda: _rows(window) >= 60, timeout=15000)
    qtbot.wait(600)  # (a second click within 0.5 s is ignored)
    window.panels.status_panel.data_button.click()  # pause
    panel.log_button.click()
    qtbot.waitUntil(lambda: not panel.busy and not panel.logging, timeout=15000)
    return panel.last_recording


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _udp_client_window(qtbot, tmp_path) -> tuple[int, MainWindow]:
    """GO in UDP client mode on a free port, data on: (port, main window)."""
    port = _free_udp_port()
    startup = StartupWindow(recording_dir=str(tmp_path))
    qtbot.addWidget(startup)
    startup.select_mode("udp")
    startup.listen_edit.setText(f"127.0.0.1:{port}")
    window = open_main_window(qtbot, startup)
    window.panels.status_panel.data_button.click()
    return port, window


def test_udp_client_session(qtbot, tmp_path, recording_path):
    port, window = _udp_client_window(qtbot, tmp_path)
    sender = subprocess.Popen(
        [sys.executable, "-m", "bpms", "replay", str(recording_path), "--udp",
         f"127.0.0.1:{port}", "--speed", "2", "--loop"],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        qtbot.waitUntil(lambda: _frames(window) > 25, timeout=20000)
        window.panels.status_panel.reset_button.click()
        _plot_six(qtbot, window)
        rec = _log(qtbot, window, raw=False, name="guiudp")
    finally:
        sender.terminate()
        sender.wait(10)
    filtered = read_filtered(rec.filtered_path)
    assert len(filtered.t) >= 60
    window.panels.status_panel.data_button.click()  # Stop Data: the session stops
    assert not window.runner.session.running
    window.close()


def test_a_udp_flood_does_not_freeze_the_gui(qtbot, tmp_path, recording_path):
    """Frames as fast as `bpms replay --speed 0` sends them: the display timer keeps running,
    each tick drains a bounded mailbox, and what cannot be shown is counted, not queued."""
    port, window = _udp_client_window(qtbot, tmp_path)
    window.panels.table.select_cells(SIX_CELLS)
    window.views.plot_selection()
    batches: list[int] = []
    window.model.samplesArrived.connect(lambda samples: batches.append(len(samples)))
    sender = subprocess.Popen(
        [sys.executable, "-m", "bpms", "replay", str(recording_path), "--udp",
         f"127.0.0.1:{port}", "--speed", "0", "--loop"],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        qtbot.waitUntil(lambda: sum(batches) > 1500, timeout=30000)
        ticks_before = len(batches)
        qtbot.waitUntil(lambda: len(batches) >= ticks_before + 5, timeout=20000)
    finally:
        sender.terminate()
        sender.wait(10)
    assert max(batches) <= 3000  # the mailbox bound: never an unbounded backlog in the GUI
    assert max(batches) > 2  # several frames per tick: one redraw per tick, not per frame
    window.close()


def test_each_filter_is_selectable_in_the_gui(qtbot, tmp_path, recording_path):
    """Issue 9: the filter chosen in the options reaches the session, and the main window's
    filter selector switches all 18 IMUs at run time; every filter gives a pose."""
    from bpms.io.options import Options

    options = Options()
    options.filter.algorithm = "observer"
    startup = StartupWindow(options=options, recording_dir=str(tmp_path))
    qtbot.addWidget(startup)
    startup.select_mode("file")
    startup.file_edit.setText(str(recording_path))
    window = open_main_window(qtbot, startup)
    processor = window.runner.session.processor
    # playback: the recording's own filter, not the app's options' (issue 44.2)
    assert processor.options.filter.algorithm == "mahony"
    combo = window.panels.gains_panel.filter_combo
    assert combo.currentText() == "mahony"
    window.panels.status_panel.data_button.click()  # play
    for algorithm in ("mahony", "vqf", "observer"):
        combo.setCurrentText(algorithm)
        qtbot.waitUntil(lambda a=algorithm: processor.options.filter.algorithm == a,
                        timeout=10000)
        after = window.model.latest.index if window.model.latest is not None else -1
        qtbot.waitUntil(lambda a=after: window.model.latest is not None
                        and window.model.latest.index > a + 25, timeout=15000)
        assert np.isfinite(window.model.latest.euler).all()
    window.panels.status_panel.data_button.click()  # pause
    window.close()
