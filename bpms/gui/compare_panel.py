"""Playback against an optical file (docs/compare.md, "In the app"): the recording being played is
compared with a Vicon or Qualisys export by ``bpms compare``'s own code (filtered again in a
background thread through the one door, with the playback's calibration, options and filter);
the chosen segment's angle — BPMS and optical over each other — and their difference are
plotted over the recording's time.

Wiring: :func:`add_compare_action` puts "Compare with optical file…" in a menu of the main
window (file playback only).
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PyQt6.QtCore import Qt
from PyQt6.QtWidgets import (
    QComboBox,
    QDockWidget,
    QFileDialog,
    QHBoxLayout,
    QMenu,
    QVBoxLayout,
    QWidget,
)

from bpms.gui.safety import BackgroundTask
from bpms.gui.widgets import label
from bpms.io.frames import IMU_NAMES

ANGLES = ("roll", "pitch", "yaw")


def compute_comparison(path: str, optical: str, calibration, options, algorithm: str | None):
    """The :class:`bpms.analysis.compare.CompareResult` of the recording at ``path`` against
    ``optical`` (runs in a worker thread; default map, estimated clock and frames)."""
    from bpms.analysis.compare import compare, load_recording, read_optical
    from bpms.filter.door import open_for_processing

    export = read_optical(optical)
    opened = open_for_processing(path, calibration, options, algorithm)
    return compare(load_recording(path, opened), export, recording_name=path)


class ComparePanel(QWidget):
    """One line of summary, the segment and angle choosers, and a plot: the BPMS angle, the
    optical angle and their difference (degrees) over the recording's time."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        layout = QVBoxLayout(self)
        self.summary = label("comparing with the optical file…")
        self.segment = QComboBox()
        self.angle = QComboBox()
        self.angle.addItems(ANGLES)
        row = QHBoxLayout()
        row.addWidget(label("segment", wrap=False))
        row.addWidget(self.segment, 1)
        row.addWidget(label("angle", wrap=False))
        row.addWidget(self.angle)
        self.plot = pg.PlotWidget()
        self.plot.addLegend()
        self.plot.setLabel("bottom", "time (recording)", units="s")
        self.plot.setLabel("left", "angle", units="deg")
        self.curves = {
            "bpms": self.plot.plot(name="BPMS", pen=pg.mkPen("#1f77b4", width=1.5)),
            "optical": self.plot.plot(name="optical", pen=pg.mkPen("#ff7f0e", width=1.5)),
            "difference": self.plot.plot(
                name="BPMS − optical",
                pen=pg.mkPen("#2ca02c", width=1, style=Qt.PenStyle.DashLine)),
        }
        layout.addWidget(self.summary)
        layout.addLayout(row)
        layout.addWidget(self.plot, 1)
        self.result = None
        self.task: BackgroundTask | None = None
        self.segment.currentIndexChanged.connect(self.redraw)
        self.angle.currentIndexChanged.connect(self.redraw)

    def start(self, path: str, optical: str, calibration=None, options=None,
              algorithm: str | None = None) -> None:
        """Compare in the background; the plot appears when done."""
        self.task = BackgroundTask(
            self, lambda: compute_comparison(path, optical, calibration, options, algorithm),
            self._done, name="bpms-compare")

    def _done(self, result, error: BaseException | None) -> None:
        if error is not None:
            self.summary.setText(f"no comparison: {str(error).splitlines()[0]}")
            return
        self.result = result
        self.summary.setText(
            f"clock offset {result.offset_s:+.3f} s ({result.offset_source}); RMSE per "
            "segment: " + ", ".join(f"{IMU_NAMES[s.imu]} {s.rmse_total:.2f}°"
                                    for s in result.segments))
        self.segment.blockSignals(True)
        self.segment.clear()
        self.segment.addItems([f"{IMU_NAMES[imu]} ({body.split(':')[-1]})"
                               for body, imu in result.pairs])
        self.segment.blockSignals(False)
        self.redraw()

    def series(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(t s, BPMS angle, optical angle, difference wrapped to ±180°) in degrees of the
        chosen segment and angle."""
        r = self.result
        j, k = self.segment.currentIndex(), self.angle.currentIndex()
        a = r.segment_angles_bpms_deg[:, j, k]
        b = r.segment_angles_optical_deg[:, j, k]
        diff = np.degrees(np.angle(np.exp(1j * np.radians(a - b))))
        return r.t, a, b, diff

    def redraw(self) -> None:
        if self.result is None or self.segment.currentIndex() < 0:
            return
        t, a, b, d = self.series()
        for key, y in (("bpms", a), ("optical", b), ("difference", d)):
            self.curves[key].setData(t, y, connect="finite")


def compare_dock(parent: QWidget) -> tuple[QDockWidget, ComparePanel]:
    """A closable, floatable dock holding a :class:`ComparePanel`."""
    dock = QDockWidget("Optical comparison", parent)
    dock.setObjectName("optical_comparison")
    panel = ComparePanel(dock)
    dock.setWidget(panel)
    return dock, panel


def open_comparison(window, optical: str | None = None) -> ComparePanel | None:
    """Ask for an optical file (unless given) and dock the comparison of the recording the
    main ``window`` plays; None when nothing is played or no file is chosen."""
    runner = window.runner
    if runner.replay is None or not runner.config.path:
        return None
    if optical is None:
        optical, _ = QFileDialog.getOpenFileName(
            window, "Optical file (Vicon Nexus CSV, Qualisys TSV)", "",
            "Optical exports (*.csv *.tsv);;All files (*)")
        if not optical:
            return None
    dock, panel = compare_dock(window)
    window.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, dock)
    panel.start(runner.config.path, optical, runner.playback_calibration,
                runner.playback_options, runner.playback_filter)
    return panel


def add_compare_action(window, menu: QMenu) -> None:
    """"Compare with optical file…" in ``menu`` (file playback)."""
    action = menu.addAction("Compare with optical file…")
    action.setToolTip("The recording against a Vicon or Qualisys export: the chosen "
                      "segment's angle by both, and the difference (docs/compare.md)")
    action.triggered.connect(lambda: open_comparison(window))
