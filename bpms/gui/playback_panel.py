"""The playback panel (file mode): the seek slider with its time labels, frame steps, the
position, the speed, which Reset Zero and which filter the recording plays with
(docs/main-window.md, "Playback")."""

from __future__ import annotations

from typing import TYPE_CHECKING

from PyQt6.QtCore import QSignalBlocker, Qt, pyqtSignal
from PyQt6.QtWidgets import (
    QComboBox,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QSizePolicy,
    QSlider,
    QStyle,
    QToolButton,
    QVBoxLayout,
)

from bpms.gui.modes import SessionRunner
from bpms.gui.safety import guard_wheel, set_enabled_keeping_focus
from bpms.gui.widgets import label, row
from bpms.io.options import ALGORITHMS
from bpms.io.timebase import stream_time

if TYPE_CHECKING:
    from PyQt6.QtWidgets import QWidget

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
        self.filter_combo.addItem(f"as recorded ({own})", None)
        for name in ALGORITHMS:
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
