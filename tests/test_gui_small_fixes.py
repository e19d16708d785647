"""The smaller defects of issue 44 item 9: the focus after Stop Logging, the options dialog's
help texts, a layout saved live used in file mode, 2-px lines and a palette where neighbouring
limbs differ, a word when no browser opens, one clock in the playback event log."""

from __future__ import annotations

import re
import webbrowser
from pathlib import Path

import pytest
from PyQt6.QtCore import Qt
from PyQt6.QtGui import QColor
from PyQt6.QtWidgets import QApplication, QLabel, QScrollArea

from bpms.firmware.sim.session import simulate
from bpms.gui.docks import inner
from bpms.gui.layouts import LayoutStore
from bpms.gui.main_window import MainWindow
from bpms.gui.modes import ModeConfig, SessionRunner
from bpms.gui.options_dialog import OptionsDialog
from bpms.gui.plot_style import PALETTE
from bpms.gui.plots import cells_plot
from bpms.io.options import Options


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    rec = simulate(duration_s=6.0, seed=9)
    return rec.save_raw(tmp_path_factory.mktemp("small") / "Raw_small_001.bpmsraw")


def _window(qtbot, config: ModeConfig, store: LayoutStore, restore_last: bool = False
            ) -> MainWindow:
    runner = SessionRunner(config, Options())
    runner.prepare()
    window = MainWindow(runner, layout_store=store, restore_last=restore_last)
    qtbot.addWidget(window)
    window.setWindowState(Qt.WindowState.WindowNoState)
    window.resize(1366, 698)
    window.show()
    qtbot.waitExposed(window)
    return window


def test_stop_logging_keeps_the_focus_off_the_udp_targets(qtbot, tmp_path):
    window = _window(qtbot, ModeConfig(mode="sim", recording_dir=str(tmp_path)),
                     LayoutStore(tmp_path / "layouts.json"))
    try:
        window.commands.set_data(True)
        panel = window.panels.file_panel
        window.panels.docks["session"].raise_()
        panel.toggle_logging()
        qtbot.waitUntil(lambda: panel.logging, timeout=5000)
        panel.log_button.setFocus()
        qtbot.waitUntil(panel.log_button.hasFocus, timeout=2000)
        targets = window.panels.udp_panel.targets_edit
        text = targets.text()
        panel.log_button.click()  # Stop Logging: the button greys while the files close
        focus = QApplication.focusWidget()
        assert focus is not targets and not targets.hasSelectedText()
        qtbot.keyClicks(focus, "x")  # a keystroke now does not land in the targets
        assert targets.text() == text
        qtbot.waitUntil(lambda: not panel.busy and panel.log_button.isEnabled(),
                        timeout=10000)
        assert panel.log_button.hasFocus()  # back where it was
    finally:
        window.close()


def test_the_options_help_texts_are_shown_whole(qtbot):
    dialog = OptionsDialog(Options())
    qtbot.addWidget(dialog)
    dialog.resize(640, 560)
    dialog.show()
    qtbot.waitExposed(dialog)
    for name, scroll in dialog.scrolls.items():
        dialog.tabs.setCurrentWidget(scroll)
        QApplication.processEvents()
        labels = [w for w in scroll.widget().findChildren(QLabel) if w.wordWrap()]
        assert labels, name
        for title in labels:
            # each help text as tall as its own lines at its width (two-line ones were cut)
            need = title.heightForWidth(title.width())
            assert title.height() >= need, (name, title.text()[:40])
        assert scroll.horizontalScrollBar().maximum() == 0


def test_a_layout_saved_live_does_not_scroll_sideways_in_file_mode(qtbot, tmp_path,
                                                                    recording):
    store = LayoutStore(tmp_path / "layouts.json")
    live = _window(qtbot, ModeConfig(mode="udp", listen="127.0.0.1:0",
                                     recording_dir=str(tmp_path)), store)
    live.resizeDocks([live.panels.docks["status"]], [150], Qt.Orientation.Horizontal)  # narrowed
    qtbot.wait(50)
    live.close()  # remembered as the last layout
    window = _window(qtbot, ModeConfig(mode="file", path=str(recording),
                                       recording_dir=str(tmp_path)), store, restore_last=True)
    try:
        qtbot.wait(100)
        for name in ("status", "session", "filter"):
            area = window.panels.docks[name].widget()
            assert isinstance(area, QScrollArea)
            content = inner(window.panels.docks[name])
            assert not area.horizontalScrollBar().isVisible(), name
            assert content.width() >= content.minimumSizeHint().width(), name
    finally:
        window.close()


def _distance(a: str, b: str) -> float:
    ca, cb = QColor(a), QColor(b)
    return sum((x - y) ** 2 for x, y in zip(ca.getRgb()[:3], cb.getRgb()[:3],
                                              strict=True)) ** 0.5


def test_lines_are_2_px_and_neighbouring_limbs_differ(qtbot):
    # the hand, the arm and the forearm (IMUs 3, 4, 5), each roll, pitch and yaw
    plot = cells_plot([(imu, col) for imu in (3, 4, 5) for col in (0, 1, 2)])
    qtbot.addWidget(plot)
    pens = [curve.opts["pen"] for curve in plot.curves]
    assert all(pen.widthF() == 2 for pen in pens)
    colours = [pen.color().name() for pen in pens]
    hand, arm, forearm = colours[0], colours[3], colours[6]
    assert colours[:3] == [hand] * 3 and colours[3:6] == [arm] * 3
    # far apart in RGB (the three blues of before were within 110 of each other)
    assert min(_distance(hand, arm), _distance(arm, forearm), _distance(hand, forearm)) > 150
    styles = [pen.style() for pen in pens[:3]]
    assert styles == [Qt.PenStyle.SolidLine, Qt.PenStyle.DashLine, Qt.PenStyle.DotLine]
    # one limb: the eight colours in order (roll, pitch, yaw the most distinct)
    one = cells_plot([(5, 0), (5, 1), (5, 2)])
    qtbot.addWidget(one)
    assert [c.opts["pen"].color().name().upper() for c in one.curves] == \
        [c.upper() for c in PALETTE[:3]]
    # neighbours in the palette are never alike
    for a, b in zip(PALETTE, PALETTE[1:] + PALETTE[:1], strict=True):
        assert _distance(a, b) > 100


def test_no_browser_is_said_in_the_event_log(qtbot, tmp_path, recording, monkeypatch):
    from bpms.gui.vpython_views import vpython_problem

    if vpython_problem() is not None:
        pytest.skip(vpython_problem())
    monkeypatch.delenv("VPYTHON_NO_LAUNCH_BROWSER", raising=False)
    monkeypatch.delenv("BROWSER", raising=False)
    # a machine with no browser registered (webbrowser's own state)
    monkeypatch.setattr(webbrowser, "_tryorder", [])
    monkeypatch.setattr(webbrowser, "_browsers", {})
    window = _window(qtbot, ModeConfig(mode="file", path=str(recording),
                                       recording_dir=str(tmp_path)),
                     LayoutStore(tmp_path / "layouts.json"))
    try:
        assert window.views.open_browser_view() is None
        assert any("Browser 3D view not opened" in t and "browser" in t
                   for t in window.panels.event_log.texts())
        assert not window.views.browser_views
    finally:
        window.close()


def test_the_playback_event_log_has_one_clock_the_recordings(qtbot, tmp_path, recording):
    window = _window(qtbot, ModeConfig(mode="file", path=str(recording),
                                       recording_dir=str(tmp_path)),
                     LayoutStore(tmp_path / "layouts.json"))
    try:
        window.panels.playback_panel.speed_combo.setCurrentText("max")
        window.commands.set_data(True)
        qtbot.waitUntil(lambda: window.runner.replay.ended, timeout=20000)
        window.model.tick()
        qtbot.waitUntil(lambda: "end of the recording" in window.panels.event_log.texts(),
                        timeout=5000)
        stamps = [when for when, _, _ in window.panels.event_log.entries]
        assert len(stamps) >= 4
        assert all(re.fullmatch(r"\d+:\d\d\.\d\d", s) for s in stamps), stamps
        # a session event stamped at the time it names
        for when, _, text in window.panels.event_log.entries:
            at = re.search(r" at (\d+\.\d\d) s", text)
            if at:
                minutes, seconds = when.split(":")
                assert 60 * int(minutes) + float(seconds) == pytest.approx(float(at[1]))
    finally:
        window.close()
