"""What the main window shows of the newer pipeline data: Reset Zero corrected output angles
(issue 12.5), health (14, 18), the sources in force (12.2), disturbance flags (19.2) and the
LSL switch (16.1). Real windows on the simulated suit, a recording or a real UDP stream."""

from __future__ import annotations

import dataclasses
import socket
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PyQt6.QtCore import Qt, QTimer

from bpms.firmware.sim.session import simulate
from bpms.gui.data_table import DISTURBANCE_COLUMN
from bpms.gui.layouts import LayoutStore
from bpms.gui.main_window import MainWindow
from bpms.gui.modes import ModeConfig, SessionRunner
from bpms.gui.plot_data import TickBlock, cell_curve
from bpms.io.options import Options
from bpms.io.udp.sender import UdpForwarder
from bpms.pipeline.sample import PoseSample
from bpms.pipeline.session import RecordingStatus

_H = Qt.Orientation.Horizontal


@pytest.fixture(scope="module")
def recording_path(tmp_path_factory) -> Path:
    rec = simulate(duration_s=6.0, seed=4)
    return rec.save_raw(tmp_path_factory.mktemp("rec") / "Raw_wiring_001.bpmsraw")


def _window(qtbot, tmp_path, config: ModeConfig) -> MainWindow:
    runner = SessionRunner(config, Options())
    runner.prepare()
    window = MainWindow(runner, layout_store=LayoutStore(tmp_path / "layouts.json"),
                        restore_last=False)
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    return window


def _file_window_at(qtbot, tmp_path, path: Path, index: int = 150) -> MainWindow:
    """A paused playback showing frame ``index``; the display timer then detached, so the
    test alone feeds the window."""
    window = _window(qtbot, tmp_path, ModeConfig(mode="file", path=str(path),
                                                 recording_dir=str(tmp_path)))
    window.runner.show_frame(index)
    qtbot.waitUntil(lambda: window.model.latest is not None
                    and window.model.latest.index == index, timeout=20000)
    return window


def _texts(window: MainWindow) -> list[str]:
    return [text for _, _, text in window.panels.event_log.entries]


def _same_rotations(a: np.ndarray, b: np.ndarray) -> bool:
    from bpms.filter.rotations import euler_to_dcm

    return np.allclose(euler_to_dcm(*np.moveaxis(a, -1, 0)),
                       euler_to_dcm(*np.moveaxis(b, -1, 0)), atol=1e-9)


def test_output_angles_by_default_sensor_angles_on_switch_and_v_toggles(qtbot, tmp_path):
    window = _window(qtbot, tmp_path, ModeConfig(mode="sim", recording_dir=str(tmp_path)))
    last = [None]

    def grab(samples):
        last[0] = samples[-1]
    window.model.samplesArrived.connect(grab)
    window.commands.set_data(True)
    model = window.panels.table_model
    qtbot.waitUntil(lambda: last[0] is not None and last[0].index > 30, timeout=20000)
    window.commands.reset_zero()
    # after Reset Zero the output angles are the segment angles: not the sensor angles
    qtbot.waitUntil(lambda: model.headerData(0, _H) == "roll (segment) [deg]", timeout=15000)
    assert model.headerData(2, _H) == "yaw (segment) [deg]"
    window.model.attach(None)  # hold still: the test compares the last sample shown
    s = last[0]
    assert not np.allclose(s.euler_output, s.euler)  # Reset Zero turned them
    # the same rotations (the table shows their continuous readout: docs/main-window.md)
    assert _same_rotations(model.euler, s.euler_output)
    assert model.data(model.index(5, 0)) == f"{np.degrees(model.euler[5, 0]):.2f}"
    # the plots' block (each tick's, and what a new plot starts with)
    calibration = model.calibration
    assert np.array_equal(TickBlock.from_samples([s], calibration, model.show_output).euler[0],
                          s.euler_output)
    # View ▸ Sensor angles (uncorrected): the filter's angles, said in the headers
    window.menus.actions_by_name["sensor_angles"].trigger()
    window.display.on_samples([s])
    assert np.array_equal(model.euler, s.euler)  # the readout starts again: as given
    assert model.headerData(0, _H) == "roll (sensor) [deg]"
    assert model.data(model.index(5, 0)) == f"{np.degrees(s.euler[5, 0]):.2f}"
    assert np.array_equal(TickBlock.from_samples([s], calibration, model.show_output).euler[0],
                          s.euler)
    window.menus.actions_by_name["sensor_angles"].trigger()
    window.display.on_samples([s])
    assert model.headerData(0, _H) == "roll (segment) [deg]"
    # the original's v key (in the table): the session's output loses its correction
    processor = window.runner.session.processor
    assert processor.corrected_output
    window.activateWindow()
    window.panels.table.setFocus()
    qtbot.waitUntil(window.panels.table.hasFocus, timeout=5000)
    qtbot.keyClick(window.panels.table, Qt.Key.Key_V)
    assert not window.menus.actions_by_name["corrected"].isChecked()
    window.model.attach(window.runner.session)
    qtbot.waitUntil(lambda: not processor.corrected_output, timeout=10000)
    qtbot.waitUntil(lambda: model.headerData(0, _H) == "roll (sensor) [deg]", timeout=10000)
    latest = window.model.latest
    assert np.array_equal(latest.euler_output, latest.euler, equal_nan=True)
    # the session's event (the line its recording and LSL stream hold), at its frame
    qtbot.waitUntil(lambda: any(t.startswith("alignment off (sensor angles) at ")
                                for t in _texts(window)), timeout=10000)
    window.commands.set_data(False)
    window.close()


def test_health_panel_shows_losses_write_errors_and_the_source_reason(qtbot, tmp_path,
                                                                     recording_path):
    window = _file_window_at(qtbot, tmp_path, recording_path)
    window.model.attach(None)
    panel = window.panels.health_panel
    base = window.runner.session.status()
    rec = RecordingStatus(raw_path=tmp_path / "Raw_x_001.bpmsraw",
                          error="[Errno 28] No space left on device")
    down = dataclasses.replace(base.source, state="gone", reason="the port vanished")
    st = dataclasses.replace(base, not_filtered=7, processing_backlog=12, display_skipped=3,
                             recording=rec, source=down)
    window.commands.set_data(True)
    window.display.refresh_texts()
    window.display.on_status(st)
    label = panel.labels["not_filtered"]
    assert label.text().startswith("7 frames") and "#d62728" in label.styleSheet()
    assert panel.labels["backlog"].text() == "12 frames"
    assert panel.labels["skipped"].text() == "3 samples"
    assert panel.rec_error_label.isVisible()
    assert "No space left on device" in panel.rec_error_label.text()
    assert panel.source_label.text() == "gone: the port vanished"
    assert "#d62728" in panel.source_label.styleSheet()
    assert "NOT FILTERED 7" in window.panels.status_panel.labels["dropped"].text()
    # no loss: not red; logging stopped: the write error goes; a warning is amber
    amber = dataclasses.replace(base.source, warning="another sender (10.0.0.9:5005) on "
                                                     "this port: ignored")
    window.display.refresh_texts()
    window.display.on_status(dataclasses.replace(base, source=amber, recording=None))
    assert panel.labels["not_filtered"].text() == "0 frames"
    assert panel.labels["not_filtered"].styleSheet() == ""
    assert not panel.rec_error_label.isVisible()
    assert panel.source_label.text().startswith("another sender")
    assert "#f0a000" in panel.source_label.styleSheet()
    assert any("another sender (10.0.0.9:5005)" in t for t in _texts(window))
    # every state-guard re-initialisation is an event
    window.display.on_status(dataclasses.replace(base, reinit_count=2))
    window.display.on_status(dataclasses.replace(base, reinit_count=2))
    window.display.on_status(dataclasses.replace(base, reinit_count=3))
    reinit = [t for t in _texts(window) if "state guard" in t]
    assert reinit == ["filter re-initialised by the state guard (2 re-initialisations, 2 so "
                      "far)", "filter re-initialised by the state guard (1 "
                      "re-initialisation, 3 so far)"]
    # when the session's own event line says it, the window does not say it again
    said = "12:00:00 filter re-initialised (state not a rotation): IMU 4; 5 so far"
    window.display.on_status(dataclasses.replace(base, reinit_count=5, events=[said]))
    lines = [t for t in _texts(window) if "filter re-initialised" in t]
    assert lines[-1] == said.partition(" ")[2] and len(lines) == 3
    window.commands.set_data(False)
    window.close()


def _send(forwarder: UdpForwarder, frames: list[bytes], state: dict) -> None:
    k = state["k"]
    forwarder.send_frame(frames[k % len(frames)], k * 0.02)
    state["k"] = k + 1


def test_udp_client_shows_its_address_and_another_sender(qtbot, tmp_path, recording_path):
    from bpms.io.rawfile import read_raw

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    window = _window(qtbot, tmp_path, ModeConfig(mode="udp", listen=f"127.0.0.1:{port}"))
    assert window.panels.health_panel.listening_label.isVisibleTo(window.panels.health_panel)
    assert window.panels.health_panel.listening_label.text().startswith(f"127.0.0.1:{port}")
    window.commands.set_data(True)
    raw = read_raw(recording_path).frames.tobytes()
    frames = [raw[i:i + 340] for i in range(0, len(raw), 340)]
    first, second = UdpForwarder([f"127.0.0.1:{port}"]), UdpForwarder([f"127.0.0.1:{port}"])
    one, two = {"k": 0}, {"k": 0}
    timer = QTimer()
    timer.timeout.connect(lambda: _send(first, frames, one))
    timer.start(20)
    try:
        qtbot.waitUntil(lambda: window.runner.session.status().frames > 20, timeout=15000)
        other = QTimer()
        other.timeout.connect(lambda: _send(second, frames, two))
        other.start(20)
        try:
            qtbot.waitUntil(lambda: any("another sender" in t for t in _texts(window)),
                            timeout=15000)
            qtbot.waitUntil(lambda: "another sender" in
                            window.panels.health_panel.source_label.text(), timeout=5000)
        finally:
            other.stop()
    finally:
        timer.stop()
        first.close()
        second.close()
    assert "#f0a000" in window.panels.health_panel.source_label.styleSheet()
    window.commands.set_data(False)
    window.close()


def test_the_data_panel_shows_where_calibration_and_options_came_from(qtbot, tmp_path,
                                                                      recording_path):
    window = _window(qtbot, tmp_path, ModeConfig(mode="file", path=str(recording_path),
                                                 recording_dir=str(tmp_path)))
    labels = window.panels.status_panel.labels
    # playback: the one door took both from the recording's header (it holds them)
    assert labels["calibration"].text() == window.runner.calibration_source
    assert labels["options"].text() == window.runner.options_source
    assert "header" in labels["calibration"].text() or "recording" in \
        labels["calibration"].text()
    window.close()
    sim = _window(qtbot, tmp_path, ModeConfig(mode="sim", recording_dir=str(tmp_path)))
    # no user default saved (tests use a fresh folder): factory values
    assert sim.panels.status_panel.labels["calibration"].text() == "factory"
    assert sim.panels.status_panel.labels["options"].text() == "factory"
    sim.close()


def test_disturbance_flags_reach_the_table_and_the_status(qtbot, tmp_path, recording_path):
    window = _file_window_at(qtbot, tmp_path, recording_path)
    s = window.model.latest
    window.model.attach(None)
    # the processor's per-frame indicators travel with each sample
    assert s.mag_disturbed is not None and s.mag_disturbed.shape == (18,)
    assert s.acc_disturbed is not None and s.acc_disturbed.dtype == bool
    model = window.panels.table_model
    header = window.panels.table.horizontalHeader()
    # shown beside the error flags (the model keeps it last: cell indices stay put)
    assert header.visualIndex(DISTURBANCE_COLUMN) == 4
    assert model.headerData(DISTURBANCE_COLUMN, _H) == "disturbance"
    mag = np.zeros(18, bool)
    acc = np.zeros(18, bool)
    mag[[2, 7]] = True
    acc[[7, 11]] = True
    window.display.on_samples([s.replace(mag_disturbed=mag, acc_disturbed=acc)])
    acc[11] = False
    # 99 frames (1.98 s) later: the flags still up say since when (their kind first)
    later = PoseSample(s.index + 99, s.host_time, s.frame, s.raw, s.errors, s.euler, s.R, s.C,
                       s.joint_angles, s.joint_positions, euler_output=s.euler_output,
                       mag_disturbed=mag, acc_disturbed=acc, estimates=s.estimates)
    window.display.on_samples([later])
    texts = [model.data(model.index(i, DISTURBANCE_COLUMN)) for i in range(18)]
    assert texts[2] == "mag 2.0 s" and texts[7] == "mag 2.0 s, acc 2.0 s" and texts[11] == ""
    assert sum(bool(t) for t in texts) == 2
    tip = model.data(model.index(7, DISTURBANCE_COLUMN), Qt.ItemDataRole.ToolTipRole)
    assert "mag: up for 2.0 s" in tip and "acc: up for 2.0 s" in tip
    table = window.panels.table
    assert table.columnWidth(DISTURBANCE_COLUMN) \
        >= table.fontMetrics().horizontalAdvance("mag 59 min, acc 59 min")
    colour = model.data(model.index(2, DISTURBANCE_COLUMN), Qt.ItemDataRole.ForegroundRole)
    assert colour.name() == "#c77c00"
    window.display.refresh_texts()
    window.display.on_status(window.runner.session.status())
    label = window.panels.health_panel.labels["disturbance"]
    assert label.text() == "mag 2 IMUs, acc 1 IMU" and "#f0a000" in label.styleSheet()
    # not plottable, not draggable
    window.panels.table.select_cells([(2, DISTURBANCE_COLUMN), (2, 0)])
    assert window.panels.table.selected_cells() == [(2, 0)]
    window.close()


def test_stream_to_lsl_switch(qtbot, tmp_path, recording_path, monkeypatch):
    window = _window(qtbot, tmp_path, ModeConfig(mode="file", path=str(recording_path),
                                                 recording_dir=str(tmp_path)))
    action = window.menus.actions_by_name["lsl"]
    assert action.isCheckable() and action in window.menus.toolbar.actions()
    # the module cannot be imported (pylsl missing): the reason is shown, the switch stays off
    monkeypatch.setitem(sys.modules, "bpms.pipeline.lsl", None)
    action.trigger()
    assert not action.isChecked() and not window.runner.lsl_on
    assert any(t.startswith("LSL streaming not started") and "pylsl" in t
               for t in _texts(window))
    monkeypatch.delitem(sys.modules, "bpms.pipeline.lsl")
    cfg = tmp_path / "lsl_api.cfg"
    cfg.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
                   f"[lab]\nKnownPeers = {{127.0.0.1}}\nSessionID = bpms-wiring-{time.time()}\n")
    monkeypatch.setenv("LSLAPICFG", str(cfg))
    action.trigger()
    try:
        assert action.isChecked() and window.runner.lsl_on
        assert _texts(window)[-1] == "LSL streaming on"
    finally:
        window.runner.set_lsl(False)
    window.close()


def test_filter_estimates_are_table_columns_and_plot_curves(qtbot, tmp_path, recording_path):
    """Issue 19.4: the observer's gyro-bias and body-acceleration estimates travel with each
    sample, show in their table columns and can be plotted like any cell."""
    from bpms.gui.columns import COLUMNS

    runner = SessionRunner(ModeConfig(mode="file", path=str(recording_path),
                                      recording_dir=str(tmp_path)), Options())
    runner.playback_filter = "observer"  # chosen in the playback controls (issue 44.2)
    runner.prepare()
    window = MainWindow(runner, layout_store=LayoutStore(tmp_path / "layouts.json"),
                        restore_last=False)
    qtbot.addWidget(window)
    window.show()
    runner.show_frame(150)
    qtbot.waitUntil(lambda: window.model.latest is not None
                    and window.model.latest.index == 150, timeout=20000)
    s = window.model.latest
    assert s.estimates is not None and s.estimates.shape == (18, 6)
    assert np.isfinite(s.estimates).all()  # the observer estimates both
    window.display.on_samples([s])
    model = window.panels.table_model
    est_cols = [k for k, c in enumerate(COLUMNS) if c.group == "est"]
    assert [COLUMNS[k].label() for k in est_cols[:1] + est_cols[3:4]] == [
        "gyro bias x [rad/s]", "body acc north [m/s²]"]
    for j, col in enumerate(est_cols):
        assert model.value(4, col) == pytest.approx(s.estimates[4, j])
    # a plot of that cell (dragged from the table, or Plot selection) draws the same numbers
    spec = cell_curve(4, est_cols[3])
    assert spec.unit == "m/s²" and "body acc north" in spec.label
    block = TickBlock.from_samples([s], model.calibration)
    assert spec.values(block)[0] == pytest.approx(s.estimates[4, 3])
    window.close()
