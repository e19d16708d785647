"""One owner and one check for the filter settings while a session runs (issue 44.1).

The session's processor owns the gains and the filter in force; the GUI's panel shows what the
session reports and sends each change as a typed :class:`bpms.io.event_types.Gains`, whose own
check is the only one. Checked on a simulated suit (live) and on a recording with a recorded
gains event (playback); a planted second copy (the panel keeping its own value) or second
check (the GUI clamping into range) is caught.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from bpms.firmware.sim.session import simulate
from bpms.gui.controls import GainsPanel
from bpms.gui.layouts import LayoutStore
from bpms.gui.main_window import MainWindow
from bpms.gui.modes import ModeConfig, SessionRunner
from bpms.io.options import FilterOptions, Options

#: kp_rollpitch's valid range, as docs/configuration.md publishes it
KP_ROLLPITCH_RANGE = "[0, 0.18]"


def _window(qtbot, tmp_path: Path, config: ModeConfig) -> MainWindow:
    runner = SessionRunner(config, Options())
    runner.prepare()
    window = MainWindow(runner, layout_store=LayoutStore(tmp_path / "layouts.json"),
                        restore_last=False)
    qtbot.addWidget(window)
    window.show()
    window.model.set_refresh_hz(50)
    return window


def _type(panel: GainsPanel, name: str, text: str) -> None:
    edit = panel.edits[name]
    edit.setFocus()
    edit.setText(text)
    edit.setModified(True)  # as typed by hand
    edit.editingFinished.emit()


def _live_checks(qtbot, window: MainWindow, timeout_ms: int = 5000) -> None:
    """A gain typed in the panel reaches the processor (and its filter bank), and the panel
    shows the processor's value, also one changed by another road (the API); a value out
    of range is refused with the event's message, the processor's value unchanged."""
    panel = window.panels.gains_panel
    proc = window.runner.session.processor
    window.commands.set_data(True)
    qtbot.waitUntil(lambda: window.runner.session.running, timeout=timeout_ms)
    _type(panel, "kp_yaw", "0.5")
    qtbot.waitUntil(lambda: proc.options.filter.kp_yaw == 0.5
                    and float(proc.bank.params[2]) == 0.5, timeout=timeout_ms)
    qtbot.waitUntil(lambda: panel.edits["kp_yaw"].text() == "0.5", timeout=timeout_ms)
    # the API (another client of the same session): the panel follows the processor
    window.runner.session.set_gains(kp_yaw=0.25)
    qtbot.waitUntil(lambda: proc.options.filter.kp_yaw == 0.25, timeout=timeout_ms)
    qtbot.waitUntil(lambda: panel.edits["kp_yaw"].text() == "0.25", timeout=timeout_ms)
    # refused by the event's own check: its message (the range), nothing changes
    before = proc.options.filter.kp_rollpitch
    _type(panel, "kp_rollpitch", "5")
    assert KP_ROLLPITCH_RANGE in panel.message.text() and "5" in panel.message.text()
    last = window.panels.event_log.entries[-1]
    assert last[1] == "warning" and last[2] == panel.message.text()
    # a frame or two later, the processor still runs with its value, and the panel shows it
    frames = window.runner.session.status().processed
    qtbot.waitUntil(lambda: window.runner.session.status().processed > frames + 5,
                    timeout=timeout_ms)
    assert proc.options.filter.kp_rollpitch == before
    qtbot.waitUntil(lambda: panel.edits["kp_rollpitch"].text() == f"{before:g}",
                    timeout=timeout_ms)


def test_the_panel_shows_and_changes_the_processors_gains_live(qtbot, tmp_path):
    window = _window(qtbot, tmp_path, ModeConfig(mode="sim", recording_dir=str(tmp_path)))
    try:
        _live_checks(qtbot, window)
        # the filter too: picked in the panel, made the processor's, shown from it
        window.panels.gains_panel.filter_combo.setCurrentText("observer")
        proc = window.runner.session.processor
        qtbot.waitUntil(lambda: proc.options.filter.algorithm == "observer", timeout=5000)
        window.runner.session.select_filter("mahony")  # another road: the panel follows
        qtbot.waitUntil(lambda: window.panels.gains_panel.filter_combo.currentText()
                        == "mahony", timeout=5000)
        assert window.panels.gains_panel.shown_settings() == [
            "kp_rollpitch", "ki_rollpitch", "kp_yaw", "ki_yaw"]
    finally:
        window.close()


def _keeps_its_own_copy(self, settings, pending=0):
    """Planted: the panel shows its own value, set when it sends, never the session's."""
    if settings is None:
        return
    self.in_force = settings if not hasattr(self, "_planted") else self.in_force
    self._planted = True


def _checks_twice(values, source=None):
    """Planted: a second check in the GUI that disagrees with the event's (clamps
    kp_rollpitch into its range instead of refusing)."""
    from bpms.io.event_types import Gains

    return Gains({k: min(float(v), 0.18) if k == "kp_rollpitch" else v
                  for k, v in values.items()}, source)


@pytest.mark.parametrize("plant", ["second copy", "second check"])
def test_a_planted_second_copy_or_check_is_seen(qtbot, tmp_path, monkeypatch, plant):
    if plant == "second copy":
        monkeypatch.setattr(GainsPanel, "show_settings", _keeps_its_own_copy)
    else:
        monkeypatch.setattr("bpms.gui.controls.Gains", _checks_twice)
    window = _window(qtbot, tmp_path, ModeConfig(mode="sim", recording_dir=str(tmp_path)))
    try:
        with pytest.raises((AssertionError, qtbot.TimeoutError)):
            _live_checks(qtbot, window, timeout_ms=1500)
    finally:
        window.close()


@pytest.fixture(scope="module")
def gains_recording(tmp_path_factory) -> Path:
    """3 s recorded with the factory filter whose session changed kp_yaw to 0.3 at frame 60
    (the events as a live session writes them, the settings in force at its start first)."""
    import dataclasses

    from bpms.io.rawfile import new_header, write_raw
    from bpms.io.session_events import SessionEvent

    rec = simulate(duration_s=3.0, seed=8)
    path = tmp_path_factory.mktemp("gains") / "Raw_gains_001.bpmsraw"
    header = new_header(calibration=rec.calibration.values, notes="gains",
                        extra={"session_events": True})
    start = {k: v for k, v in dataclasses.asdict(FilterOptions()).items() if k != "algorithm"}
    events = [SessionEvent("filter", 0, data={"algorithm": "mahony", "source": "in force"}),
              SessionEvent("gains", 0, data={"values": start, "source": "in force"}),
              SessionEvent("gains", 60, data={"values": {"kp_yaw": 0.3}})]
    write_raw(path, 1.7e9 + rec.t, rec.frames, header, events)
    return path


def test_in_playback_the_panel_follows_the_recordings_gains(qtbot, tmp_path, gains_recording):
    window = _window(qtbot, tmp_path, ModeConfig(mode="file", path=str(gains_recording),
                                                 recording_dir=str(tmp_path)))
    try:
        panel, proc = window.panels.gains_panel, window.runner.session.processor
        factory = FilterOptions().kp_yaw
        assert factory != 0.3 and panel.edits["kp_yaw"].text() == f"{factory:g}"
        window.panels.playback_panel.seek(40)  # before the recorded change
        qtbot.waitUntil(lambda: window.model.latest is not None
                        and window.model.latest.index == 40, timeout=10000)
        assert proc.options.filter.kp_yaw == factory
        assert panel.edits["kp_yaw"].text() == f"{factory:g}"
        window.panels.playback_panel.seek(120)  # past it: applied at its frame, shown
        qtbot.waitUntil(lambda: proc.options.filter.kp_yaw == 0.3, timeout=10000)
        qtbot.waitUntil(lambda: panel.edits["kp_yaw"].text() == "0.3", timeout=5000)
    finally:
        window.close()


def test_a_restarted_udp_stream_keeps_the_gains_in_force(qtbot, tmp_path):
    """The UDP client's Stop/Start Data makes a new session: it starts from the values the
    old session's processor ran with (the one owner), not from the app's starting options."""
    window = _window(qtbot, tmp_path, ModeConfig(mode="udp", listen="127.0.0.1:0",
                                                 recording_dir=str(tmp_path)))
    try:
        window.commands.set_data(True)
        first = window.runner.session
        _type(window.panels.gains_panel, "kp_yaw", "0.5")
        qtbot.waitUntil(lambda: first.processor.options.filter.kp_yaw == 0.5, timeout=5000)
        window.commands.set_data(False)
        window.commands.set_data(True)
        second = window.runner.session
        assert second is not first and second.processor.options.filter.kp_yaw == 0.5
        assert window.options.filter.kp_yaw == Options().filter.kp_yaw  # no second copy
        qtbot.waitUntil(lambda: window.panels.gains_panel.edits["kp_yaw"].text() == "0.5",
                        timeout=5000)
    finally:
        window.close()
