"""Panels of the main window: data controls and status, filter gains, file operations
(logging) and the UDP server (playback, file mode: :mod:`bpms.gui.playback_panel`). Every
panel reads the session's :class:`LiveStatus` snapshot that :class:`SessionModel` emits once
per display tick; button presses call :class:`LiveSession` / :class:`SessionRunner` methods,
which only queue work for the pipeline threads (the GUI thread never filters or writes
files).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from PyQt6.QtCore import Qt, pyqtSignal
from PyQt6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QWidget,
)

from bpms.gui.modes import SessionRunner
from bpms.gui.playback_panel import SPEEDS, ZERO_CHOICES, PlaybackPanel
from bpms.gui.safety import BackgroundTask, debounce, guard_wheel, set_enabled_keeping_focus
from bpms.gui.widgets import button, label, row
from bpms.io.event_types import FilterChoice, Gains
from bpms.io.filtered_file.reader import is_number
from bpms.io.options import ALGORITHM_SETTINGS, ALGORITHMS, FilterOptions, option_range
from bpms.io.rawfile import RecordingError
from bpms.io.udp.addresses import UdpConfigError

if TYPE_CHECKING:  # the filter (numba) loads with the first session, not the window
    from bpms.pipeline.session import LiveStatus

def _size(n: int) -> str:
    return f"{n / 1e6:.2f} MB" if n >= 1e6 else f"{n / 1e3:.1f} kB"


class StatusPanel(QGroupBox):
    """Start/Stop Data, Reset Zero and the link's numbers (units in the labels)."""

    dataToggled = pyqtSignal(bool)
    resetZeroClicked = pyqtSignal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Data", parent)
        form = QFormLayout(self)
        self.data_button = button("Start Data", tip="Start or stop the stream (Ctrl+Space)")
        debounce(self.data_button, lambda: self.dataToggled.emit(not self.streaming))
        self.reset_button = button("Reset Zero", self.resetZeroClicked,
                                   "Stand in the calibration pose and press (Ctrl+R); done "
                                   "automatically once the subject stands still, from 1 s "
                                   "after the stream starts")
        self.reset_button.setEnabled(False)
        form.addRow(row(self.data_button, self.reset_button))
        self.labels: dict[str, QLabel] = {}
        for key, title in (("source", "Source"), ("state", "Link state"),
                           ("rate", "Reception rate"), ("frames", "Frames"),
                           ("errors", "Error counter"), ("battery", "Battery"),
                           ("dropped", "Health"), ("latency", "Latency p99"),
                           ("extra", "Source counters"), ("event", "Last event"),
                           ("calibration", "Calibration"), ("options", "Options"),
                           ("filter", "Filter"), ("reset_zero", "Reset Zero")):
            self.labels[key] = label("–", selectable=True)
            form.addRow(title, self.labels[key])
        self.labels["calibration"].setToolTip("Where the sensor calibration in force came from")
        self.labels["options"].setToolTip("Where the options in force came from")
        self.labels["filter"].setToolTip("The attitude filter the numbers come from")
        self.labels["reset_zero"].setToolTip("The Reset Zero in force: who made it and when "
                                             "(stream time), or what it waits for")
        self.streaming = False

    def set_sources(self, calibration: str, options: str) -> None:
        """Where the calibration and the options in force came from
        (``SessionRunner.calibration_source`` / ``options_source``)."""
        self.labels["calibration"].setText(calibration or "–")
        self.labels["options"].setText(options or "–")

    def set_streaming(self, on: bool) -> None:
        self.streaming = on
        self.data_button.setText("Stop Data" if on else "Start Data")
        set_enabled_keeping_focus(on, self.data_button, self.reset_button)

    def show_status(self, st: LiveStatus, health_state: str | None = None) -> None:
        """``health_state``: the GUI's view of the link (:mod:`bpms.gui.health`), shown instead
        of the source's own word when data is on (a UDP client says "streaming" at 0 Hz)."""
        src = st.source
        state = src.state
        if health_state is not None and health_state != "streaming" \
                and not health_state.startswith("degraded"):
            state = health_state
        text = {
            "source": src.description,
            "state": state if st.running else f"{state} (session stopped)",
            "rate": f"{st.rate_hz:.1f} Hz (nominal 50 Hz)",
            "frames": f"{st.frames} received, {st.processed} processed",
            "errors": f"{st.error_bits} sensor error flags",
            "battery": f"{src.battery_v:.2f} V" if src.battery_v is not None else "–",
            "dropped": st.health_line(),
            "latency": f"{st.latency_p99_ms:.1f} ms",
            "extra": ", ".join(f"{k} {v}" for k, v in src.counters.items())
                     + (f", resyncs {src.resyncs}" if src.resyncs else ""),
            "event": st.events[-1] if st.events else "–",
        }
        # the labels beside the numbers, from the processor that made them
        for key, value in (("calibration", st.calibration_source),
                           ("options", st.options_source), ("filter", st.filter_name),
                           ("reset_zero", st.reset_zero)):
            if value:
                text[key] = value
        for key, value in text.items():
            if self.labels[key].text() != value:
                self.labels[key].setText(value or "–")


class GainsPanel(QGroupBox):
    """The attitude filter (all 18 IMUs) and the selected filter's own settings, editable at
    run time (applied from the next frame on). Only the chosen filter's settings are shown,
    each with its valid range beside it (``bpms.io.options.VALID_RANGES``).

    The panel owns no value: it shows the filter settings in force that the session reports
    (:meth:`show_settings`, from ``LiveStatus.filter_settings`` at each display tick: the
    processor's own, so a recording's gain events show as they are played). A value is sent
    when Enter is pressed or the field is left, as a typed :class:`bpms.io.event_types.Gains`
    (``gainsChanged(Gains)``; a filter picked: ``filterChanged(FilterChoice)``), and the
    event's own check is the only one: a value it refuses (outside its range, not a number)
    is not sent, the field goes back to the value in force and the check's message is shown
    under the fields and sent as ``logged(text, "warning")``; a change sent is logged as
    ``logged("filter gain …: old → new", "info")`` (the main window writes both to the event
    log).
    """

    gainsChanged = pyqtSignal(object)
    filterChanged = pyqtSignal(object)
    logged = pyqtSignal(str, str)

    def __init__(self, options: FilterOptions, parent: QWidget | None = None) -> None:
        super().__init__("Filter gains", parent)
        form = QFormLayout(self)
        form.setRowWrapPolicy(QFormLayout.RowWrapPolicy.WrapLongRows)
        fields = {f.name: f for f in dataclasses.fields(FilterOptions)}
        self.filter_combo = QComboBox()
        self.filter_combo.addItems(list(ALGORITHMS))
        self.filter_combo.setToolTip("mahony: the original DCM filter; observer and "
                                     "vqf keep the attitude right under body acceleration "
                                     "(docs/filters.md)")
        self.filter_combo.currentTextChanged.connect(self._filter_picked)
        guard_wheel(self.filter_combo)
        form.addRow("filter", self.filter_combo)
        self.edits: dict[str, QLineEdit] = {}
        self.rows: dict[str, QWidget] = {}
        self.labels: dict[str, QLabel] = {}
        names = dict.fromkeys(n for names in ALGORITHM_SETTINGS.values() for n in names)
        for name in names:  # one field per setting, also when two filters share it
            rng = option_range("filter", name)
            edit = QLineEdit()
            edit.setToolTip(f"{fields[name].metadata.get('help', '')}; valid "
                            f"{rng.describe() if rng else 'any'}")
            edit.editingFinished.connect(lambda n=name: self.apply(n))
            field = QWidget()
            line = QHBoxLayout(field)
            line.setContentsMargins(0, 0, 0, 0)
            line.addWidget(edit, 1)
            line.addWidget(label(rng.describe() if rng else "", wrap=False, style="color: #666"))
            self.edits[name], self.rows[name] = edit, field
            self.labels[name] = QLabel(_short_name(name))
            form.addRow(self.labels[name], field)
        self.message = label(style="color: #b00")
        form.addRow(self.message)
        #: the settings in force as the session last reported them (replaced, never edited)
        self.in_force = options
        self.show_settings(options)
        self.show_settings_of(options.algorithm)

    def show_settings(self, settings: FilterOptions | None, pending: int = 0) -> None:
        """Show the filter and settings in force (the session's report); a field being
        edited keeps its text until it is sent. ``pending``: changes the session has not
        applied yet (``LiveStatus.settings_pending``): its values are about to change, the
        panel waits for them."""
        if settings is None or pending:
            return
        self.in_force = settings
        if self.filter_combo.currentText() != settings.algorithm:
            self.filter_combo.blockSignals(True)
            self.filter_combo.setCurrentText(settings.algorithm)
            self.filter_combo.blockSignals(False)
            self.show_settings_of(settings.algorithm)
        for name, edit in self.edits.items():
            text = f"{getattr(settings, name):g}"
            if not edit.isModified() and edit.text() != text:
                edit.setText(text)

    def show_settings_of(self, algorithm: str) -> None:
        """Show only ``algorithm``'s own settings."""
        mine = set(ALGORITHM_SETTINGS.get(algorithm, ()))
        for name, widget in self.rows.items():
            widget.setVisible(name in mine)
            self.labels[name].setVisible(name in mine)
        self.message.setText("")

    def shown_settings(self) -> list[str]:
        """The settings whose fields are shown (those of the chosen filter)."""
        return [n for n, field in self.rows.items() if not field.isHidden()]

    def _filter_picked(self, algorithm: str) -> None:
        self.show_settings_of(algorithm)
        try:
            change = FilterChoice(algorithm)
        except ValueError as exc:  # (the combo offers only valid names)
            self._refuse_filter(str(exc))
            return
        self.filterChanged.emit(change)

    def _refuse_filter(self, why: str) -> None:
        self.filter_combo.blockSignals(True)
        self.filter_combo.setCurrentText(self.in_force.algorithm)
        self.filter_combo.blockSignals(False)
        self.show_settings_of(self.in_force.algorithm)
        self.message.setText(f"refused {why}")
        self.logged.emit(self.message.text(), "warning")

    def apply(self, name: str) -> bool:
        """Send the field of ``name`` as a :class:`Gains` (False: refused by its check, the
        message says why)."""
        edit = self.edits[name]
        text = edit.text().strip()
        old = getattr(self.in_force, name)
        edit.setModified(False)  # the field shows the session's value again from now on
        if text == f"{old:g}":
            return True
        try:
            change = Gains({name: float(text) if is_number(text) else text})
        except ValueError as exc:  # the event's own check: its message, the value in force
            return self._refuse(name, f"refused {exc}; kept {old:g}")
        self.message.setText("")
        self.gainsChanged.emit(change)  # the session applies it before the next frame
        self.logged.emit(f"filter gain {name}: {old:g} → {change.values[name]:g}", "info")
        return True

    def _refuse(self, name: str, message: str) -> bool:
        self.edits[name].setText(f"{getattr(self.in_force, name):g}")
        self.message.setText(message)
        self.logged.emit(message, "warning")
        return False


def _short_name(name: str) -> str:
    """``observer_k_incl`` → ``k_incl``: the filter's name is in the combo box above."""
    return next((name.removeprefix(f"{algorithm}_") for algorithm in ALGORITHM_SETTINGS
                 if name.startswith(f"{algorithm}_")), name)


class FilePanel(QGroupBox):
    """File operations: name, Raw / Filtered, Start/Stop Logging, current files and sizes."""

    def __init__(self, runner: SessionRunner, parent: QWidget | None = None) -> None:
        super().__init__("File operations", parent)
        self.runner = runner
        form = QFormLayout(self)
        self.name_edit = QLineEdit(runner.options.logging.name)
        self.name_edit.setPlaceholderText("empty = a time stamp")
        self.name_edit.setToolTip("Files are Raw_<name>_<n>.bpmsraw and Filtered_<name>_<n>.csv;"
                                  " n grows at every Start Logging")
        form.addRow("Name", self.name_edit)
        self.raw_box = QCheckBox("Raw")
        self.filtered_box = QCheckBox("Filtered")
        self.raw_box.setChecked(runner.options.logging.raw)
        self.filtered_box.setChecked(runner.options.logging.filtered)
        if runner.mode == "file":  # replaying a raw file: only filtered recording makes sense
            self.raw_box.setChecked(False)
            self.raw_box.setEnabled(False)
            self.raw_box.setToolTip("Raw recording is off in file mode (the file is the raw "
                                    "data)")
        self.degrees_box = QCheckBox("angles in deg")
        self.degrees_box.setToolTip("Filtered file angle unit (default rad)")
        form.addRow(row(self.raw_box, self.filtered_box, self.degrees_box))
        self.log_button = button("Start Logging", tip="Ctrl+L")
        debounce(self.log_button, self.toggle_logging)
        form.addRow(self.log_button)
        self.files_label = label("not logging", selectable=True)
        form.addRow(self.files_label)
        self.message = ""
        self.last_recording = None
        self.stopping: BackgroundTask | None = None
        self._focus_back = False  # the button had the focus when Stop Logging was pressed
        self.on_stopped: list = []  # callables(RecordingStatus | None) after a stop completes

    @property
    def logging(self) -> bool:
        session = self.runner.session
        return session is not None and session.status().recording is not None

    def toggle_logging(self) -> None:
        """Start Logging, or Stop Logging: the files are flushed and closed in the background
        (the button says "Stopping…" until they are)."""
        session = self.runner.session
        if session is None or (self.stopping is not None and self.stopping.running):
            return
        if self.logging:
            # the focus stays on this panel (Qt would hand it to the next field, the UDP
            # targets, text selected: one keystroke replaced them)
            self._focus_back = self.log_button.hasFocus()
            set_enabled_keeping_focus(False, self, self.log_button)
            self.log_button.setText("Stopping…")
            self.stopping = BackgroundTask(self, session.stop_logging, self._stopped,
                                           name="bpms-stop-logging")
            return
        raw = self.raw_box.isChecked() and self.raw_box.isEnabled()
        filtered = self.filtered_box.isChecked()
        if not raw and not filtered:
            self.files_label.setText("tick Raw and/or Filtered first")
            return
        try:
            session.start_logging(raw=raw, filtered=filtered,
                                  name=self.name_edit.text().strip(),  # "" = time stamp
                                  degrees=self.degrees_box.isChecked())
        except (RecordingError, OSError) as exc:
            self.files_label.setText(f"cannot start logging: {exc}")
            return
        self.log_button.setText("Stop Logging")

    def _stopped(self, rec, error: BaseException | None) -> None:
        self.log_button.setEnabled(True)
        if self._focus_back and self.hasFocus():
            self.log_button.setFocus(Qt.FocusReason.OtherFocusReason)
        self.log_button.setText("Start Logging")
        self.last_recording = rec
        if error is not None:
            self.files_label.setText(f"stopping failed: {error}")
        else:
            self.files_label.setText("stopped: " + self._describe(rec))
        for callback in self.on_stopped:
            callback(rec)

    @property
    def busy(self) -> bool:
        """A stop is still closing the files."""
        return self.stopping is not None and self.stopping.running

    @staticmethod
    def _describe(rec) -> str:
        if rec is None:
            return "–"
        parts = []
        if rec.raw_path is not None:
            parts.append(f"{rec.raw_path.name}: {rec.raw_records} frames, "
                         f"{_size(rec.raw_bytes)}")
        if rec.filtered_path is not None:
            size = rec.filtered_path.stat().st_size if rec.filtered_path.exists() else 0
            parts.append(f"{rec.filtered_path.name}: {_size(size)}")
        if rec.error:
            parts.append(f"error: {rec.error}")
        return "; ".join(parts)

    def show_status(self, st: LiveStatus) -> None:
        if st.recording is not None:
            text = "logging: " + self._describe(st.recording)
            if self.files_label.text() != text:
                self.files_label.setText(text)
            if not self.busy:
                self.log_button.setText("Stop Logging")
        elif self.log_button.text() == "Stop Logging":
            self.log_button.setText("Start Logging")


class UdpServerPanel(QGroupBox):
    """UDP server (suit and simulated modes): forward the live stream to the configured
    targets; shows the forwarder's counts."""

    def __init__(self, runner: SessionRunner, parent: QWidget | None = None) -> None:
        super().__init__("UDP server", parent)
        self.runner = runner
        form = QFormLayout(self)
        self.targets_edit = QLineEdit(", ".join(runner.options.udp.forward_to))
        self.targets_edit.setToolTip("host:port targets, comma-separated (multicast allowed)")
        form.addRow("Targets", self.targets_edit)
        self.button = button("Start UDP server")
        debounce(self.button, self.toggle)
        form.addRow(self.button)
        self.status_label = label("off")
        form.addRow(self.status_label)
        self.on = False

    def toggle(self) -> None:
        session = self.runner.session
        if session is None:
            return
        if self.on:
            session.stop_forwarding()
            self.on = False
            self.button.setText("Start UDP server")
            self.status_label.setText("off")
            self.targets_edit.setEnabled(True)
            return
        targets = [t.strip() for t in self.targets_edit.text().split(",") if t.strip()]
        if not targets:
            self.status_label.setText("cannot start: no target; enter host:port (e.g. "
                                      "127.0.0.1:5005), comma-separated for several")
            return
        try:
            session.start_forwarding(targets)
        except (UdpConfigError, OSError) as exc:
            self.status_label.setText(f"cannot start: {exc}")
            return
        self.on = True
        self.button.setText("Stop UDP server")
        self.targets_edit.setEnabled(False)

    def show_status(self, st: LiveStatus) -> None:
        if self.on:
            refused = f", nobody listening ({st.forward_refused})" if st.forward_refused else ""
            self.status_label.setText(f"sending to {', '.join(st.forwarding)}: "
                                      f"{st.forwarded} datagrams, {st.forward_errors} errors"
                                      f"{refused}")


__all__ = ["SPEEDS", "ZERO_CHOICES", "FilePanel", "GainsPanel", "PlaybackPanel", "StatusPanel",
           "UdpServerPanel"]
