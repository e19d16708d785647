"""The pages of the sensor calibration wizard (:mod:`bpms.gui.calibration_wizard`): set-up,
gyroscope, accelerometer, magnetometer, summary. Each page feeds its procedure
(:mod:`bpms.calibration.procedures`) with the frames the wizard polls.

IMUs are named by number and name ("IMU 2 Right Shank") everywhere, also in the procedures'
messages (:func:`named`); no "nan" is ever shown (a value not measured yet reads "–"). The
magnetometer page asks for the sphere coverage the procedure wants (80 %): below it, Next
stays disabled until the sweep is done again or "use them anyway" is ticked (the
confirmation, with the figures on it). Each page is given its wizard
(:class:`bpms.gui.calibration_wizard.CalibrationWizard`: the chosen IMUs and sensors, the
set-up page, the frame source).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from PyQt6.QtCore import Qt
from PyQt6.QtWidgets import (
    QCheckBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGridLayout,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QListWidget,
    QProgressBar,
    QPushButton,
    QRadioButton,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWizard,
    QWizardPage,
)

from bpms.calibration.procedures import (
    AXES,
    SENSORS,
    AccelProcedure,
    GyroProcedure,
    MagProcedure,
    pose_name,
)
from bpms.calibration.result import summary
from bpms.io.events import FrameSource
from bpms.io.frames import IMU_NAMES, N_IMUS

PAGE_SETUP, PAGE_GYRO, PAGE_ACCEL, PAGE_MAG, PAGE_SUMMARY = range(5)


def imu_label(imu: int) -> str:
    """"2 Right Shank": the IMU's number (wire order) and name."""
    return f"{imu} {IMU_NAMES[imu]}"


def named(text: str) -> str:
    """Every "IMU n" of a procedure's message with the IMU's name after it."""
    return re.sub(r"\bIMU (\d+)\b",
                  lambda m: f"IMU {imu_label(int(m.group(1)))}" if int(m.group(1)) < N_IMUS
                  else m.group(0), text)


def _number(value: float, fmt: str = ".2f") -> str:
    return format(value, fmt) if np.isfinite(value) else "–"


def _number_item(text: str) -> QTableWidgetItem:
    item = QTableWidgetItem(text)
    item.setTextAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
    return item


def _counts(value: float) -> str:
    """A count for the page: "–" while there is none (never "nan")."""
    return f"{value:.0f} counts" if np.isfinite(value) else "–"


def _scene(source: FrameSource | None, *args, **kwargs) -> None:
    """Simulated suit only: hold the pose the current step asks for."""
    if source is not None and hasattr(source, "set_scene"):
        source.set_scene(*args, **kwargs)


class SetupPage(QWizardPage):
    """IMUs, sensors, settings, the suit or the simulated suit, the output file."""

    def __init__(self, wizard: QWizard) -> None:
        super().__init__()
        self.setTitle("Sensor calibration")
        self.setSubTitle("Choose the IMUs and sensors to calibrate. Values of everything not "
                         "chosen are kept from the existing file.")
        layout = QVBoxLayout(self)
        grid = QGridLayout()
        self.imu_boxes = []
        for i in range(N_IMUS):
            box = QCheckBox(imu_label(i))
            box.setChecked(True)
            box.toggled.connect(self.completeChanged)
            grid.addWidget(box, i // 4, i % 4)
            self.imu_boxes.append(box)
        layout.addLayout(grid)
        row = QHBoxLayout()
        for text, state in (("All", True), ("None", False)):
            b = QPushButton(text)
            b.clicked.connect(lambda _=False, s=state: [x.setChecked(s) for x in self.imu_boxes])
            row.addWidget(b)
        row.addStretch(1)
        self.sensor_boxes = {}
        for s in SENSORS:
            box = QCheckBox(s)
            box.setChecked(True)
            box.toggled.connect(self.completeChanged)
            row.addWidget(box)
            self.sensor_boxes[s] = box
        layout.addLayout(row)
        form = QFormLayout()
        self.gyro_samples = QSpinBox()
        self.gyro_samples.setRange(10, 100_000)
        self.gyro_samples.setValue(500)
        self.gyro_samples.setSuffix(" readings")
        form.addRow("Gyro average of", self.gyro_samples)
        self.accel_samples = QSpinBox()
        self.accel_samples.setRange(10, 10_000)
        self.accel_samples.setValue(200)
        self.accel_samples.setSuffix(" readings")
        form.addRow("Accel average of", self.accel_samples)
        self.sweep_s = QDoubleSpinBox()
        self.sweep_s.setRange(1.0, 1200.0)
        self.sweep_s.setValue(120.0)
        self.sweep_s.setSuffix(" s")
        form.addRow("Magnetometer sweep", self.sweep_s)
        self.ellipsoid = QCheckBox("also fit an ellipsoid (hard + soft iron)")
        form.addRow("", self.ellipsoid)
        out_row = QHBoxLayout()
        self.output = QLineEdit(str(Path.cwd() / "Calib.cfg"))
        self.output.textChanged.connect(self.completeChanged)
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        out_row.addWidget(self.output, 1)
        out_row.addWidget(browse)
        form.addRow("Calibration file", out_row)
        self.use_suit = QRadioButton("the suit")
        self.use_sim = QRadioButton("the simulated suit")
        self.use_suit.setChecked(True)
        src = QHBoxLayout()
        src.addWidget(self.use_suit)
        src.addWidget(self.use_sim)
        src.addStretch(1)
        form.addRow("Calibrate", src)
        layout.addLayout(form)
        self.status = QLabel()
        self.status.setWordWrap(True)
        layout.addWidget(self.status)
        self._wizard = wizard

    def _browse(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Calibration file", self.output.text(),
                                              "Calibration (*.cfg);;All files (*)")
        if path:
            self.output.setText(path)

    def imus(self) -> list[int]:
        return [i for i, b in enumerate(self.imu_boxes) if b.isChecked()]

    def sensors(self) -> list[str]:
        return [s for s, b in self.sensor_boxes.items() if b.isChecked()]

    def isComplete(self) -> bool:
        return bool(self.imus() and self.sensors() and self.output.text().strip())

    def validatePage(self) -> bool:
        ok, message = self._wizard.prepare()
        self.status.setText(message)
        return ok


class GyroPage(QWizardPage):
    def __init__(self, wizard: QWizard) -> None:
        super().__init__()
        self._wizard = wizard
        self.setTitle("Gyroscope")
        self.setSubTitle("Lay the suit down and keep it still, then press Start. Moving it "
                         "refuses the capture.")
        layout = QVBoxLayout(self)
        self.start = QPushButton("Start")
        self.start.clicked.connect(self.begin)
        self.progress = QProgressBar()
        self.motion = QLabel("motion: –")
        self.message = QLabel()
        self.message.setWordWrap(True)
        for w in (self.start, self.progress, self.motion, self.message):
            layout.addWidget(w)
        layout.addStretch(1)
        self.proc: GyroProcedure | None = None

    def initializePage(self) -> None:
        w = self._wizard
        self.proc = GyroProcedure(w.imus, w.setup.gyro_samples.value())
        self.proc.state = "idle"  # until Start
        self.tries = 0
        self.message.setText("")
        self.progress.setValue(0)

    def begin(self) -> None:
        assert self.proc is not None
        self.proc.restart()
        self.tries += 1
        _scene(self._wizard.source, "moving" if self._wizard.sim_move_gyro and
               self.tries == 1 else "still")
        self.start.setEnabled(False)
        self.message.setText("keep the suit still…")

    def feed(self, raw: np.ndarray, errors: np.ndarray) -> None:
        proc = self.proc
        if proc is None or proc.state != "collecting":
            return
        for k in range(len(raw)):
            proc.feed(raw[k], errors[k])
        self.progress.setValue(round(100 * proc.progress))
        self.motion.setText(f"motion: {proc.motion:.1f} counts gyro std "
                            f"(limit {proc.check.gyro_std_counts:g} counts)")
        if proc.state == "rejected":
            self.message.setText(f"<b style='color:#b00'>Refused:</b> {named(proc.message)}")
            self.start.setText("Start again")
            self.start.setEnabled(True)
        elif proc.state == "done":
            self.message.setText(f"Done: {named(proc.message)}.")
            self.completeChanged.emit()

    def isComplete(self) -> bool:
        return self.proc is not None and self.proc.state == "done"


class AccelPage(QWizardPage):
    def __init__(self, wizard: QWizard) -> None:
        super().__init__()
        self._wizard = wizard
        self.setTitle("Accelerometer")
        self.setSubTitle("Six poses per IMU, in the order shown. Hold the IMU still with the "
                         "axis at its extreme, then Capture.")
        layout = QVBoxLayout(self)
        self.prompt = QLabel()
        self.prompt.setWordWrap(True)
        self.live = QLabel()
        self.still = QLabel()
        self.progress = QProgressBar()
        row = QHBoxLayout()
        self.capture = QPushButton("Capture")
        self.capture.clicked.connect(self._capture)
        self.skip = QPushButton("Skip")
        self.skip.clicked.connect(self._skip)
        self.redo = QPushButton("Redo selected")
        self.redo.clicked.connect(self._redo)
        for b in (self.capture, self.skip, self.redo):
            row.addWidget(b)
        self.steps = QListWidget()
        self.message = QLabel()
        self.message.setWordWrap(True)
        for w in (self.prompt, self.live, self.still, self.progress):
            layout.addWidget(w)
        layout.addLayout(row)
        layout.addWidget(self.message)
        layout.addWidget(self.steps, 1)
        self.proc: AccelProcedure | None = None

    def initializePage(self) -> None:
        w = self._wizard
        self.proc = AccelProcedure(w.imus, w.setup.accel_samples.value())
        self._refresh_steps()
        self._pose()

    def _pose(self) -> None:
        proc = self.proc
        if proc is None:
            return
        self.prompt.setText(named(proc.prompt()))
        if not proc.done:
            _scene(self._wizard.source, "accel", *proc.current)
        self.capture.setEnabled(not proc.done)
        self.skip.setEnabled(not proc.done)
        self._refresh_steps()
        self.completeChanged.emit()

    def _refresh_steps(self) -> None:
        proc = self.proc
        if proc is None:
            return
        self.steps.clear()
        for k, step in enumerate(proc.steps):
            imu, axis, sign = step
            if step in proc.captures:
                c = proc.captures[step]
                state = f"{c.mean[axis]:.1f} counts (±{c.std[axis]:.1f})"
            elif step in proc.skipped:
                state = "skipped (old value kept)"
            else:
                state = "current" if k == proc.index else "to do"
            self.steps.addItem(f"IMU {imu_label(imu)} {pose_name(axis, sign)}: {state}")

    def _capture(self) -> None:
        if self.proc is not None and not self.proc.capture():
            self.message.setText(named(self.proc.message))

    def _skip(self) -> None:
        if self.proc is not None:
            self.proc.skip()
            self._pose()

    def _redo(self) -> None:
        row = self.steps.currentRow()
        if self.proc is not None and row >= 0:
            self.proc.redo(row)
            self._pose()

    def feed(self, raw: np.ndarray, errors: np.ndarray) -> None:
        proc = self.proc
        if proc is None or proc.done:
            return
        before = proc.index
        for k in range(len(raw)):
            proc.feed(raw[k], errors[k])
            if proc.index != before:
                break
        v = proc.live
        axis = proc.current[1] if not proc.done else 0
        where = "at the extreme" if proc.at_extreme else "not at the extreme"
        self.live.setText(f"raw a = ({v[0]:.0f}, {v[1]:.0f}, {v[2]:.0f}) counts; "
                          f"{AXES[axis]}: {where} (most extreme so far {_counts(proc.best)})")
        self.still.setText("● still" if proc.still else "○ moving")
        self.progress.setValue(round(100 * proc.progress))
        if proc.message:
            self.message.setText(named(proc.message))
        if proc.index != before:
            self._pose()

    def isComplete(self) -> bool:
        return self.proc is not None and self.proc.done


class MagPage(QWizardPage):
    """The magnetometer sweep. Below the coverage the procedure asks for, the page is complete
    only when the sweep is done again or :attr:`accept_low` (the confirmation) is ticked."""

    HEADERS = ("IMU", "mag x [counts]\nmin / max", "mag y [counts]\nmin / max",
               "mag z [counts]\nmin / max", "sphere\ncoverage")

    def __init__(self, wizard: QWizard) -> None:
        super().__init__()
        self._wizard = wizard
        self.setTitle("Magnetometer")
        self.setSubTitle("Away from metal, rotate the garment through every orientation in one "
                         "place for the whole sweep.")
        layout = QVBoxLayout(self)
        row = QHBoxLayout()
        self.start = QPushButton("Start sweep")
        self.start.clicked.connect(self.begin)
        self.stop = QPushButton("Finish now")
        self.stop.clicked.connect(self._finish)
        self.stop.setEnabled(False)
        row.addWidget(self.start)
        row.addWidget(self.stop)
        self.remaining = QLabel()
        self.remaining.setWordWrap(True)
        row.addWidget(self.remaining, 1)
        layout.addLayout(row)
        self.progress = QProgressBar()
        layout.addWidget(self.progress)
        self.table = QTableWidget(0, len(self.HEADERS))
        self.table.setHorizontalHeaderLabels(list(self.HEADERS))
        self.table.verticalHeader().setVisible(False)
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        header.setStretchLastSection(True)
        header.setHighlightSections(False)
        layout.addWidget(self.table, 1)
        self.warnings = QLabel()
        self.warnings.setWordWrap(True)
        layout.addWidget(self.warnings)
        self.accept_low = QCheckBox()
        self.accept_low.setVisible(False)
        self.accept_low.toggled.connect(self.completeChanged)
        layout.addWidget(self.accept_low)
        self.proc: MagProcedure | None = None
        self._ticks = 0

    def initializePage(self) -> None:
        self._new_procedure()

    def _new_procedure(self) -> None:
        w = self._wizard
        self.proc = MagProcedure(w.imus, w.setup.sweep_s.value(),
                                 ellipsoid=w.setup.ellipsoid.isChecked())
        self.proc.state = "idle"
        self.table.setRowCount(len(w.imus))
        for r, imu in enumerate(w.imus):
            self.table.setItem(r, 0, QTableWidgetItem(imu_label(imu)))
            for c in range(1, len(self.HEADERS)):
                self.table.setItem(r, c, QTableWidgetItem("–"))
        self.remaining.setText(f"{self.proc.duration_s:.0f} s sweep")
        self.accept_low.setChecked(False)
        self.accept_low.setVisible(False)
        self.start.setText("Start sweep")
        self.warnings.setText("")
        self.progress.setValue(0)
        self.completeChanged.emit()

    def begin(self) -> None:
        assert self.proc is not None
        if self.proc.state == "done":  # "Sweep again"
            self._new_procedure()
        self.proc.state = "sweeping"
        _scene(self._wizard.source, "sweep")
        self.start.setEnabled(False)
        self.stop.setEnabled(True)

    def _finish(self) -> None:
        if self.proc is not None and self.proc.state == "sweeping":
            self.proc.finish()
            self._show(True)

    def feed(self, raw: np.ndarray, errors: np.ndarray) -> None:
        proc = self.proc
        if proc is None or proc.state != "sweeping":
            return
        for k in range(len(raw)):
            proc.feed(raw[k], errors[k])
        self._ticks += 1
        self._show(proc.state == "done" or self._ticks % 5 == 0)

    def low_coverage(self) -> dict[int, float]:
        """IMU → coverage (0..1) of the IMUs below the procedure's threshold (sweep done)."""
        proc = self.proc
        if proc is None or proc.state != "done":
            return {}
        return {i: c for i, c in proc.coverage().items() if c < proc.min_coverage}

    def _show(self, full: bool) -> None:
        proc = self.proc
        assert proc is not None
        self.progress.setValue(round(100 * proc.progress))
        self.remaining.setText(f"{proc.remaining_s:.0f} s left")
        cover = proc.coverage() if full else {}
        for r, imu in enumerate(proc.imus):
            for a in range(3):
                lo, hi = proc.mins[imu, a], proc.maxs[imu, a]
                text = f"{lo:.0f} / {hi:.0f}" if np.isfinite(lo) else "–"
                self.table.setItem(r, 1 + a, _number_item(text))
            if imu in cover:
                self.table.setItem(r, 4, _number_item(f"{100 * cover[imu]:.0f} %"))
        warnings = proc.warnings()
        self.warnings.setText("\n".join("⚠ " + named(w) for w in warnings[:8]))
        if proc.state == "done":
            self.stop.setEnabled(False)
            self.start.setText("Sweep again")
            self.start.setEnabled(True)
            low = self.low_coverage()
            self.remaining.setText("sweep done (counts; coverage = fraction of the sphere "
                                   f"seen, {100 * proc.min_coverage:.0f} % wanted)")
            if low:
                worst = ", ".join(f"IMU {imu_label(i)} {100 * c:.0f} %" for i, c in low.items())
                self.accept_low.setText(f"Use these values anyway: coverage below "
                                        f"{100 * proc.min_coverage:.0f} % ({worst})")
                self.accept_low.setVisible(True)
            self.completeChanged.emit()

    def isComplete(self) -> bool:
        if self.proc is None or self.proc.state != "done":
            return False
        return not self.low_coverage() or self.accept_low.isChecked()


class SummaryPage(QWizardPage):
    def __init__(self, wizard: QWizard) -> None:
        super().__init__()
        self._wizard = wizard
        self.setTitle("Summary")
        self.setSubTitle("Old vs new values (counts; Gravity in counts per g). Finish saves the "
                         "legacy Calib.cfg and the modern .json beside it.")
        layout = QVBoxLayout(self)
        self.table = QTableWidget(0, 5)
        self.table.setHorizontalHeaderLabels(["IMU", "value", "old", "new", "change"])
        self.table.verticalHeader().setVisible(False)
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        header.setStretchLastSection(False)  # the numbers beside their names
        header.setHighlightSections(False)
        layout.addWidget(self.table, 1)
        self.quality = QLabel()
        self.quality.setWordWrap(True)
        self.quality.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        layout.addWidget(self.quality)

    def initializePage(self) -> None:
        w = self._wizard
        update = w.update()
        new = update.merge(w.existing.table)
        rows = summary(w.existing.table, new, w.imus)
        self.table.setRowCount(len(rows))
        for r, row in enumerate(rows):
            for c, text in enumerate((imu_label(row.imu), row.field, _number(row.old),
                                      _number(row.new), _number(row.change, "+.2f"))):
                self.table.setItem(r, c, QTableWidgetItem(text) if c < 2 else _number_item(text))
        lines = update.quality.lines() or ["no quality figure (nothing measured)"]
        self.quality.setText("\n".join(named(line) for line in lines))

    def validatePage(self) -> bool:
        return self._wizard.save()
