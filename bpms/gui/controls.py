"""Panels of the main window: data controls and status, filter gains, file operations
(logging), playback (file mode) and the UDP server. Every panel reads the session's
:class:`LiveStatus` snapshot that :class:`SessionModel` emits once per display tick; button
presses call :class:`LiveSession` / :class:`SessionRunner` methods, which only queue work for
the pipeline threads (the GUI thread never filters or writes files).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from PyQt6.QtCore import QSignalBlocker, Qt, pyqtSignal
from PyQt6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QSizePolicy,
    QSlider,
    QStyle,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from bpms.gui.modes import SessionRunner
from bpms.gui.safety import BackgroundTask, debounce, guard_wheel, set_enabled_keeping_focus
from bpms.gui.widgets import button, label, row
from bpms.io.filtered_file.reader import is_number
from bpms.io.options import ALGORITHM_SETTINGS, FilterOptions, check_option, option_range
from bpms.io.rawfile import RecordingError
from bpms.io.timebase import stream_time
from bpms.io.udp.addresses import UdpConfigError

if TYPE_CHECKING:  # the filter (numba) loads with the first session, not the window
    from bpms.pipeline.session import LiveStatus

#: The playback window's Reset Zero choice (bpms.filter.zero_choice): label, mode.
ZERO_CHOICES = (("as recorded", "events"), ("automatic", "auto"), ("none", "none"))
SPEEDS: tuple[tuple[str, float | None], ...] = (
    ("0.25×", 0.25), ("0.5×", 0.5), ("1×", 1.0), ("2×", 2.0), ("4×", 4.0), ("8×", 8.0),
    ("max", None),
)


def _mmss(seconds: float, decimals: int = 0) -> str:
    """Seconds → "m:ss" (or "m:ss.ss" with ``decimals``)."""
    minutes, rest = divmod(max(0.0, seconds), 60.0)
    width = 2 if decimals == 0 else 3 + decimals
    return f"{int(minutes)}:{rest:0{width}.{decimals}f}"


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

    A value is applied when Enter is pressed or the field is left. One outside its range (or
    not a number) is refused: the field goes back to the value in force and the message, with
    the range, is shown under the fields and sent as ``logged(text, "warning")``; an accepted
    change is sent as ``gainsChanged({name: value})`` and ``logged("filter gain …: old →
    new", "info")`` (the main window writes both to the event log).
    """

    gainsChanged = pyqtSignal(dict)
    filterChanged = pyqtSignal(str)
    logged = pyqtSignal(str, str)

    def __init__(self, options: FilterOptions, parent: QWidget | None = None) -> None:
        super().__init__("Filter gains", parent)
        form = QFormLayout(self)
        form.setRowWrapPolicy(QFormLayout.RowWrapPolicy.WrapLongRows)
        fields = {f.name: f for f in dataclasses.fields(FilterOptions)}
        self.filter_combo = QComboBox()
        self.filter_combo.addItems(list(fields["algorithm"].metadata["choices"]))
        self.filter_combo.setCurrentText(options.algorithm)
        self.filter_combo.setToolTip("mahony: the original DCM filter; observer and "
                                     "vqf keep the attitude right under body acceleration "
                                     "(docs/filters.md)")
        self.filter_combo.currentTextChanged.connect(self.filterChanged.emit)
        self.filter_combo.currentTextChanged.connect(self.show_settings_of)
        guard_wheel(self.filter_combo)
        form.addRow("filter", self.filter_combo)
        self.values: dict[str, float] = {}
        self.edits: dict[str, QLineEdit] = {}
        self.rows: dict[str, QWidget] = {}
        self.labels: dict[str, QLabel] = {}
        names = dict.fromkeys(n for names in ALGORITHM_SETTINGS.values() for n in names)
        for name in names:  # one field per setting, also when two filters share it
            rng = option_range("filter", name)
            edit = QLineEdit(f"{getattr(options, name):g}")
            edit.setToolTip(f"{fields[name].metadata.get('help', '')}; valid "
                            f"{rng.describe() if rng else 'any'}")
            edit.editingFinished.connect(lambda n=name: self.apply(n))
            field = QWidget()
            line = QHBoxLayout(field)
            line.setContentsMargins(0, 0, 0, 0)
            line.addWidget(edit, 1)
            line.addWidget(label(rng.describe() if rng else "", wrap=False, style="color: #666"))
            self.values[name] = float(getattr(options, name))
            self.edits[name], self.rows[name] = edit, field
            self.labels[name] = QLabel(_short_name(name))
            form.addRow(self.labels[name], field)
        self.message = label(style="color: #b00")
        form.addRow(self.message)
        self._refused = ""
        self.show_settings_of(options.algorithm)

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

    def apply(self, name: str) -> bool:
        """Check the field of ``name`` and apply it (False: refused, the message says why)."""
        edit = self.edits[name]
        text = edit.text().strip()
        old = self.values[name]
        rng = option_range("filter", name)
        valid = f"valid {rng.describe()}" if rng is not None else "any number"
        try:
            value = check_option("filter", name, float(text))
        except ValueError as exc:
            why = str(exc).split(" (")[0] if is_number(text) else \
                f"filter.{name}: {text!r} is not a number"
            shown = "" if rng is not None and rng.describe() in why else f"; {valid}"
            return self._refuse(name, f"refused {why}{shown}; kept {old:g}")
        edit.setText(f"{value:g}")
        if value == old:
            return True
        self._refused = ""
        self.values[name] = value
        self.gainsChanged.emit({name: value})  # the receiver may refuse(): the session said no
        if self._refused:
            self.values[name] = old
            return self._refuse(name, f"refused filter.{name} = {value:g}: {self._refused}; "
                                      f"kept {old:g}")
        self.message.setText("")
        self.logged.emit(f"filter gain {name}: {old:g} → {value:g}", "info")
        return True

    def refuse(self, why: str) -> None:
        """Called by a ``gainsChanged`` receiver whose session refused the value."""
        self._refused = why or "refused"

    def _refuse(self, name: str, message: str) -> bool:
        self.edits[name].setText(f"{self.values[name]:g}")
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


class PlaybackPanel(QGroupBox):
    """File mode: seek slider, speed, position. Slider and speed disabled while playing.
    ``filterChosen`` after the filter played with changed (the options' source too)."""

    filterChosen = pyqtSignal()

    def __init__(self, runner: SessionRunner, parent: QWidget | None = None) -> None:
        super().__init__("Playback", parent)
        assert runner.replay is not None
        self.runner = runner
        self.replay = runner.replay
        self.step_buttons: list[QToolButton] = []
        self.shown = self.replay.position  # the frame at the slider
        #: frames delivered up to the one shown after a paused seek (the plots' window; the
        #: main window sets it to its plot history)
        self.window_frames = 1
        layout = QVBoxLayout(self)
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setRange(0, max(0, len(self.replay) - 1))
        self.slider.setToolTip("Seek (only while stopped)")
        self.slider.sliderReleased.connect(lambda: self.seek(self.slider.value()))
        self.slider.valueChanged.connect(self._slider_moved)
        guard_wheel(self.slider)
        layout.addWidget(self.slider)
        ticks = QHBoxLayout()
        self.tick_labels: list[QLabel] = []
        n_ticks = 5
        for k in range(n_ticks):
            tick = label(_mmss(stream_time(round(k / (n_ticks - 1) * len(self.replay)))),
                         wrap=False, style="color: #666; font-size: 9pt")
            self.tick_labels.append(tick)
            ticks.addWidget(tick)
            if k < n_ticks - 1:
                ticks.addStretch(1)
        layout.addLayout(ticks)
        steps = QHBoxLayout()
        icon = self.style().standardIcon
        sp = QStyle.StandardPixmap
        # icons from Qt's standard set (a font may lack the media glyphs)
        for pixmap, text, n, tip in (
                (sp.SP_MediaSkipBackward, "−1 s", -50, "Ctrl+Shift+Left"),
                (sp.SP_MediaSeekBackward, "−1", -1, "Ctrl+Left"),
                (sp.SP_MediaSeekForward, "+1", 1, "Ctrl+Right"),
                (sp.SP_MediaSkipForward, "+1 s", 50, "Ctrl+Shift+Right")):
            # tool buttons: as wide as icon and text (push buttons keep a style minimum that
            # makes four of them scroll a narrow panel sideways)
            tool = QToolButton()
            tool.setIcon(icon(pixmap))
            tool.setText(text)
            tool.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
            tool.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
            if n > 0:
                tool.setLayoutDirection(Qt.LayoutDirection.RightToLeft)  # text, then icon
            word = "forward" if n > 0 else "back"
            tool.setToolTip(f"Paused: {abs(n)} frame{'s' if abs(n) > 1 else ''} {word} "
                            f"({'1 s' if abs(n) == 50 else 'one frame'}; {tip})")
            tool.clicked.connect(lambda _=False, n=n: self.step(n))
            steps.addWidget(tool)
            self.step_buttons.append(tool)
        layout.addLayout(steps)
        self.position_label = label()  # a narrow panel: two lines, no sideways scroll
        self.speed_combo = QComboBox()
        self.speed_combo.addItems([text for text, _ in SPEEDS])
        self.speed_combo.setCurrentIndex(2)
        self.speed_combo.currentIndexChanged.connect(
            lambda i: self.replay.set_speed(SPEEDS[i][1]))
        guard_wheel(self.speed_combo)
        layout.addLayout(row(self.position_label, QLabel("Speed"), self.speed_combo,
                             grow=self.position_label))
        self.zero_combo = QComboBox()
        self.zero_combo.addItems([text for text, _ in ZERO_CHOICES])
        self.zero_combo.setToolTip("as recorded: the Reset Zero captures made live, at their "
                                   "frames; automatic: made again once the subject stands "
                                   "still; none: the IMUs' own attitudes. Changing it plays "
                                   "the recording again from its start "
                                   "(docs/opening-recordings.md)")
        self.zero_combo.currentIndexChanged.connect(
            lambda i: self.runner.set_playback_reset_zero(ZERO_CHOICES[i][1]))
        guard_wheel(self.zero_combo)
        layout.addLayout(row(QLabel("Reset Zero"), self.zero_combo, grow=self.zero_combo))
        self._filter_row(layout)
        self._update_label(self.replay.position)

    def _filter_row(self, layout: QVBoxLayout) -> None:
        """The filter played with: the recording's own (its filter and gain changes at their
        frames), or another chosen here, said in red under it."""
        own = self.runner.recorded_filter or "?"
        self.filter_combo = QComboBox()
        choices = dataclasses.fields(FilterOptions)
        names = next(f for f in choices if f.name == "algorithm").metadata["choices"]
        self.filter_combo.addItem(f"as recorded ({own})", None)
        for name in names:
            self.filter_combo.addItem(name, name)
        chosen = self.runner.playback_filter
        if chosen is not None:
            self.filter_combo.setCurrentIndex(self.filter_combo.findData(chosen))
        self.filter_combo.setToolTip("as recorded: the recording's filter, with its filter and "
                                     "gain changes at their frames; another: played with it "
                                     "instead, the recorded changes left out. Changing it "
                                     "plays the recording again from its start")
        self.filter_combo.currentIndexChanged.connect(self._filter_chosen)
        guard_wheel(self.filter_combo)
        layout.addLayout(row(QLabel("Filter"), self.filter_combo, grow=self.filter_combo))
        self.override_label = label(style="color: #d62728; font-weight: bold")
        layout.addWidget(self.override_label)
        self._show_override()

    def _filter_chosen(self, index: int) -> None:
        try:
            self.runner.set_playback_filter(self.filter_combo.itemData(index))
        except ValueError as exc:  # e.g. vqf not installed
            self.override_label.setText(str(exc))
            return
        self._show_override()
        self.filterChosen.emit()

    def _show_override(self) -> None:
        chosen = self.runner.playback_filter
        text = (f"Not as recorded: filter {chosen} chosen here; the recording's filter "
                f"and gain changes are not applied") if chosen else ""
        self.override_label.setText(text)
        self.override_label.setVisible(bool(text))

    def _slider_moved(self, value: int) -> None:
        if not self.slider.isSliderDown() and self.slider.isEnabled() \
                and value != self.replay.position:
            self.seek(value)
        self._update_label(value)

    def seek(self, index: int) -> None:
        """Jump to frame ``index`` (the filters are pre-rolled; Reset Zero is kept). While
        paused the frame itself is delivered with the :attr:`window_frames` before it, so
        every view shows it and the plots their window up to it."""
        if self.replay.playing:
            self.replay.seek(index)
        else:
            self.runner.show_frame(index, self.window_frames - 1)
        self.shown = index
        self._update_label(index)

    def step(self, n: int) -> None:
        """Paused: move ``n`` frames (clamped to the recording). Forward from the frame last
        delivered, the frames are delivered as playing would (no seek); back, it seeks."""
        if self.replay.playing:
            return
        index = min(max(0, self.shown + n), max(0, len(self.replay) - 1))
        with QSignalBlocker(self.slider):
            self.slider.setValue(index)
        if index > self.shown and self.replay.position == self.shown + 1 \
                and self.runner.show_next(index - self.shown):
            self.shown = index
            self._update_label(index)
            return
        self.seek(index)

    def _update_label(self, index: int) -> None:
        total = len(self.replay)
        self.position_label.setText(f"{_mmss(stream_time(index), 2)} / "
                                    f"{_mmss(stream_time(total), 2)} "
                                    f"(frame {index} of {total})")

    def show_status(self, st: LiveStatus | None = None) -> None:
        playing = self.replay.playing
        # disabled while playing; the focus stays on this panel (not the next field below)
        set_enabled_keeping_focus(not playing, self, self.slider, self.speed_combo,
                                  *self.step_buttons)
        if playing and not self.slider.isSliderDown():
            # the last delivered frame (position is the next one)
            pos = min(max(0, self.replay.position - 1), self.slider.maximum())
            with QSignalBlocker(self.slider):
                self.slider.setValue(pos)
            self.shown = pos
            self._update_label(pos)


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
