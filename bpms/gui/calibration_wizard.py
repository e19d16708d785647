"""The sensor calibration wizard (docs/units.md): choose IMUs and sensors, then gyro, accelerometer
and magnetometer steps live against the suit, a summary (old vs new, quality figures) and save.

The procedures are the Qt-free state machines of :mod:`bpms.calibration.procedures`; a display
timer reads the frame source without blocking and feeds the procedure of the current page.
With the simulated suit (``ScriptedCalibrationSource``) the wizard also plays the operator: it
tells the suit which pose to hold for the current step.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
from PyQt6.QtCore import Qt, QTimer
from PyQt6.QtWidgets import (
    QCheckBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QMessageBox,
    QProgressBar,
    QPushButton,
    QRadioButton,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
    QWizard,
    QWizardPage,
)

from bpms.calibration.frames import poll_raw
from bpms.calibration.output import load_existing, save_pair
from bpms.calibration.procedures import (
    AXES,
    SENSORS,
    AccelProcedure,
    GyroProcedure,
    MagProcedure,
    pose_name,
)
from bpms.calibration.result import CalibrationUpdate, collect, summary
from bpms.io.events import FrameSource
from bpms.io.frames import N_IMUS
from bpms.io.options import Options

PAGE_SETUP, PAGE_GYRO, PAGE_ACCEL, PAGE_MAG, PAGE_SUMMARY = range(5)


def _scene(source: FrameSource | None, *args, **kwargs) -> None:
    """Simulated suit only: hold the pose the current step asks for."""
    if source is not None and hasattr(source, "set_scene"):
        source.set_scene(*args, **kwargs)


class SetupPage(QWizardPage):
    """IMUs, sensors, settings, the suit or the simulated suit, the output file."""

    def __init__(self, wizard: CalibrationWizard) -> None:
        super().__init__()
        self.setTitle("Sensor calibration")
        self.setSubTitle("Choose the IMUs and sensors to calibrate. Values of everything not "
                         "chosen are kept from the existing file.")
        layout = QVBoxLayout(self)
        grid = QGridLayout()
        self.imu_boxes = []
        for i in range(N_IMUS):
            box = QCheckBox(f"IMU {i}")
            box.setChecked(True)
            box.toggled.connect(self.completeChanged)
            grid.addWidget(box, i // 6, i % 6)
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
    def __init__(self, wizard: CalibrationWizard) -> None:
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
            self.message.setText(f"<b style='color:#b00'>Refused:</b> {proc.message}")
            self.start.setText("Start again")
            self.start.setEnabled(True)
        elif proc.state == "done":
            self.message.setText(f"Done: {proc.message}.")
            self.completeChanged.emit()

    def isComplete(self) -> bool:
        return self.proc is not None and self.proc.state == "done"


class AccelPage(QWizardPage):
    def __init__(self, wizard: CalibrationWizard) -> None:
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
        self.prompt.setText(proc.prompt())
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
            self.steps.addItem(f"IMU {imu} {pose_name(axis, sign)}: {state}")

    def _capture(self) -> None:
        if self.proc is not None and not self.proc.capture():
            self.message.setText(self.proc.message)

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
                          f"{AXES[axis]}: {where} (most extreme so far {proc.best:.0f} counts)")
        self.still.setText("● still" if proc.still else "○ moving")
        self.progress.setValue(round(100 * proc.progress))
        if proc.message:
            self.message.setText(proc.message)
        if proc.index != before:
            self._pose()

    def isComplete(self) -> bool:
        return self.proc is not None and self.proc.done


class MagPage(QWizardPage):
    def __init__(self, wizard: CalibrationWizard) -> None:
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
        row.addWidget(self.remaining, 1)
        layout.addLayout(row)
        self.progress = QProgressBar()
        layout.addWidget(self.progress)
        self.table = QTableWidget(0, 5)
        self.table.setHorizontalHeaderLabels(["IMU", "x min/max, counts", "y min/max, counts",
                                              "z min/max, counts", "coverage"])
        layout.addWidget(self.table, 1)
        self.warnings = QLabel()
        self.warnings.setWordWrap(True)
        layout.addWidget(self.warnings)
        self.proc: MagProcedure | None = None
        self._ticks = 0

    def initializePage(self) -> None:
        w = self._wizard
        self.proc = MagProcedure(w.imus, w.setup.sweep_s.value(),
                                 ellipsoid=w.setup.ellipsoid.isChecked())
        self.proc.state = "idle"
        self.table.setRowCount(len(w.imus))
        for r, imu in enumerate(w.imus):
            self.table.setItem(r, 0, QTableWidgetItem(str(imu)))
        self.remaining.setText(f"{self.proc.duration_s:.0f} s sweep")

    def begin(self) -> None:
        assert self.proc is not None
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
                self.table.setItem(r, 1 + a, QTableWidgetItem(text))
            if imu in cover:
                self.table.setItem(r, 4, QTableWidgetItem(f"{100 * cover[imu]:.0f} %"))
        warnings = proc.warnings()
        self.warnings.setText("\n".join("⚠ " + w for w in warnings[:8]))
        if proc.state == "done":
            self.stop.setEnabled(False)
            self.remaining.setText("sweep done (counts; coverage = fraction of the sphere)")
            self.completeChanged.emit()

    def isComplete(self) -> bool:
        return self.proc is not None and self.proc.state == "done"


class SummaryPage(QWizardPage):
    def __init__(self, wizard: CalibrationWizard) -> None:
        super().__init__()
        self._wizard = wizard
        self.setTitle("Summary")
        self.setSubTitle("Old vs new values (counts; Gravity in counts per g). Finish saves the "
                         "legacy Calib.cfg and the modern .json beside it.")
        layout = QVBoxLayout(self)
        self.table = QTableWidget(0, 5)
        self.table.setHorizontalHeaderLabels(["IMU", "value", "old", "new", "change"])
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
            for c, text in enumerate((str(row.imu), row.field, f"{row.old:.2f}",
                                      f"{row.new:.2f}", f"{row.change:+.2f}")):
                self.table.setItem(r, c, QTableWidgetItem(text))
        lines = update.quality.lines() or ["no quality figure (nothing measured)"]
        self.quality.setText("\n".join(lines))

    def validatePage(self) -> bool:
        return self._wizard.save()


class CalibrationWizard(QWizard):
    """The calibration wizard. ``source``: a frame source to calibrate from (default: chosen
    on the first page — the suit through ``options.serial`` or the simulated suit);
    ``existing``: the file to merge into (default: the output file when it exists)."""

    def __init__(self, options: Options, parent: QWidget | None = None, *,
                 source: FrameSource | None = None, existing: str | Path | None = None,
                 output: str | Path | None = None, poll_ms: int = 40) -> None:
        super().__init__(parent)
        self.setWindowTitle("BPMS sensor calibration")
        self.options = options
        self.source = source
        self._own_source = source is None
        self._existing_path = existing
        self.existing = load_existing(None)
        self.imus: list[int] = []
        self.sensors: list[str] = []
        self.saved: tuple[Path, Path] | None = None
        self.sim_move_gyro = False  # tests: the simulated suit moves in the first gyro try
        self.setup = SetupPage(self)
        if output is not None:
            self.setup.output.setText(str(output))
        if source is not None:
            self.setup.use_sim.setEnabled(False)
            self.setup.use_suit.setText(source.status().description)
        self.gyro_page, self.accel_page = GyroPage(self), AccelPage(self)
        self.mag_page, self.summary_page = MagPage(self), SummaryPage(self)
        for pid, page in ((PAGE_SETUP, self.setup), (PAGE_GYRO, self.gyro_page),
                          (PAGE_ACCEL, self.accel_page), (PAGE_MAG, self.mag_page),
                          (PAGE_SUMMARY, self.summary_page)):
            self.setPage(pid, page)
        self.timer = QTimer(self)
        self.timer.setInterval(poll_ms)
        self.timer.timeout.connect(self.poll)
        self.frames = 0
        self.last_error = ""
        self._connecting: threading.Thread | None = None
        self._connected: FrameSource | None = None
        self._connect_error = ""
        self._connect_timer = QTimer(self)
        self._connect_timer.setInterval(50)
        self._connect_timer.timeout.connect(self._check_connection)
        self.resize(720, 560)

    # -- flow --------------------------------------------------------------------------
    def nextId(self) -> int:
        order = [PAGE_SETUP] + [{"gyro": PAGE_GYRO, "accel": PAGE_ACCEL, "mag": PAGE_MAG}[s]
                                for s in self.sensors] + [PAGE_SUMMARY]
        current = self.currentId()
        if current == PAGE_SUMMARY:
            return -1
        if current not in order:
            return PAGE_SUMMARY
        return order[order.index(current) + 1]

    def prepare(self) -> tuple[bool, str]:
        """Leaving the first page: read the existing file, open the source, start polling."""
        self.imus = self.setup.imus()
        self.sensors = self.setup.sensors()
        out = Path(self.setup.output.text().strip())
        if out.is_dir():
            return False, f"{out} is a folder: give a file name such as Calib.cfg"
        existing = self._existing_path or (out if out.exists() else None)
        self.existing = load_existing(existing)
        problems = "; ".join(str(p) for p in self.existing.problems[:3])
        if self.source is None:
            if self._connecting is None:  # connect in a worker thread; Next again when done
                self._connecting = threading.Thread(target=self._connect, daemon=True)
                self._connecting.start()
                self._connect_timer.start()
            return False, "connecting to the suit…"
        self.timer.start()
        return True, problems

    def _connect(self) -> None:
        try:
            self._connected = self._open_source()
        except Exception as exc:  # shown as one line on the page; the wizard stays open
            self._connect_error = str(exc) or type(exc).__name__

    def _check_connection(self) -> None:
        if self._connecting is None or self._connecting.is_alive():
            return
        self._connect_timer.stop()
        self._connecting = None
        if self._connected is not None:
            self.source, self._connected = self._connected, None
            self.next()
        else:
            self.setup.status.setText(f"Cannot connect: {self._connect_error}")

    def _open_source(self) -> FrameSource:
        if self.setup.use_sim.isChecked():
            from bpms.firmware.sim.calibration_poses import (
                CalibrationSuit,
                ScriptedCalibrationSource,
                changed_table,
            )

            return ScriptedCalibrationSource(CalibrationSuit(changed_table()), speed=1.0)
        from bpms.pipeline.sources import SuitFrameSource

        source = SuitFrameSource(self.options.serial.port or None, self.options.serial)
        try:
            source.connect()
        except Exception:
            source.close()
            raise
        return source

    def poll(self) -> None:
        """Timer: frames available now → the current page's procedure."""
        if self.source is None:
            return
        try:
            raw, errors = poll_raw(self.source, 0.0)
        except Exception as exc:  # a broken link: say so, keep the wizard open
            self.last_error = str(exc)
            return
        if not len(raw):
            return
        self.frames += len(raw)
        page = self.currentPage()
        if hasattr(page, "feed"):
            page.feed(raw, errors)

    def update(self) -> CalibrationUpdate:
        return collect(self.gyro_page.proc if "gyro" in self.sensors else None,
                       self.accel_page.proc if "accel" in self.sensors else None,
                       self.mag_page.proc if "mag" in self.sensors else None,
                       self.existing.table)

    def save(self) -> bool:
        update = self.update()
        if not update.imus:
            QMessageBox.warning(self, "Calibration", "Nothing was measured; nothing to save.")
            return False
        try:
            self.saved = save_pair(self.existing, update, self.setup.output.text().strip(),
                                   self.sensors, method="calibration wizard")
        except OSError as exc:
            QMessageBox.warning(self, "Calibration", f"Cannot save: {exc.strerror or exc}")
            return False
        return True

    def done(self, result: int) -> None:
        self.timer.stop()
        self._connect_timer.stop()
        for source in (self._connected, self.source if self._own_source else None):
            if source is not None:
                source.close()
        super().done(result)
