"""The sensor calibration wizard (docs/units.md): choose IMUs and sensors, then gyro, accelerometer
and magnetometer steps live against the suit, a summary (old vs new, quality figures) and save.

The procedures are the Qt-free state machines of :mod:`bpms.calibration.procedures`; a display
timer reads the frame source without blocking and feeds the procedure of the current page.
With the simulated suit (``ScriptedCalibrationSource``) the wizard also plays the operator: it
tells the suit which pose to hold for the current step. The pages:
:mod:`bpms.gui.calibration_pages`.
"""

from __future__ import annotations

import threading
from pathlib import Path

from PyQt6.QtCore import QTimer
from PyQt6.QtWidgets import QMessageBox, QWidget, QWizard

from bpms.calibration.frames import poll_raw
from bpms.calibration.output import load_existing, save_pair
from bpms.calibration.result import CalibrationUpdate, collect
from bpms.gui.calibration_pages import (
    PAGE_ACCEL,
    PAGE_GYRO,
    PAGE_MAG,
    PAGE_SETUP,
    PAGE_SUMMARY,
    AccelPage,
    GyroPage,
    MagPage,
    SetupPage,
    SummaryPage,
)
from bpms.io.events import FrameSource
from bpms.io.options import Options

__all__ = ["PAGE_ACCEL", "PAGE_GYRO", "PAGE_MAG", "PAGE_SETUP", "PAGE_SUMMARY",
           "CalibrationWizard"]


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
