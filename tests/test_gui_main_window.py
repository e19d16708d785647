"""The main window (issue 15.1, 15.2, 15.5): docks and saved layouts, menus, the health light
and event log on a real UDP stream and the simulated suit, dragging table cells onto plots."""

from __future__ import annotations

import socket
import time
from pathlib import Path

import numpy as np
import pytest
from deadlines import scaled
from PyQt6.QtCore import QPointF, Qt, QTimer
from PyQt6.QtGui import QDragEnterEvent, QDropEvent
from PyQt6.QtWidgets import QApplication, QDockWidget

from bpms.firmware.sim.session import simulate
from bpms.gui.layouts import CALIBRATION, LayoutStore
from bpms.gui.main_window import MainWindow
from bpms.gui.modes import ModeConfig, SessionRunner
from bpms.gui.plots import PlotWindow
from bpms.io.options import Options
from bpms.io.udp.sender import UdpForwarder


@pytest.fixture(scope="module")
def recording_path(tmp_path_factory) -> Path:
    rec = simulate(duration_s=6.0, seed=3)
    return rec.save_raw(tmp_path_factory.mktemp("rec") / "Raw_mw_001.bpmsraw")


def _window(qtbot, config: ModeConfig, store: LayoutStore, **kw) -> MainWindow:
    runner = SessionRunner(config, Options())
    runner.prepare()
    window = MainWindow(runner, layout_store=store, **kw)
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    return window


def _drop(widget, mime) -> bool:
    """A drag entering ``widget`` and dropping ``mime`` there (the events a real drop sends);
    True when the widget accepted the drop."""
    pos = QPointF(widget.rect().center())
    actions = Qt.DropAction.CopyAction
    enter = QDragEnterEvent(pos.toPoint(), actions, mime, Qt.MouseButton.LeftButton,
                            Qt.KeyboardModifier.NoModifier)
    QApplication.sendEvent(widget, enter)
    if not enter.isAccepted():
        return False
    drop = QDropEvent(pos, actions, mime, Qt.MouseButton.LeftButton,
                      Qt.KeyboardModifier.NoModifier)
    QApplication.sendEvent(widget, drop)
    return drop.isAccepted()


def test_docks_layouts_saved_and_restored_between_launches(qtbot, tmp_path, recording_path):
    store = LayoutStore(tmp_path / "layouts.json")
    config = ModeConfig(mode="file", path=str(recording_path), recording_dir=str(tmp_path))
    window = _window(qtbot, config, store)
    # every panel is a Qt dock: movable, floatable, closable
    for name in ("table", "status", "session", "filter", "events"):
        dock = window.panels.docks[name]
        assert isinstance(dock, QDockWidget) and dock.objectName() == name
        features = dock.features()
        for f in (QDockWidget.DockWidgetFeature.DockWidgetMovable,
                  QDockWidget.DockWidgetFeature.DockWidgetFloatable,
                  QDockWidget.DockWidgetFeature.DockWidgetClosable):
            assert features & f
    # a layout of my own: two cell plots, the filter dock floating, the event log closed
    window.panels.table.select_cells([(3, 0), (3, 4)])
    first = window.views.plot_selection()
    window.panels.table.select_cells([(6, 1)])
    window.views.plot_selection()
    window.panels.docks["filter"].setFloating(True)
    window.panels.docks["events"].close()
    window.layouts.save_layout("mine")
    assert store.names() == ["mine"]
    mine = [d.widget() for d in window.views.dynamic_docks if isinstance(d.widget(), PlotWindow)]
    # another layout moves the panels and keeps the plots (issue 27.2)...
    window.layouts.apply_default_layout(CALIBRATION)
    docks = window.panels.docks
    assert not docks["filter"].isFloating() and docks["events"].isVisible()
    kept = [d.widget() for d in window.views.dynamic_docks if isinstance(d.widget(), PlotWindow)]
    assert {id(p) for p in kept} == {id(p) for p in mine}
    # ...and loading "mine" brings back the dock states, with the same plots
    assert window.layouts.load_layout("mine")
    plots = [d.widget() for d in window.views.dynamic_docks if isinstance(d.widget(), PlotWindow)]
    assert {id(p) for p in plots} == {id(p) for p in mine}
    # (the playback layout's joint-angle plot was part of "mine" too)
    assert sorted(len(p.curves) for p in plots) == [1, 2, 28]
    labels = sorted(c.name() for p in plots if p.kind == "cells" for c in p.curves)
    assert labels == sorted([*(c.name() for c in first.curves), "Hip pitch [deg]"])
    assert window.panels.docks["filter"].isFloating()
    assert not window.panels.docks["events"].isVisible()
    window.close()  # remembered as the last layout
    # the next launch (a new main window, same user) starts with it
    again = _window(qtbot, config, LayoutStore(tmp_path / "layouts.json"))
    plots = [d.widget() for d in again.views.dynamic_docks if isinstance(d.widget(), PlotWindow)]
    assert sorted(len(p.curves) for p in plots) == [1, 2, 28]
    assert again.panels.docks["filter"].isFloating()
    again.close()


def test_menus_list_every_command_with_its_shortcut(qtbot, tmp_path, recording_path):
    store = LayoutStore(tmp_path / "layouts.json")
    config = ModeConfig(mode="file", path=str(recording_path), recording_dir=str(tmp_path))
    window = _window(qtbot, config, store)
    in_menus = {a for menu in window.menuBar().findChildren(type(window.menus.layouts_menu))
                for a in menu.actions()}
    for key, action in window.menus.actions_by_name.items():
        assert action in in_menus, key
    shortcuts = {a.text(): a.shortcut().toString() for a in window.menus.actions_by_name.values()}
    assert shortcuts["Reset Zero"] == "Ctrl+R" and shortcuts["Start/Stop Data"] == "Ctrl+Space"
    toolbar = [a.text() for a in window.menus.toolbar.actions()]
    assert any("Start" in t for t in toolbar) and "Reset Zero" in toolbar
    assert any("Record" in t for t in toolbar)
    window.close()


def test_drag_a_cell_onto_a_plot_adds_the_curve_or_opens_a_new_plot(qtbot, tmp_path,
                                                                    recording_path):
    store = LayoutStore(tmp_path / "layouts.json")
    config = ModeConfig(mode="file", path=str(recording_path), recording_dir=str(tmp_path))
    window = _window(qtbot, config, store, restore_last=False)
    window.panels.table.select_cells([(8, 0)])
    plot = window.views.plot_selection()
    model = window.panels.table_model
    mime = model.mimeData([model.index(12, 1), model.index(4, 4)])  # pitch, acc x
    assert _drop(plot, mime)
    names = [c.name() for c in plot.curves]
    assert names[0] == "Spine roll [deg]" and len(names) == 3
    assert sorted(names[1:]) == ["Left Leg pitch [deg]", "Right Arm acc x [m/s²]"]
    units = sorted(p.getAxis("left").labelText for p in plot.plots)
    assert units == ["[deg]", "[m/s²]"]  # one y axis per unit
    # the error column is not plottable: a drag of it carries nothing
    assert not _drop(plot, model.mimeData([model.index(2, 3)]))
    # onto empty space: a new plot
    before = len(window.views.plot_windows)
    assert _drop(window.panels.drop_area, model.mimeData([model.index(17, 2)]))
    assert len(window.views.plot_windows) == before + 1
    assert window.views.plot_windows[-1].curves[0].name() == "Head yaw [deg]"
    # joint names from the joint-angle list: onto the plot, and onto empty space
    jm = window.panels.joint_model
    assert jm.data(jm.index(10, 0)) == "Right hip abduction"
    assert _drop(plot, jm.mimeData([jm.index(10, 0), jm.index(10, 1)]))
    assert plot.curves[-1].name() == "Right hip abduction [deg]" and len(plot.curves) == 4
    assert plot.description()["joints"] == [10]
    before = len(window.views.plot_windows)
    assert _drop(window.panels.drop_area, jm.mimeData([jm.index(0, 0), jm.index(2, 0)]))
    assert len(window.views.plot_windows) == before + 1
    assert [c.name() for c in window.views.plot_windows[-1].curves] == [
        "Right elbow flexion [deg]", "Right knee flexion [deg]"]
    # play: the dropped curves get data
    window.commands.set_data(True)
    qtbot.waitUntil(lambda: len(plot.buffer) > 20, timeout=15000)
    for curve in (plot.curves[2], plot.curves[3]):
        _x, y = curve.getData()
        assert np.isfinite(y[-5:]).all()
    window.commands.set_data(False)
    window.close()


def _send_frames(forwarder: UdpForwarder, frames: list[bytes], state: dict) -> None:
    k = state["k"]
    forwarder.send_frame(frames[k % len(frames)], k * 0.02)
    state["k"] = k + 1
    state["last"] = time.monotonic()


def test_health_light_goes_red_and_udp_client_leaves_streaming_within_a_second(
        qtbot, tmp_path, recording_path):
    from bpms.io.rawfile import read_raw

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    store = LayoutStore(tmp_path / "layouts.json")
    window = _window(qtbot, ModeConfig(mode="udp", listen=f"127.0.0.1:{port}"), store)
    window.commands.set_data(True)
    raw = read_raw(recording_path).frames.tobytes()
    frames = [raw[i:i + 340] for i in range(0, len(raw), 340)]
    forwarder = UdpForwarder([f"127.0.0.1:{port}"])
    state = {"k": 0, "last": 0.0}
    timer = QTimer()
    timer.timeout.connect(lambda: _send_frames(forwarder, frames, state))
    timer.start(20)
    try:
        qtbot.waitUntil(lambda: window.panels.health_panel.colour in ("green", "amber")
                        and state["k"] > 60, timeout=15000)
    finally:
        timer.stop()
        forwarder.close()
    silent_since = state["last"]
    # red within 1.2 s of the last datagram, and the state no longer says "streaming"
    qtbot.waitUntil(lambda: window.panels.health_panel.colour == "red",
                    timeout=int(scaled(1.2) * 1000))
    assert time.monotonic() - silent_since < scaled(1.2) + 0.5  # (the wait's slack)
    assert "streaming" not in window.panels.status_panel.labels["state"].text()
    assert window.panels.health_panel.state_label.text() == "no data"
    assert any(t.startswith("link lost") for t in window.panels.event_log.texts())
    window.close()


def test_simulated_source_is_unmistakable_and_stop_start_is_not_a_link_loss(qtbot, tmp_path):
    store = LayoutStore(tmp_path / "layouts.json")
    window = _window(qtbot, ModeConfig(mode="sim", recording_dir=str(tmp_path)), store)
    assert "SIMULATED" in window.windowTitle()
    assert window.panels.health_panel.simulated_label.isVisible()
    assert window.panels.health_panel.simulated_label.text() == "SIMULATED"
    window.commands.set_data(True)
    qtbot.waitUntil(lambda: window.panels.health_panel.colour == "green", timeout=15000)
    assert window.panels.health_panel.labels["battery"].text() == "3.35 V"  # above the warning
    window.commands.set_data(False)
    assert window.panels.health_panel.colour in ("grey", "green")
    qtbot.waitUntil(lambda: window.panels.health_panel.colour == "grey", timeout=2000)
    window.commands.set_data(True)  # a quick Stop → Start
    qtbot.waitUntil(lambda: window.panels.health_panel.colour == "green", timeout=15000)
    # watched for longer than the 1 s silence rule: 65 more frames (1.3 s of the suit's
    # 50 Hz), never red (amber is allowed: a loaded machine may read a low rate)
    first = window.model.last_status.frames
    colours: list[str] = []

    def watched() -> bool:
        colours.append(window.panels.health_panel.colour)
        return window.model.last_status.frames >= first + 65

    qtbot.waitUntil(watched, timeout=int(scaled(15.0) * 1000))
    assert "red" not in colours and "grey" not in colours, colours
    texts = window.panels.event_log.texts()
    assert "data stopped" in texts and texts.count("data started") == 2
    assert not any("link lost" in t for t in texts)
    # Reset Zero and logging are logged, with the REC indicator while recording
    window.commands.reset_zero()
    window.panels.file_panel.name_edit.setText("evlog")
    window.panels.file_panel.toggle_logging()
    qtbot.waitUntil(lambda: "REC" in window.panels.health_panel.recording_text, timeout=5000)
    assert "Raw_evlog_1.bpmsraw" in window.panels.health_panel.recording_text
    assert str(tmp_path) in window.panels.health_panel.recording_text
    window.panels.file_panel.toggle_logging()
    panel = window.panels.file_panel
    qtbot.waitUntil(lambda: not panel.busy and panel.last_recording is not None,
                    timeout=15000)
    qtbot.waitUntil(lambda: window.panels.health_panel.recording_text == "", timeout=3000)
    texts = window.panels.event_log.texts()
    assert any(t.startswith("Reset Zero (manual) at ") for t in texts), texts
    assert any(t.startswith("logging started") for t in texts)
    assert any(t.startswith("logging stopped: Raw_evlog_1.bpmsraw") for t in texts)
    window.close()


def test_reset_zero_warns_when_the_subject_moved_during_its_window(qtbot, tmp_path,
                                                                 recording_path):
    """The warning comes from the capture itself (the motion the processor measured over its
    window, bpms.filter.pose.window_motion), through the session's event, in red. The
    simulated script: still until 3 s, then the right arm (IMU 4) rises 60° in 2 s."""
    store = LayoutStore(tmp_path / "layouts.json")
    config = ModeConfig(mode="file", path=str(recording_path), recording_dir=str(tmp_path))
    window = _window(qtbot, config, store, restore_last=False)
    replay = window.runner.replay
    window.commands.set_data(True)  # (Reset Zero is enabled while data run)
    qtbot.waitUntil(lambda: window.model.latest is not None
                    and window.model.latest.index >= 60, timeout=15000)
    window.commands.reset_zero()  # still: no warning
    qtbot.waitUntil(lambda: any(t.startswith("Reset Zero (manual)")
                                for t in window.panels.event_log.texts()), timeout=10000)
    assert not any("moved during its window" in t for t in window.panels.event_log.texts())
    qtbot.waitUntil(lambda: replay.position >= 210, timeout=15000)  # the arm rises
    window.commands.reset_zero()
    qtbot.waitUntil(lambda: any("moved during its window" in t
                                for t in window.panels.event_log.texts()), timeout=10000)
    warning = [(level, text) for _, level, text in window.panels.event_log.entries
               if "moved during its window" in text]
    assert len(warning) == 1 and warning[0][0] == "warning"
    moved = float(warning[0][1].split("moved ")[1].split("°")[0])
    assert moved > 5.0 and any(f"(IMU {i})" in warning[0][1] for i in (3, 4, 5))  # right arm
    window.commands.set_data(False)
    window.close()


def test_a_truncated_recording_is_a_file_warning_in_the_event_log(qtbot, tmp_path,
                                                                   recording_path):
    torn = tmp_path / "Raw_torn_1.bpmsraw"
    data = recording_path.read_bytes()
    torn.write_bytes(data[:-100])  # the last record cut short, as by a crash
    store = LayoutStore(tmp_path / "layouts.json")
    window = _window(qtbot, ModeConfig(mode="file", path=str(torn),
                                       recording_dir=str(tmp_path)), store)
    warnings = [text for when, level, text in window.panels.event_log.entries if level == "warning"]
    assert any(t.startswith("file warning:") and "incomplete" in t for t in warnings), warnings
    window.close()
