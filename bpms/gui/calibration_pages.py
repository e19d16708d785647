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
    QFileDialog,
    QFormLayout,
    QGridLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QListWidget,
    QProgressBar,
    QRadioButton,
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
from bpms.gui.widgets import button, label, row, spin_box
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


def _table(headers: list[str], stretch_last: bool) -> QTableWidget:
    """A table of text under ``headers``, columns as wide as their contents (the last one
    taking the room left when ``stretch_last``), no row numbers."""
    table = QTableWidget(0, len(headers))
    table.setHorizontalHeaderLabels(headers)
    table.verticalHeader().setVisible(False)
    header = table.horizontalHeader()
    header.setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
    header.setStretchLastSection(stretch_last)
    header.setHighlightSections(False)
    return table


class _Page(QWizardPage):
    """A page of ``wizard`` (``_wizard``): its title and subtitle over a vertical layout
    (``box``)."""

    def __init__(self, wizard: QWizard, title: str, subtitle: str) -> None:
        super().__init__()
        self._wizard = wizard
        self.setTitle(title)
        self.setSubTitle(subtitle)
        self.box = QVBoxLayout(self)


class SetupPage(_Page):
    """IMUs, sensors, settings, the suit or the simulated suit, the output file."""

    def __init__(self, wizard: QWizard) -> None:
        super().__init__(wizard, "Sensor calibration", "Choose the IMUs and sensors to "
                         "calibrate. Values of everything not chosen are kept from the "
                         "existing file.")
        layout = self.box
        grid = QGridLayout()
        self.imu_boxes = [self._chosen(imu_label(i)) for i in range(N_IMUS)]
        for i, box in enumerate(self.imu_boxes):
            grid.addWidget(box, i // 4, i % 4)
        layout.addLayout(grid)
        every = [button(text, lambda _=False, on=on: [b.setChecked(on) for b in self.imu_boxes])
                 for text, on in (("All", True), ("None", False))]
        self.sensor_boxes = {s: self._chosen(s) for s in SENSORS}
        layout.addLayout(row(*every, None, *self.sensor_boxes.values()))
        form = QFormLayout()
        self.gyro_samples = spin_box(10, 100_000, 500, " readings")
        form.addRow("Gyro average of", self.gyro_samples)
        self.accel_samples = spin_box(10, 10_000, 200, " readings")
        form.addRow("Accel average of", self.accel_samples)
        self.sweep_s = spin_box(1.0, 1200.0, 120.0, " s")
        form.addRow("Magnetometer sweep", self.sweep_s)
        self.ellipsoid = QCheckBox("also fit an ellipsoid (hard + soft iron)")
        form.addRow("", self.ellipsoid)
        self.output = QLineEdit(str(Path.cwd() / "Calib.cfg"))
        self.output.textChanged.connect(self.completeChanged)
        form.addRow("Calibration file", row(self.output, button("Browse…", self._browse),
                                            grow=self.output))
        self.use_suit = QRadioButton("the suit")
        self.use_sim = QRadioButton("the simulated suit")
        self.use_suit.setChecked(True)
        form.addRow("Calibrate", row(self.use_suit, self.use_sim, None))
        layout.addLayout(form)
        self.status = label()
        layout.addWidget(self.status)

    def _chosen(self, text: str) -> QCheckBox:
        """A box ticked at first; ticking or unticking it may complete the page."""
        box = QCheckBox(text)
        box.setChecked(True)
        box.toggled.connect(self.completeChanged)
        return box

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


class GyroPage(_Page):
    def __init__(self, wizard: QWizard) -> None:
        super().__init__(wizard, "Gyroscope", "Lay the suit down and keep it still, then "
                         "press Start. Moving it refuses the capture.")
        self.start = button("Start", self.begin)
        self.progress = QProgressBar()
        self.motion = QLabel("motion: –")
        self.message = label()
        for w in (self.start, self.progress, self.motion, self.message):
            self.box.addWidget(w)
        self.box.addStretch(1)
        self.proc: GyroProcedure | None = None

    def initializePage(self) -> None:
        """Entered (again, after Back): a new capture, Start ready."""
        w = self._wizard
        self.proc = GyroProcedure(w.imus, w.setup.gyro_samples.value())
        self.proc.state = "idle"  # until Start
        self.tries = 0
        self.message.setText("")
        self.motion.setText("motion: –")
        self.progress.setValue(0)
        self.start.setText("Start")
        self.start.setEnabled(True)
        self.completeChanged.emit()

    def cleanupPage(self) -> None:
        """Back: a capture under way stops (entering again starts a new one)."""
        super().cleanupPage()
        self.proc = None

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


class AccelPage(_Page):
    def __init__(self, wizard: QWizard) -> None:
        super().__init__(wizard, "Accelerometer", "Six poses per IMU, in the order shown. "
                         "Hold the IMU still with the axis at its extreme, then Capture.")
        self.prompt = label()
        self.live = QLabel()
        self.still = QLabel()
        self.progress = QProgressBar()
        self.capture = button("Capture", self._capture)
        self.skip = button("Skip", self._skip)
        self.redo = button("Redo selected", self._redo)
        self.steps = QListWidget()
        self.message = label()
        for w in (self.prompt, self.live, self.still, self.progress):
            self.box.addWidget(w)
        self.box.addLayout(row(self.capture, self.skip, self.redo))
        self.box.addWidget(self.message)
        self.box.addWidget(self.steps, 1)
        self.proc: AccelProcedure | None = None

    def initializePage(self) -> None:
        """Entered (again, after Back): the six poses from the first."""
        w = self._wizard
        self.proc = AccelProcedure(w.imus, w.setup.accel_samples.value())
        self.message.setText("")
        self._refresh_steps()
        self._pose()

    def cleanupPage(self) -> None:
        super().cleanupPage()
        self.proc = None

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
        step = self.steps.currentRow()
        if self.proc is not None and step >= 0:
            self.proc.redo(step)
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


class MagPage(_Page):
    """The magnetometer sweep. Below the coverage the procedure asks for, the page is complete
    only when the sweep is done again or :attr:`accept_low` (the confirmation) is ticked."""

    HEADERS = ("IMU", "mag x [counts]\nmin / max", "mag y [counts]\nmin / max",
               "mag z [counts]\nmin / max", "sphere\ncoverage")

    def __init__(self, wizard: QWizard) -> None:
        super().__init__(wizard, "Magnetometer", "Away from metal, rotate the garment through "
                         "every orientation in one place for the whole sweep.")
        layout = self.box
        self.start = button("Start sweep", self.begin)
        self.stop = button("Finish now", self._finish)
        self.stop.setEnabled(False)
        self.remaining = label()
        layout.addLayout(row(self.start, self.stop, self.remaining, grow=self.remaining))
        self.progress = QProgressBar()
        layout.addWidget(self.progress)
        self.table = _table(list(self.HEADERS), stretch_last=True)
        layout.addWidget(self.table, 1)
        self.warnings = label()
        layout.addWidget(self.warnings)
        self.accept_low = QCheckBox()
        self.accept_low.setVisible(False)
        self.accept_low.toggled.connect(self.completeChanged)
        layout.addWidget(self.accept_low)
        self.proc: MagProcedure | None = None
        self._ticks = 0

    def initializePage(self) -> None:
        """Entered (again, after Back): a new sweep, Start ready."""
        self._new_procedure()

    def cleanupPage(self) -> None:
        """Back: a sweep under way stops (entering again starts a new one)."""
        super().cleanupPage()
        self.proc = None

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
        self.start.setEnabled(True)
        self.stop.setEnabled(False)
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


class SummaryPage(_Page):
    def __init__(self, wizard: QWizard) -> None:
        super().__init__(wizard, "Summary", "Old vs new values (counts; Gravity in counts per "
                         "g). Finish saves the legacy Calib.cfg and the modern .json beside it.")
        # the numbers beside their names (the last column not stretched)
        self.table = _table(["IMU", "value", "old", "new", "change"], stretch_last=False)
        self.box.addWidget(self.table, 1)
        self.quality = label(selectable=True)
        self.box.addWidget(self.quality)

    def initializePage(self) -> None:
        w = self._wizard
        update = w.update()
        new = update.merge(w.existing.table)
        rows = summary(w.existing.table, new, w.imus)
        self.table.setRowCount(len(rows))
        for r, line in enumerate(rows):
            for c, text in enumerate((imu_label(line.imu), line.field, _number(line.old),
                                      _number(line.new), _number(line.change, "+.2f"))):
                self.table.setItem(r, c, QTableWidgetItem(text) if c < 2 else _number_item(text))
        lines = update.quality.lines() or ["no quality figure (nothing measured)"]
        self.quality.setText("\n".join(named(line) for line in lines))

    def validatePage(self) -> bool:
        return self._wizard.save()
