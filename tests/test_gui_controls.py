"""The filter-settings panel (issue 27.8): each filter lists only its own settings, a value
outside its range is refused with the range shown, every change and refusal is reported for
the event log; the playback panel keeps the focus (and its slider) in place."""

from __future__ import annotations

import pytest
from PyQt6.QtWidgets import QFormLayout

from bpms.gui.controls import GainsPanel
from bpms.io.options import ALGORITHM_SETTINGS, VALID_RANGES, Options


def _shown_rows(panel: GainsPanel) -> set[str]:
    """Names of the setting rows a user sees in the form (label and field both shown)."""
    form = panel.layout()
    assert isinstance(form, QFormLayout)
    shown = set()
    for row in range(form.rowCount()):
        label = form.itemAt(row, QFormLayout.ItemRole.LabelRole)
        field = form.itemAt(row, QFormLayout.ItemRole.FieldRole)
        if label is None or field is None or label.widget() is None:
            continue
        if not label.widget().isHidden() and not field.widget().isHidden():
            shown.add(label.widget().text())
    return shown - {"filter"}


@pytest.mark.parametrize("algorithm", list(ALGORITHM_SETTINGS))
def test_each_filters_panel_lists_only_its_own_settings(qtbot, algorithm):
    panel = GainsPanel(Options().filter)
    qtbot.addWidget(panel)
    panel.filter_combo.setCurrentText(algorithm)
    own = ALGORITHM_SETTINGS[algorithm]
    assert set(panel.shown_settings()) == set(own)
    shorts = {n.split("_", 1)[1] if n.startswith(("observer_", "vqf_", "adaptive_")) else n
              for n in own}
    assert _shown_rows(panel) == shorts
    for name in own:  # the range beside each field
        rng = VALID_RANGES["filter"].get(name)
        if rng is not None:
            assert rng.describe() in panel.rows[name].findChildren(type(panel.message))[0].text()


@pytest.mark.parametrize("typed", ["5", "-1", "abc"])
def test_a_value_outside_the_range_is_refused_with_the_range_and_logged(qtbot, typed):
    panel = GainsPanel(Options().filter)
    qtbot.addWidget(panel)
    gains, log = [], []
    panel.gainsChanged.connect(gains.append)
    panel.logged.connect(lambda text, level: log.append((text, level)))
    edit = panel.edits["kp_rollpitch"]
    old = edit.text()
    edit.setText(typed)
    edit.editingFinished.emit()
    assert gains == [] and edit.text() == old  # refused, the value in force is back
    # the message is the event's own check's: the range (a number), else "not a number"
    why = "not a number" if typed == "abc" else "[0, 0.18]"
    assert why in panel.message.text() and typed in panel.message.text()
    assert log == [(panel.message.text(), "warning")]


def test_an_accepted_change_is_sent_once_as_a_gains_event_and_logged(qtbot):
    from bpms.io.event_types import Gains

    panel = GainsPanel(Options().filter)
    qtbot.addWidget(panel)
    gains, log = [], []
    panel.gainsChanged.connect(gains.append)
    panel.logged.connect(lambda text, level: log.append((text, level)))
    edit = panel.edits["kp_yaw"]
    old = float(edit.text())
    edit.setText("0.5")
    edit.editingFinished.emit()
    assert len(gains) == 1 and isinstance(gains[0], Gains) and gains[0].values == {"kp_yaw": 0.5}
    assert log == [(f"filter gain kp_yaw: {old:g} → 0.5", "info")]
    # the panel owns no value: until the session reports 0.5 in force, the field shows the old
    panel.show_settings(Options().filter)
    assert edit.text() == f"{old:g}"
    reported = Options().filter
    reported.kp_yaw = 0.5
    panel.show_settings(reported)
    assert edit.text() == "0.5"
    edit.editingFinished.emit()  # leaving the field again: no second change
    assert len(gains) == 1


def test_playing_keeps_the_focus_and_the_slider_in_view(qtbot, tmp_path):
    from PyQt6.QtWidgets import QApplication, QScrollArea, QVBoxLayout, QWidget

    from bpms.firmware.sim.session import simulate
    from bpms.gui.controls import FilePanel, PlaybackPanel
    from bpms.gui.modes import ModeConfig, SessionRunner

    path = simulate(duration_s=3.0, seed=1).save_raw(tmp_path / "Raw_focus_1.bpmsraw")
    runner = SessionRunner(ModeConfig(mode="file", path=str(path), recording_dir=str(tmp_path)),
                           Options())
    runner.prepare()
    box = QWidget()
    layout = QVBoxLayout(box)
    playback, files = PlaybackPanel(runner), FilePanel(runner)
    layout.addWidget(playback)
    layout.addWidget(files)
    area = QScrollArea()
    area.setWidget(box)
    area.setWidgetResizable(True)
    area.resize(420, 180)  # shorter than the panels: the file panel is below the fold
    qtbot.addWidget(area)
    area.show()
    qtbot.waitExposed(area)
    try:
        playback.slider.setFocus()
        qtbot.waitUntil(playback.slider.hasFocus, timeout=2000)
        top = area.verticalScrollBar().value()
        runner.start_data()
        qtbot.waitUntil(lambda: runner.replay.playing, timeout=5000)
        playback.show_status()
        assert not playback.slider.isEnabled()
        focus = QApplication.focusWidget()
        assert focus is playback or playback.isAncestorOf(focus)  # not the Name field below
        assert area.verticalScrollBar().value() == top  # the slider stays in view
        for button in playback.step_buttons:  # icons from Qt's standard set
            assert not button.icon().isNull()
            assert all(ord(ch) < 0x2190 or ch == "−" for ch in button.text())
    finally:
        runner.close()
