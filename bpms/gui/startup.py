"""The start-up window: choose the mode, load or edit options, load a calibration file, start
the sensor-calibration tool, GO.

Blocking work (suit discovery, opening the port, reading a recording) runs in a worker thread
polled by a timer, so the window stays responsive. A failure to start says what to check and
leaves this window open; closing the main window brings it back.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from PyQt6.QtCore import Qt, pyqtSignal
from PyQt6.QtGui import QKeySequence, QShortcut
from PyQt6.QtWidgets import (
    QButtonGroup,
    QComboBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QMessageBox,
    QRadioButton,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from bpms.gui import settings_store
from bpms.gui.main_window import MainWindow
from bpms.gui.modes import MODE_LABELS, MODES, ModeConfig, ModeError, SessionRunner
from bpms.gui.optional import optional_module
from bpms.gui.options_dialog import OptionsDialog
from bpms.gui.safety import BackgroundTask
from bpms.gui.widgets import button, label, row, spin_box
from bpms.io import defaults
from bpms.io.calib_file import CalibrationTable, load_calibration
from bpms.io.link import describe_candidate_ports, discover_suit
from bpms.io.options import Options, load_options
from bpms.io.problems import FileProblem


def show_problems(parent: QWidget | None, title: str, problems: list[FileProblem],
                  fallback: str) -> QMessageBox:
    """A non-blocking warning dialog listing every problem (file, where, what, fallback)."""
    box = QMessageBox(QMessageBox.Icon.Warning, title,
                      f"{len(problems)} problem(s) found; {fallback}.", parent=parent)
    box.setDetailedText("\n".join(str(p) for p in problems))
    box.setInformativeText("\n".join(f"• {p.where}: {p.message} ({p.fallback})"
                                     for p in problems[:12])
                           + (f"\n… and {len(problems) - 12} more" if len(problems) > 12
                              else ""))
    box.open()
    return box


def show_error(parent: QWidget | None, title: str, text: str) -> QMessageBox:
    """A non-blocking warning with one message."""
    box = QMessageBox(QMessageBox.Icon.Warning, title, text, parent=parent)
    box.open()
    return box


# -- the start-up window ------------------------------------------------------------------
class StartupWindow(QWidget):
    """Mode, options, calibration, GO. ``mainWindowOpened(MainWindow)`` after a good GO."""

    mainWindowOpened = pyqtSignal(object)

    def __init__(self, options: Options | None = None,
                 calibration: CalibrationTable | None = None,
                 recording_dir: str | None = None, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("BPMS Suite — start")
        # none given: the user's defaults, else factory (one notice in the log)
        self.options = options or defaults.default_options()
        self.calibration = calibration  # None: the user's default, else factory
        self.calibration_path: str | None = None
        self.recording_dir = recording_dir
        #: the simulated subject's options (ModeConfig.sim_options) and the subject's
        #: profile (ModeConfig.subject) given on the command line (bpms gui)
        self.sim_options: dict = {}
        self.subject = ""
        self.main_window: MainWindow | None = None
        self.last_dialog: QMessageBox | None = None
        self.calibration_wizard: QWidget | None = None
        self._worker: BackgroundTask | None = None

        layout = QVBoxLayout(self)
        # -- mode --------------------------------------------------------------------------
        mode_box = QGroupBox("Mode")
        mode_layout = QVBoxLayout(mode_box)
        self.mode_group = QButtonGroup(self)
        self.mode_buttons: dict[str, QRadioButton] = {}
        radios = QHBoxLayout()
        self.pages = QStackedWidget()
        for k, mode in enumerate(MODES):
            radio = QRadioButton(MODE_LABELS[mode])
            self.mode_group.addButton(radio, k)
            self.mode_buttons[mode] = radio
            radios.addWidget(radio)
        self.mode_group.idToggled.connect(
            lambda k, on: on and self.pages.setCurrentIndex(k))
        mode_layout.addLayout(radios)
        mode_layout.addWidget(self.pages)
        self.pages.addWidget(self._suit_page())
        self.pages.addWidget(self._udp_page())
        self.pages.addWidget(self._file_page())
        self.pages.addWidget(self._sim_page())
        layout.addWidget(mode_box)

        # -- options and calibration -------------------------------------------------------
        files_box = QGroupBox("Options and calibration")
        form = QFormLayout(files_box)
        self.options_label = QLabel()
        load = button("Load options…", lambda: self._choose(
            "Load options", "TOML (*.toml);;All (*)", self.load_options_file))
        form.addRow("Options", row(self.options_label, load,
                                   button("Edit options…", self.edit_options),
                                   grow=self.options_label))
        self.calibration_label = QLabel()
        self.wizard_button = button("Sensor calibration…", self.open_calibration_wizard)
        self._wizard_module, why = optional_module("bpms.gui.calibration_wizard")
        if self._wizard_module is None or not hasattr(self._wizard_module, "CalibrationWizard"):
            self.wizard_button.setEnabled(False)
            self.wizard_button.setToolTip(why or "no CalibrationWizard in "
                                                 "bpms.gui.calibration_wizard")
        else:
            self.wizard_button.setToolTip("Calibrate the IMUs' sensors (writes a Calib.cfg)")
        load = button("Load calibration…", lambda: self._choose(
            "Load calibration", "Calibration (*.cfg);;All (*)", self.load_calibration_file))
        form.addRow("Calibration", row(self.calibration_label, load, self.wizard_button,
                                       grow=self.calibration_label))
        self.default_button = button("Save as default", self.save_as_default,
                                     "Use these options and this calibration whenever none "
                                     "are given, from the next start on (bpms config)")
        form.addRow("", self.default_button)
        layout.addWidget(files_box)

        # -- GO ----------------------------------------------------------------------------
        self.status_label = label()
        self.go_button = button("GO", self.go, "Open the main window (Enter)")
        self.go_button.setDefault(True)
        self.go_button.setMinimumWidth(120)
        for key in (Qt.Key.Key_Return, Qt.Key.Key_Enter):
            QShortcut(QKeySequence(key), self, activated=self.go)
        layout.addLayout(row(self.status_label, self.go_button, grow=self.status_label))
        self._show_files()
        self.refresh_ports()
        # The simulated suit unless the remembered port answers (probed in the background):
        # a generic serial port is never pre-selected.
        self.select_mode("sim")
        if self.options.serial.port:
            self.probe_remembered_port(self.options.serial.port)
        self.resize(760, 420)
        settings_store.restore_startup(self)  # mode, port, folder... of the last launch

    # -- pages -----------------------------------------------------------------------------
    def _suit_page(self) -> QWidget:
        page = QWidget()
        form = QFormLayout(page)
        self.port_combo = QComboBox()
        self.port_combo.setEditable(True)
        self.port_combo.setToolTip("Serial port or pyserial URL; empty = discover at GO")
        self.discover_button = button("Discover", self.discover,
                                      "Ask every port for the suit's 'BPMS' answer")
        form.addRow("Port", row(self.port_combo, button("Refresh", self.refresh_ports),
                                self.discover_button, grow=self.port_combo))
        self.baud_spin = spin_box(1200, 4_000_000, self.options.serial.baud, " bit/s")
        form.addRow("Baud", self.baud_spin)
        self.discover_label = QLabel("")
        form.addRow(self.discover_label)
        return page

    def _udp_page(self) -> QWidget:
        page = QWidget()
        form = QFormLayout(page)
        self.listen_edit = QLineEdit(self.options.udp.listen)
        self.listen_edit.setToolTip("host:port to listen on (0.0.0.0 = every interface)")
        self.group_edit = QLineEdit()
        self.group_edit.setPlaceholderText("optional, e.g. 239.1.2.3")
        form.addRow("Listen on", self.listen_edit)
        form.addRow("Multicast group", self.group_edit)
        return page

    def _file_page(self) -> QWidget:
        page = QWidget()
        form = QFormLayout(page)
        self.file_edit = QLineEdit()
        self.file_edit.setPlaceholderText("a .bpmsraw recording or a legacy raw file")
        browse = button("Browse…", lambda: self._choose(
            "Raw recording", "Raw recordings (*.bpmsraw *.txt);;All (*)", self.file_edit.setText))
        form.addRow("Recording", row(self.file_edit, browse, grow=self.file_edit))
        return page

    def _sim_page(self) -> QWidget:
        page = QWidget()
        form = QFormLayout(page)
        self.seed_spin = spin_box(0, 1_000_000)
        form.addRow("Seed", self.seed_spin)
        form.addRow(QLabel("The simulated suit (bpms.firmware.sim) on a pseudo-terminal in this "
                           "process, streaming its scripted motion at 50 frames/s."))
        return page

    # -- mode ------------------------------------------------------------------------------
    @property
    def mode(self) -> str:
        return MODES[self.mode_group.checkedId()]

    def select_mode(self, mode: str) -> None:
        self.mode_buttons[mode].setChecked(True)

    def refresh_ports(self) -> None:
        """List the candidate ports; keep what the user typed, else leave the field empty
        (= discover at GO): no port is pre-selected just because it exists."""
        current = self.port_combo.currentText()
        self.port_combo.clear()
        for device, description in describe_candidate_ports():  # what the OS calls each port
            self.port_combo.addItem(device)
            self.port_combo.setItemData(self.port_combo.count() - 1, description or device,
                                        Qt.ItemDataRole.ToolTipRole)
        self.port_combo.setCurrentIndex(-1)  # no generic port pre-selected
        self.port_combo.setEditText(current)

    def probe_remembered_port(self, port: str) -> None:
        """Pre-select ``port`` and the suit mode only if a suit answers there."""
        timeout, baud = self.options.serial.discovery_timeout_s, self.baud_spin.value()
        self.discover_label.setText(f"asking the remembered port {port}…")

        def done(found: str | None, error: BaseException | None) -> None:
            if found and self.mode == "sim" and not self.port_combo.currentText():
                self.port_combo.setEditText(found)
                self.select_mode("suit")
                self.discover_label.setText(f"suit found on {found}")
            elif not found:
                self.discover_label.setText(f"no suit answered on the remembered port {port}")

        self._probe = BackgroundTask(self, lambda: discover_suit([port], timeout, baud), done)

    def discover(self) -> None:
        """Look for the suit in a worker thread; none found → the simulated suit."""
        ports = [self.port_combo.itemText(i) for i in range(self.port_combo.count())]
        self.discover_button.setEnabled(False)
        self.discover_label.setText(f"asking {len(ports)} port(s)…")
        timeout, baud = self.options.serial.discovery_timeout_s, self.baud_spin.value()

        def done(port: str | None, error: BaseException | None) -> None:
            self.discover_button.setEnabled(True)
            if port:
                self.port_combo.setCurrentText(port)
                self.discover_label.setText(f"suit found on {port}")
                self.select_mode("suit")
            else:
                why = f" ({error})" if error else ""
                self.discover_label.setText(f"no suit answered{why}: check pairing, power and "
                                            "battery; the simulated suit is selected")
                self.select_mode("sim")

        self._worker = BackgroundTask(self, lambda: discover_suit(ports, timeout, baud), done)

    def config(self) -> ModeConfig:
        return ModeConfig(mode=self.mode, port=self.port_combo.currentText().strip(),
                          baud=self.baud_spin.value(), listen=self.listen_edit.text().strip(),
                          group=self.group_edit.text().strip(),
                          path=self.file_edit.text().strip(), sim_seed=self.seed_spin.value(),
                          recording_dir=self.recording_dir,
                          sim_options=dict(self.sim_options), subject=self.subject)

    # -- files -----------------------------------------------------------------------------
    def _show_files(self) -> None:
        self.options_label.setText(f"{self.options.source}")
        self.calibration_label.setText(self.calibration.source if self.calibration
                                       else defaults.calibration_source())

    def save_as_default(self) -> str:
        """Make the options and calibration in force the user's defaults; returns what was
        said in the status line."""
        try:
            saved = [f"options → {defaults.save_default_options(self.options)}"]
            if self.calibration is not None:
                source = self.calibration_path or self.calibration
                saved.append(f"calibration → {defaults.save_default_calibration(source)}")
        except (OSError, ValueError) as exc:
            message = f"not saved as default: {exc}"
        else:
            message = "saved as default: " + "; ".join(saved)
        self.status_label.setText(message)
        return message

    def load_options_file(self, path: str | Path) -> Options:
        """Load options; problems → the warning dialog, factory values used for them."""
        self.options = load_options(path)
        self.baud_spin.setValue(self.options.serial.baud)
        self.listen_edit.setText(self.options.udp.listen)
        self._show_files()
        if self.options.problems:
            self.last_dialog = show_problems(self, "Options file", self.options.problems,
                                             "factory values used for these")
        return self.options

    def load_calibration_file(self, path: str | Path) -> CalibrationTable:
        """Load a Calib.cfg; problems → the warning dialog, factory values used for them."""
        self.calibration = load_calibration(path)
        self.calibration_path = str(path)
        self._show_files()
        if self.calibration.problems:
            self.last_dialog = show_problems(self, "Calibration file", self.calibration.problems,
                                             "factory values used for these")
        return self.calibration

    def _choose(self, title: str, filters: str, then: Callable[[str], object]) -> None:
        """Ask for a file to open; ``then(path)`` once one is chosen."""
        path, _ = QFileDialog.getOpenFileName(self, title, "", filters)
        if path:
            then(path)

    def edit_options(self) -> OptionsDialog:
        """Open the options form; OK applies it (problems → the warning dialog)."""
        dialog = OptionsDialog(self.options, self)

        def accepted() -> None:
            self.options = dialog.options()
            self._show_files()
            if dialog.problems:
                self.last_dialog = show_problems(self, "Options", dialog.problems,
                                                 "factory values used for these")

        dialog.accepted.connect(accepted)
        dialog.open()
        return dialog

    def open_calibration_wizard(self) -> QWidget | None:
        if self._wizard_module is None or not self.wizard_button.isEnabled():
            return None
        wizard = self._wizard_module.CalibrationWizard(self.options, self)

        def finished(*_args: object) -> None:
            saved = getattr(wizard, "saved", None)
            if saved:  # (Calib.cfg, companion): use the new calibration from now on
                self.load_calibration_file(saved[0])
                self.offer_calibration_default(saved[0])

        wizard.finished.connect(finished)
        wizard.show()
        self.calibration_wizard = wizard
        return wizard

    def offer_calibration_default(self, path: str | Path) -> QMessageBox:
        """Ask (non-blocking) whether a new calibration becomes the user's default."""
        box = QMessageBox(QMessageBox.Icon.Question, "Default calibration",
                          f"Make {path} your default calibration (used whenever none is "
                          "given)?", QMessageBox.StandardButton.Yes
                          | QMessageBox.StandardButton.No, self)

        def answered(button: int) -> None:
            if button == QMessageBox.StandardButton.Yes.value:
                try:
                    target = defaults.save_default_calibration(path)
                    self.status_label.setText(f"default calibration: {target}")
                except (OSError, ValueError) as exc:
                    self.status_label.setText(f"not made the default: {exc}")

        box.finished.connect(answered)
        box.open()
        self.last_dialog = box
        return box

    # -- GO --------------------------------------------------------------------------------
    @property
    def busy(self) -> bool:
        return self._worker is not None and self._worker.running

    def go(self) -> None:
        """Prepare the session in a worker thread, then open the main window."""
        if self.busy:
            return
        settings_store.remember_startup(self)
        try:
            runner = SessionRunner(self.config(), self.options, self.calibration)
        except ModeError as exc:
            self.last_dialog = show_error(self, "Cannot start", str(exc))
            return
        self.go_button.setEnabled(False)
        self.status_label.setText(f"starting {MODE_LABELS[runner.mode]}…")

        def done(_result: Any, error: BaseException | None) -> None:
            self.go_button.setEnabled(True)
            if error is not None:
                message = str(error) if isinstance(error, ModeError) else \
                    f"{type(error).__name__}: {error}"
                self.status_label.setText(message)
                if runner.mode == "suit":
                    if runner.config.port:  # not offered again at the next launch
                        settings_store.forget_port(runner.config.port)
                    self.last_dialog = self._offer_simulated_suit(error)
                else:
                    self.last_dialog = show_error(self, "Cannot start", message)
                self.show()
                return
            self.status_label.setText("")
            self.open_main_window(runner)

        self._worker = BackgroundTask(self, runner.prepare, done)

    def _offer_simulated_suit(self, error: BaseException) -> QMessageBox:
        """No suit: what went wrong, what to check (each point once), and the simulated
        suit offered in the same dialog."""
        reason = getattr(error, "reason", "") or str(error)
        checks = getattr(error, "checks", ())
        text = reason[:1].upper() + reason[1:] + "."
        if checks:
            text += "<br><br>Check that:<ul>" + "".join(f"<li>{c}</li>" for c in checks) \
                + "</ul>"
        box = QMessageBox(QMessageBox.Icon.Warning, "No suit found", text, parent=self)
        box.setTextFormat(Qt.TextFormat.RichText)
        box.setInformativeText("Or try the software with the simulated suit.")
        self.use_sim_button = box.addButton("Use the simulated suit",
                                            QMessageBox.ButtonRole.AcceptRole)
        box.addButton(QMessageBox.StandardButton.Close)
        box.setDefaultButton(self.use_sim_button)

        def clicked(button) -> None:
            if button is self.use_sim_button:
                self.select_mode("sim")
                self.go()

        box.buttonClicked.connect(clicked)
        box.open()
        return box

    def open_main_window(self, runner: SessionRunner) -> MainWindow:
        window = MainWindow(runner, saved_geometry=settings_store.saved_main_geometry())
        window.closed.connect(lambda: settings_store.remember_main(window, window.panels))
        window.closed.connect(self._main_closed)
        self.main_window = window
        window.show()
        if runner.mode == "sim":
            window.commands.set_data(True)  # one click on GO shows live data
        self.hide()
        self.mainWindowOpened.emit(window)
        return window

    def _main_closed(self) -> None:
        self.main_window = None
        self.show()
