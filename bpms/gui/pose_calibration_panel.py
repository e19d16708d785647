"""Pose calibration on the live session (docs/pose-calibration.md, docs/gui.md): Data ▸ Pose
calibration… opens a window with the two calibrations that need no neutral pose.

- **Declared posture**: a preset (``neutral``, ``suit``) or joint angles typed in (ISB names,
  degrees, e.g. ``elbow_r.flexion=15,knee_r.flexion=12``); *Calibrate in this posture* asks
  the session for it at the next frame (:meth:`LiveSession.calibrate_posture`, the road of
  ``bpms record``'s field command ``p``).
- **Functional calibration**: *Start* (the subject stands still 0.5 s, then does the knee and
  elbow flexions, an arm swing, a few steps), *Stop* ends the movements (or they end after the
  longest span given); then the session makes the calibration, adopts its zero and the window
  shows its quality report (:meth:`LiveSession.calibrate_functional` and
  :meth:`LiveSession.finish_functional`, the road of the field command ``f``).

Both are recorded by the session as ``reset_zero`` events, like Reset Zero, so ``bpms filter``
of the recording gives the numbers the session showed. Nothing here computes a calibration.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from PyQt6.QtCore import QTimer
from PyQt6.QtWidgets import (
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QDoubleSpinBox,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPlainTextEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from bpms.filter.posture_calibration import POSTURES, parse_posture

CUSTOM = "joint angles…"
STILL_S = 0.5  # the functional calibration's still window, s (as the field command f)
POLL_MS = 200


def posture_text(posture: dict[str, float]) -> str:
    """``"joint.angle=deg,..."`` of a declared posture (non-zero angles only)."""
    return ",".join(f"{name}={value:g}" for name, value in posture.items() if value)


class PoseCalibrationPanel(QWidget):
    """The two calibrations for the session ``session_of()`` returns (None: no live data,
    the buttons do nothing but say so). ``status``: the last thing it said."""

    def __init__(self, session_of: Callable[[], Any], parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.session_of = session_of
        self._report_seen: object | None = None
        self._running = False
        layout = QVBoxLayout(self)

        posture = QGroupBox("Declared posture: the subject holds it, still, when you click")
        rows = QVBoxLayout(posture)
        self.preset_combo = QComboBox()
        self.preset_combo.addItems([*POSTURES, CUSTOM])
        self.angles_edit = QLineEdit()
        self.angles_edit.setPlaceholderText("e.g. elbow_r.flexion=15,knee_r.flexion=12 (degrees)")
        self.angles_edit.setToolTip("Joint angles in degrees, names as in docs/joint-angles.md "
                                    "(ISB: flexion, abduction, external rotation positive); "
                                    "angles not named are 0")
        self.posture_button = QPushButton("Calibrate in this posture")
        self.posture_button.clicked.connect(self.calibrate_posture)
        self.preset_combo.currentTextChanged.connect(self._preset_chosen)
        line = QHBoxLayout()
        line.addWidget(QLabel("Posture"))
        line.addWidget(self.preset_combo)
        line.addWidget(self.angles_edit, 1)
        rows.addLayout(line)
        rows.addWidget(self.posture_button)
        layout.addWidget(posture)

        functional = QGroupBox("Functional calibration: still 0.5 s, then knee and elbow "
                               "flexions, an arm swing, a few steps")
        rows = QVBoxLayout(functional)
        self.seconds_spin = QDoubleSpinBox()
        self.seconds_spin.setRange(5.0, 120.0)
        self.seconds_spin.setValue(30.0)
        self.seconds_spin.setSuffix(" s at most")
        self.start_button = QPushButton("Start")
        self.start_button.clicked.connect(self.start_functional)
        self.stop_button = QPushButton("Stop")
        self.stop_button.setEnabled(False)
        self.stop_button.clicked.connect(self.stop_functional)
        line = QHBoxLayout()
        line.addWidget(QLabel("Movements"))
        line.addWidget(self.seconds_spin)
        line.addWidget(self.start_button)
        line.addWidget(self.stop_button)
        rows.addLayout(line)
        self.report_view = QPlainTextEdit()
        self.report_view.setReadOnly(True)
        self.report_view.setPlaceholderText("its quality report appears here")
        rows.addWidget(self.report_view)
        layout.addWidget(functional)

        self.status_label = QLabel("")
        self.status_label.setWordWrap(True)
        layout.addWidget(self.status_label)
        self._timer = QTimer(self)
        self._timer.timeout.connect(self.poll)
        self._preset_chosen(self.preset_combo.currentText())

    @property
    def status(self) -> str:
        return self.status_label.text()

    def _say(self, text: str) -> None:
        self.status_label.setText(text)

    def _preset_chosen(self, name: str) -> None:
        """A preset shows its angles (read-only); ``joint angles…`` lets them be typed."""
        custom = name == CUSTOM
        self.angles_edit.setReadOnly(not custom)
        if not custom:
            self.angles_edit.setText(posture_text(POSTURES[name]) or "all 0")

    def _session(self) -> Any:
        session = self.session_of()
        if session is None:
            self._say("no live data: start the data first")
        return session

    def declared_posture(self) -> tuple[str, dict[str, float]]:
        """(its description, joint angles °) of what is chosen. Raises ValueError."""
        name = self.preset_combo.currentText()
        if name != CUSTOM:
            return name, parse_posture(name)
        text = self.angles_edit.text().strip()
        if not text:
            raise ValueError("type the joint angles, e.g. elbow_r.flexion=15")
        return text, parse_posture(text)

    def calibrate_posture(self) -> None:
        """Declared-posture calibration at the next frame."""
        try:
            what, posture = self.declared_posture()
        except ValueError as exc:
            self._say(str(exc))
            return
        session = self._session()
        if session is not None:
            session.calibrate_posture(posture)
            self._say(f"pose calibration in the declared posture ({what}) at the next frame")

    def start_functional(self) -> None:
        """Functional calibration from the next frame: still, then the movements."""
        session = self._session()
        if session is None:
            return
        self._report_seen = session.functional_report
        session.calibrate_functional(self.seconds_spin.value(), STILL_S)
        self._running = True
        self._set_running(True)
        self._say(f"functional calibration: stand still {STILL_S:g} s, then the movements; "
                  "Stop when done")
        self._timer.start(POLL_MS)

    def stop_functional(self) -> None:
        """End the movements now: the calibration is made from the frames so far."""
        session = self.session_of()
        if session is not None and self._running:
            session.finish_functional()
            self._say("functional calibration: movements ended, calibrating…")

    def _set_running(self, running: bool) -> None:
        self.start_button.setEnabled(not running)
        self.stop_button.setEnabled(running)
        self.seconds_spin.setEnabled(not running)

    def poll(self) -> None:
        """Progress while the movements are collected; the report once the session made it."""
        if not self._running:
            return
        session = self.session_of()
        if session is None:
            self._say("functional calibration: no data; it goes on when the data starts again")
            return
        report = session.functional_report
        if report is not None and report is not self._report_seen:
            self._report_seen = report
            self._finished(report)
            return
        progress = session.functional_progress
        if progress is not None:
            frames, needed = progress
            dt = session.processor.options.filter.dt
            self._say(f"functional calibration: {frames * dt:.1f} of at most "
                      f"{needed * dt:.1f} s; Stop when the movements are done")
        elif any("functional calibration cancelled" in e for e in session.status().events):
            self._running = False
            self._timer.stop()
            self._set_running(False)
            self._say("functional calibration cancelled: stopped before the movements")

    def _finished(self, report: Any) -> None:
        self._running = False
        self._timer.stop()
        self._set_running(False)
        self.report_view.setPlainText("\n".join(report.lines()))
        missing = f"; missing: {', '.join(report.missing)}" if report.missing else ""
        self._say(f"functional calibration adopted (heading from {report.heading}){missing}")


class PoseCalibrationDialog(QDialog):
    """The panel in its own window (not modal: the views stay live behind it)."""

    def __init__(self, session_of: Callable[[], Any], parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Pose calibration")
        self.panel = PoseCalibrationPanel(session_of, self)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close)
        buttons.rejected.connect(self.close)
        layout = QVBoxLayout(self)
        layout.addWidget(self.panel)
        layout.addWidget(buttons)

