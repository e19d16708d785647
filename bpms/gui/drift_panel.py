"""The drift check after playback (docs/analysis.md "Drift check"): each segment's attitude
change, in degrees, between the calibration pause at the start of a trial and the one at its
end, found automatically. The recording is filtered again in a background thread through the
one door, with the playback's calibration, options and filter, so the figures equal
``bpms drift``'s."""

from __future__ import annotations

from PyQt6.QtWidgets import (
    QDockWidget,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from bpms.gui.safety import BackgroundTask
from bpms.gui.widgets import label
from bpms.io.frames import IMU_NAMES

COLUMNS = ("segment", "total [deg]", "heading [deg]", "inclination [deg]")


def compute_drift(path: str, calibration, options, algorithm: str | None):
    """The drift report of the recording at ``path`` (runs in a worker thread)."""
    from bpms.analysis.drift import drift_of_recording
    from bpms.filter.door import open_for_processing

    return drift_of_recording(open_for_processing(path, calibration, options, algorithm))


class DriftPanel(QWidget):
    """A table of the per-IMU drift and one line saying which pauses were compared (or why
    there is no report)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        layout = QVBoxLayout(self)
        self.summary = label("computing the drift report…")
        self.table = QTableWidget(len(IMU_NAMES), len(COLUMNS))
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        self.table.setVerticalHeaderLabels([str(i) for i in range(len(IMU_NAMES))])
        layout.addWidget(self.summary)
        layout.addWidget(self.table)
        self.report = None
        self.task: BackgroundTask | None = None

    def start(self, path: str, calibration, options, algorithm: str | None) -> None:
        """Filter the recording again in the background and show the report when done."""
        self.task = BackgroundTask(self, lambda: compute_drift(path, calibration, options,
                                                               algorithm), self._done,
                                   name="bpms-drift")

    def _done(self, report, error: BaseException | None) -> None:
        if error is not None:
            self.summary.setText(f"no drift report: {error}")
            return
        self.report = report
        if not report.ok:
            self.summary.setText(f"no drift report: {report.problem}")
            return
        self.summary.setText(
            f"start pause ends {report.t_start:.2f} s, end pause starts {report.t_end:.2f} s "
            f"({report.t_end - report.t_start:.1f} s apart): attitude change of each segment")
        for i, name in enumerate(IMU_NAMES):
            values = (name, f"{report.total_deg[i]:.2f}", f"{report.heading_deg[i]:.2f}",
                      f"{report.inclination_deg[i]:.2f}")
            for col, text in enumerate(values):
                self.table.setItem(i, col, QTableWidgetItem(text))


def drift_dock(parent: QWidget) -> tuple[QDockWidget, DriftPanel]:
    """A closable, floatable dock holding a :class:`DriftPanel`."""
    dock = QDockWidget("Drift check", parent)
    dock.setObjectName("drift_check")
    panel = DriftPanel(dock)
    dock.setWidget(panel)
    return dock, panel
