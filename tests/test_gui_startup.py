"""The start-up window's files and checks, and ``bpms gui`` without a display."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from PyQt6.QtWidgets import QApplication, QLineEdit
from waiting import wait_until

from bpms.gui.modes import ModeConfig, ModeError, SessionRunner
from bpms.gui.options_dialog import OptionsDialog
from bpms.gui.startup import StartupWindow
from bpms.io.calib_file import load_factory_calibration
from bpms.io.options import Options, load_options

ROOT = Path(__file__).resolve().parents[1]


def test_bpms_without_display_says_so_in_one_line():
    env = {k: v for k, v in os.environ.items()
           if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    for args in ([], ["gui", "--sim"]):
        done = subprocess.run([sys.executable, "-m", "bpms", *args], cwd=ROOT, env=env,
                              capture_output=True, text=True, timeout=60)
        assert done.returncode == 2
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1, done.stderr
        assert "no display" in lines[0] and "bpms monitor" in lines[0]
        assert "bpms record" in lines[0] and "bpms replay" in lines[0]
        assert "Traceback" not in done.stderr and done.stdout == ""


def test_bad_options_and_calibration_files_warn_and_use_factory_values(qtbot, tmp_path):
    startup = StartupWindow()
    qtbot.addWidget(startup)
    bad_options = tmp_path / "options.toml"
    bad_options.write_text("[filter]\nkp_yaw = -3.0\n[display]\nrefresh_hz = 'fast'\n")
    options = startup.load_options_file(bad_options)
    box = startup.last_dialog
    assert box is not None and box.isVisible()
    assert "filter.kp_yaw" in box.detailedText() and "display.refresh_hz" in box.detailedText()
    assert options.filter.kp_yaw == Options().filter.kp_yaw
    assert options.display.refresh_hz == Options().display.refresh_hz
    box.close()
    bad_cal = tmp_path / "Calib.cfg"
    bad_cal.write_text("this is not a calibration file")
    table = startup.load_calibration_file(bad_cal)
    box = startup.last_dialog
    assert box.isVisible() and str(bad_cal) in box.detailedText()
    assert (table.values == load_factory_calibration().values).all()
    box.close()


def test_options_form_round_trip_and_rejects_bad_values(qtbot, tmp_path):
    dialog = OptionsDialog(Options())
    qtbot.addWidget(dialog)
    kp = dialog.editors[("filter", "kp_yaw")]
    assert isinstance(kp, QLineEdit) and "gain" in kp.toolTip()
    kp.setText("0.8")
    dialog.editors[("udp", "forward_to")].setText("127.0.0.1:6000, 127.0.0.1:6001")
    path = tmp_path / "edited.toml"
    dialog.save(path)
    saved = load_options(path)
    assert not saved.problems
    assert saved.filter.kp_yaw == 0.8
    assert saved.udp.forward_to == ["127.0.0.1:6000", "127.0.0.1:6001"]
    dialog.editors[("display", "refresh_hz")].setText("-5")
    options = dialog.options()
    assert [p.where for p in dialog.problems] == ["display.refresh_hz"]
    assert options.display.refresh_hz == Options().display.refresh_hz


def test_a_missing_suit_says_what_to_check_and_keeps_the_start_up_window(qtbot, tmp_path):
    runner = SessionRunner(ModeConfig(mode="suit", port=str(tmp_path / "ttyNOPE")), Options())
    try:
        runner.prepare()
    except ModeError as exc:
        assert all(word in str(exc) for word in ("paired", "battery", "port"))
    else:
        raise AssertionError("prepare() should fail")
    startup = StartupWindow()
    qtbot.addWidget(startup)
    startup.show()
    startup.select_mode("suit")
    startup.port_combo.setCurrentText(str(tmp_path / "ttyNOPE"))
    startup.go_button.click()
    qtbot.waitUntil(lambda: not startup.busy, timeout=10000)
    assert startup.isVisible() and startup.main_window is None
    assert "paired" in startup.last_dialog.text()
    startup.last_dialog.close()


def test_discover_finds_a_suit_on_a_pty_or_falls_back_to_the_simulated_suit(qtbot, tmp_path):
    from bpms.gui.modes import SimulatedSuit

    startup = StartupWindow(recording_dir=str(tmp_path))
    qtbot.addWidget(startup)
    startup.port_combo.clear()
    startup.port_combo.addItems([str(tmp_path / "ttyNOPE")])
    startup.select_mode("suit")
    startup.discover_button.click()
    qtbot.waitUntil(lambda: startup.discover_button.isEnabled(), timeout=10000)
    assert startup.mode == "sim" and "no suit answered" in startup.discover_label.text()
    suit = SimulatedSuit()  # a suit on a real pty, found like any serial port
    try:
        startup.port_combo.addItems([suit.path])
        startup.discover_button.click()
        qtbot.waitUntil(lambda: startup.discover_button.isEnabled(), timeout=10000)
        assert startup.mode == "suit" and startup.port_combo.currentText() == suit.path
        with qtbot.waitSignal(startup.mainWindowOpened, timeout=20000) as blocker:
            startup.go_button.click()
        window = blocker.args[0]
        window.panels.status_panel.data_button.click()
        qtbot.waitUntil(lambda: window.model.latest is not None, timeout=10000)
        assert window.model.last_status.source.description == f"suit {suit.path}"
        window.close()
    finally:
        suit.close()


def test_bpms_gui_sim_runs_and_quits_cleanly_on_ctrl_c(tmp_path):
    import signal
    import threading

    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    proc = subprocess.Popen([sys.executable, "-m", "bpms", "-v", "gui", "--sim",
                             "--recording-dir", str(tmp_path)], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    err_lines: list[str] = []

    def read_stderr() -> None:
        for line in proc.stderr:
            err_lines.append(line)

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    try:
        # Wait (with a deadline) for the event loop to run, not a fixed time.
        assert wait_until(lambda: any("the app is running" in ln for ln in err_lines)
                          or proc.poll() is not None, 60), "the app never said it runs"
        assert proc.poll() is None, "".join(err_lines)
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=20)
        reader.join(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        proc.stdout.close()
    err = "".join(err_lines)
    assert proc.returncode == 0, err
    assert "Traceback" not in err


def test_optional_windows_open_when_their_modules_exist(qtbot, tmp_path):
    startup = StartupWindow(recording_dir=str(tmp_path))
    qtbot.addWidget(startup)
    try:
        import bpms.gui.calibration_wizard
    except ImportError:
        assert not startup.wizard_button.isEnabled() and startup.wizard_button.toolTip()
    else:
        assert startup.wizard_button.isEnabled()
        wizard = startup.open_calibration_wizard()
        assert wizard is not None and wizard.isVisible()
        wizard.close()
    startup.select_mode("sim")
    with qtbot.waitSignal(startup.mainWindowOpened, timeout=20000) as blocker:
        startup.go_button.click()
    window = blocker.args[0]
    try:
        import bpms.gui.view3d  # noqa: F401
    except ImportError:
        assert not window.panels.view3d_button.isEnabled() and window.panels.view3d_button.toolTip()
    else:
        first, second = window.views.open_3d_view(), window.views.open_3d_view()
        assert first is not None and second is not None and first is not second
    window.close()


def test_a_bad_recording_is_reported_and_the_start_up_window_stays(qtbot, tmp_path):
    bad = tmp_path / "Raw_bad_1.bpmsraw"
    bad.write_bytes(b"not a recording at all")
    startup = StartupWindow(recording_dir=str(tmp_path))
    qtbot.addWidget(startup)
    startup.show()
    startup.select_mode("file")
    startup.file_edit.setText(str(bad))
    startup.go_button.click()
    qtbot.waitUntil(lambda: not startup.busy, timeout=10000)
    assert startup.main_window is None and startup.isVisible()
    assert str(bad) in startup.last_dialog.text()
    startup.last_dialog.close()


def test_no_port_is_pre_selected_and_the_simulated_suit_is(qtbot):
    startup = StartupWindow()
    qtbot.addWidget(startup)
    assert startup.port_combo.currentText() == ""
    assert startup.mode == "sim"
    startup.refresh_ports()
    assert startup.port_combo.currentText() == ""


def test_the_remembered_port_is_pre_selected_only_when_a_suit_answers(qtbot, tmp_path):
    from bpms.gui.modes import SimulatedSuit

    options = Options()
    options.serial.port = str(tmp_path / "ttyGONE")
    options.serial.discovery_timeout_s = 0.5
    silent = StartupWindow(options)
    qtbot.addWidget(silent)
    qtbot.waitUntil(lambda: "no suit answered" in silent.discover_label.text(), timeout=10000)
    assert silent.mode == "sim" and silent.port_combo.currentText() == ""
    suit = SimulatedSuit()
    try:
        options = Options()
        options.serial.port = suit.path
        startup = StartupWindow(options)
        qtbot.addWidget(startup)
        qtbot.waitUntil(lambda: startup.mode == "suit", timeout=10000)
        assert startup.port_combo.currentText() == suit.path
    finally:
        suit.close()


def test_when_go_finds_no_suit_the_same_dialog_offers_the_simulated_suit(qtbot, tmp_path):
    startup = StartupWindow(recording_dir=str(tmp_path))
    qtbot.addWidget(startup)
    startup.show()
    startup.select_mode("suit")
    startup.port_combo.setEditText(str(tmp_path / "ttyNOPE"))
    startup.go_button.click()
    qtbot.waitUntil(lambda: not startup.busy and startup.last_dialog is not None, timeout=10000)
    box = startup.last_dialog
    assert "paired" in box.text() and startup.main_window is None
    # the port that failed is not offered again at the next launch (issue 44.9)
    from bpms.gui.settings_store import SettingsStore

    assert SettingsStore().get("port") is None
    # each piece of advice once: what went wrong, then what to check
    for word in ("paired", "battery", "baud", "no suit"):
        assert (box.text() + box.informativeText()).lower().count(word) == 1, word
    with qtbot.waitSignal(startup.mainWindowOpened, timeout=20000) as blocker:
        startup.use_sim_button.click()
    window = blocker.args[0]
    assert window.runner.mode == "sim" and "SIMULATED" in window.windowTitle()
    qtbot.waitUntil(lambda: window.model.latest is not None, timeout=15000)  # live data
    # clearing Name returns to time-stamp names
    panel = window.panels.file_panel
    for name in ("subject7", ""):
        panel.name_edit.setText(name)
        panel.toggle_logging()
        qtbot.waitUntil(lambda: window.runner.session.status().recording is not None,
                        timeout=5000)
        panel.toggle_logging()
        qtbot.waitUntil(lambda: not panel.busy and panel.last_recording is not None
                        and not panel.logging, timeout=15000)
        stem = panel.last_recording.raw_path.name
        if name:
            assert stem == "Raw_subject7_1.bpmsraw"
        else:
            import re

            assert re.fullmatch(r"Raw_\d{8}-\d{6}_1\.bpmsraw", stem), stem
        panel.last_recording = None
    window.close()


def test_every_options_editor_lies_inside_its_tab_at_640_by_560(qtbot):
    dialog = OptionsDialog(Options())
    qtbot.addWidget(dialog)
    dialog.resize(640, 560)
    dialog.show()
    qtbot.waitExposed(dialog)
    assert (dialog.width(), dialog.height()) == (640, 560)
    for k, (section, scroll) in enumerate(dialog.scrolls.items()):
        dialog.tabs.setCurrentIndex(k)
        qtbot.waitUntil(scroll.isVisible, timeout=2000)
        viewport = scroll.viewport()
        for (sec, key), editor in dialog.editors.items():
            if sec != section:
                continue
            QApplication.processEvents()  # the page laid out
            # scroll as a user would: the editor's row near the top of the viewport
            top = editor.mapTo(scroll.widget(), editor.rect().topLeft()).y()
            scroll.verticalScrollBar().setValue(top - 8)
            QApplication.processEvents()
            top_left = editor.mapTo(viewport, editor.rect().topLeft())
            rect = editor.rect().translated(top_left)
            assert viewport.rect().contains(rect), (section, key, rect, viewport.rect())
            assert editor.width() >= 80, (section, key)  # room to type


def test_the_options_help_text_uses_the_forms_width(qtbot):
    from PyQt6.QtWidgets import QLabel

    dialog = OptionsDialog(Options())
    qtbot.addWidget(dialog)
    dialog.resize(640, 560)
    dialog.show()
    qtbot.waitExposed(dialog)
    QApplication.processEvents()
    scroll = next(iter(dialog.scrolls.values()))
    width = scroll.viewport().width()
    labels = [w for w in scroll.widget().findChildren(QLabel) if w.wordWrap()]
    longest = max(labels, key=lambda w: len(w.text()))
    assert longest.width() > 0.85 * width  # not a ~200 px column
    for label in labels:  # each help text above its field, as wide as the field
        editor = label.buddy()
        assert editor.mapTo(scroll.widget(), editor.rect().topLeft()).y() > \
            label.mapTo(scroll.widget(), label.rect().topLeft()).y()
