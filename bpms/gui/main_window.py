"""The main window: the standard data table, data controls and status, filter gains, file
operations, playback (file mode), UDP server (suit modes), and buttons opening plot and 3D
windows. Everything redraws on :class:`SessionModel`'s display timer.
"""

from __future__ import annotations

import importlib
import time

from PyQt6.QtCore import Qt, pyqtSignal
from PyQt6.QtGui import QAction, QKeySequence
from PyQt6.QtWidgets import (
    QComboBox,
    QHBoxLayout,
    QLabel,
    QMainWindow,
    QMessageBox,
    QPushButton,
    QScrollArea,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from bpms.gui.controls import FilePanel, GainsPanel, PlaybackPanel, StatusPanel, UdpServerPanel
from bpms.gui.data_table import DataTable, ImuTableModel
from bpms.gui.model import SessionModel
from bpms.gui.modes import MODE_LABELS, ModeError, SessionRunner
from bpms.gui.plots import PlotWindow, TickBlock, cells_plot, joint_angle_plot
from bpms.pipeline.session import LiveStatus


def optional_module(name: str) -> tuple[object | None, str]:
    """Import ``name`` lazily: (module, "") or (None, why it is unavailable)."""
    try:
        return importlib.import_module(name), ""
    except Exception as exc:
        return None, f"{name} is not available ({type(exc).__name__}: {exc})"


class MainWindow(QMainWindow):
    """One session's window. ``closed`` is emitted (after the session stopped) on close."""

    closed = pyqtSignal()

    def __init__(self, runner: SessionRunner, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        assert runner.session is not None, "runner.prepare() first"
        self.runner = runner
        self.options = runner.options
        self.model = SessionModel(self.options, self)
        self.plot_windows: list[PlotWindow] = []
        self.view3d_windows: list[QWidget] = []
        self._plot_count = 0
        self.tick_times_s: list[float] = []  # GUI time per display tick (bench/gui.py)
        self.setWindowTitle(f"BPMS Suite — {MODE_LABELS[runner.mode]}")
        calibration = runner.session.processor.sensor_calibration

        # -- the table -------------------------------------------------------------------
        self.table_model = ImuTableModel(calibration, self.options.display.angle_unit, self)
        self.table = DataTable(self.table_model)

        # -- buttons above the table -------------------------------------------------------
        top = QHBoxLayout()
        self.plot_button = QPushButton("Plot selection")
        self.plot_button.setToolTip("Select cells (Ctrl/Shift+click), then plot them (Ctrl+P)")
        self.plot_button.clicked.connect(self.plot_selection)
        self.joints_button = QPushButton("Joint angles")
        self.joints_button.setToolTip("Plot the 28 joint angles (Ctrl+J)")
        self.joints_button.clicked.connect(self.open_joint_plot)
        self.view3d_button = QPushButton("3D View")
        self.view3d_button.clicked.connect(self.open_3d_view)
        self._view3d, why = optional_module("bpms.gui.view3d")
        if self._view3d is None or not hasattr(self._view3d, "open_3d_window"):
            self.view3d_button.setEnabled(False)
            self.view3d_button.setToolTip(why or "bpms.gui.view3d has no open_3d_window")
        else:
            self.view3d_button.setToolTip("An independent 3D stick-figure window (Ctrl+3)")
        self.browser_button = QPushButton("Browser 3D view")
        self.browser_button.clicked.connect(self.open_browser_view)
        self.browser_views: list = []
        self._vpython, why = optional_module("bpms.gui.vpython_views")
        problem = why or (self._vpython.vpython_problem()  # type: ignore[union-attr]
                          if hasattr(self._vpython, "vpython_problem") else None)
        if problem or not hasattr(self._vpython, "open_browser_view"):
            self.browser_button.setEnabled(False)
            self.browser_button.setToolTip(problem or "no open_browser_view in "
                                                      "bpms.gui.vpython_views")
        else:
            self.browser_button.setToolTip("The stick figure in a web browser (vpython)")
        self.unit_combo = QComboBox()
        self.unit_combo.addItems(["deg", "rad"])
        self.unit_combo.setCurrentText(self.options.display.angle_unit)
        self.unit_combo.setToolTip("Unit of Euler angles in the table and new plots (Ctrl+U)")
        self.unit_combo.currentTextChanged.connect(self.set_angle_unit)
        for widget in (self.plot_button, self.joints_button, self.view3d_button,
                       self.browser_button):
            top.addWidget(widget)
        top.addStretch(1)
        top.addWidget(QLabel("Angles"))
        top.addWidget(self.unit_combo)
        left = QWidget()
        left_layout = QVBoxLayout(left)
        left_layout.addLayout(top)
        left_layout.addWidget(self.table)

        # -- side panels -------------------------------------------------------------------
        self.status_panel = StatusPanel()
        self.status_panel.dataToggled.connect(self.set_data)
        self.status_panel.resetZeroClicked.connect(self.reset_zero)
        self.gains_panel = GainsPanel(self.options.filter)
        self.gains_panel.gainsChanged.connect(self._set_gains)
        self.gains_panel.filterChanged.connect(self.select_filter)
        self.file_panel = FilePanel(runner)
        self.playback_panel = PlaybackPanel(runner) if runner.replay is not None else None
        self.udp_panel = UdpServerPanel(runner) if runner.mode in ("suit", "sim") else None
        side = QWidget()
        side_layout = QVBoxLayout(side)
        for panel in (self.status_panel, self.playback_panel, self.file_panel, self.udp_panel,
                      self.gains_panel):
            if panel is not None:
                side_layout.addWidget(panel)
        side_layout.addStretch(1)
        scroll = QScrollArea()
        scroll.setWidget(side)
        scroll.setWidgetResizable(True)
        scroll.setMinimumWidth(340)
        splitter = QSplitter(Qt.Orientation.Horizontal)
        splitter.addWidget(left)
        splitter.addWidget(scroll)
        splitter.setStretchFactor(0, 3)
        self.setCentralWidget(splitter)
        self.resize(1500, 720)
        self._shortcuts()

        self.model.samplesArrived.connect(self._on_samples)
        self.model.statusChanged.connect(self._on_status)
        self.model.attach(runner.session)

    def _shortcuts(self) -> None:
        for keys, slot in (("Ctrl+Space", lambda: self.set_data(not self.runner.data_on)),
                           ("Ctrl+R", self.reset_zero), ("Ctrl+P", self.plot_selection),
                           ("Ctrl+J", self.open_joint_plot), ("Ctrl+3", self.open_3d_view),
                           ("Ctrl+L", self.file_panel.toggle_logging),
                           ("Ctrl+U", self._toggle_unit), ("Ctrl+Q", self.close)):
            action = QAction(self)
            action.setShortcut(QKeySequence(keys))
            action.triggered.connect(slot)
            self.addAction(action)

    # -- commands ------------------------------------------------------------------------
    def set_data(self, on: bool) -> None:
        """Start Data / Stop Data."""
        if on:
            try:
                session = self.runner.start_data()
            except ModeError as exc:
                self.statusBar().showMessage(str(exc), 10000)
                return
            if session is not self.model.session:
                self.model.attach(session)
        else:
            self.runner.stop_data()
        self.status_panel.set_streaming(self.runner.data_on)

    def reset_zero(self) -> None:
        """Reset Zero at the next frame (stand in the calibration pose)."""
        if self.runner.session is not None and self.runner.data_on:
            self.runner.session.reset_zero()
            self.statusBar().showMessage("Reset Zero requested", 3000)

    def _set_gains(self, gains: dict) -> None:
        if self.runner.session is not None:
            try:
                self.runner.session.set_gains(**gains)
            except ValueError as exc:  # outside the valid range: refused, said why
                self.statusBar().showMessage(str(exc), 8000)
                return
            setattr_all = self.options.filter
            for name, value in gains.items():
                setattr(setattr_all, name, value)

    def select_filter(self, algorithm: str) -> None:
        """Switch the attitude filter of all 18 IMUs (Reset Zero is kept)."""
        if self.runner.session is not None:
            self.runner.session.select_filter(algorithm)
        self.options.filter.algorithm = algorithm
        self.statusBar().showMessage(f"filter: {algorithm}", 3000)

    def set_angle_unit(self, unit: str) -> None:
        self.table_model.set_angle_unit(unit)
        self.options.display.angle_unit = unit

    def _toggle_unit(self) -> None:
        self.unit_combo.setCurrentText("rad" if self.unit_combo.currentText() == "deg" else "deg")

    def plot_selection(self) -> PlotWindow | None:
        """A new plot window of the selected cells (one curve each)."""
        cells = self.table.selected_cells()
        if not cells:
            self.statusBar().showMessage("Select one or more numeric cells first "
                                         "(Ctrl/Shift+click)", 5000)
            return None
        self._plot_count += 1
        window = cells_plot(cells, self.table_model.angle_unit,
                            self.options.display.plot_history_s, self._plot_count)
        return self._show_plot(window)

    def open_joint_plot(self) -> PlotWindow:
        return self._show_plot(joint_angle_plot(self.table_model.angle_unit,
                                                self.options.display.plot_history_s))

    def _show_plot(self, window: PlotWindow) -> PlotWindow:
        window.destroyed.connect(lambda *_: self._forget(window))
        self.plot_windows.append(window)
        window.resize(max(window.width(), 640), max(window.height(), 380))
        window.show()
        return window

    def _forget(self, window: QWidget) -> None:
        if window in self.plot_windows:
            self.plot_windows.remove(window)
        if window in self.view3d_windows:
            self.view3d_windows.remove(window)

    def open_3d_view(self) -> QWidget | None:
        """An independent 3D stick-figure window (when bpms.gui.view3d is available)."""
        if not self.view3d_button.isEnabled() or self._view3d is None:
            return None
        window = self._view3d.open_3d_window(self.model)
        window.destroyed.connect(lambda *_: self._forget(window))
        self.view3d_windows.append(window)
        return window

    def open_browser_view(self) -> object | None:
        """The figure in a browser (the vpython extra), fed from this window's model."""
        if self._vpython is None or not self.browser_button.isEnabled():
            return None
        try:
            view = self._vpython.open_browser_view(self.model)  # type: ignore[union-attr]
        except (RuntimeError, OSError) as exc:
            self.statusBar().showMessage(f"Browser 3D view: {exc}", 10000)
            return None
        self.browser_views.append(view)
        return view

    # -- display tick ----------------------------------------------------------------------
    def _on_samples(self, samples: list) -> None:
        start = time.perf_counter()
        self.table_model.update(samples[-1])
        open_plots = [w for w in self.plot_windows if not w.closed]
        if open_plots:
            block = TickBlock.from_samples(samples, self.table_model.calibration)
            for window in open_plots:
                window.append(block)
        self.tick_times_s.append(time.perf_counter() - start)
        del self.tick_times_s[:-20000]

    def _on_status(self, st: LiveStatus) -> None:
        self.status_panel.show_status(st)
        self.file_panel.show_status(st)
        if self.playback_panel is not None:
            self.playback_panel.show_status(st)
            if self.runner.replay is not None and self.runner.replay.ended \
                    and self.runner.data_on:
                self.runner.stop_data()
                self.status_panel.set_streaming(False)
                self.statusBar().showMessage("end of the recording", 5000)
        if self.udp_panel is not None:
            self.udp_panel.show_status(st)

    # -- closing ---------------------------------------------------------------------------
    def shutdown(self) -> None:
        """Close plot and 3D windows, stop the session (files closed), free the source."""
        for window in [*self.plot_windows, *self.view3d_windows]:
            window.close()
        for view in self.browser_views:
            self.model.samplesArrived.disconnect(view.feed)
            view.close()
        self.browser_views.clear()
        self.model.attach(None)
        self.runner.close()

    def closeEvent(self, event) -> None:
        if self.file_panel.logging:
            answer = QMessageBox.question(self, "BPMS Suite",
                                          "Logging is on. Stop logging and close?")
            if answer != QMessageBox.StandardButton.Yes:
                event.ignore()
                return
        self.shutdown()
        self.closed.emit()
        super().closeEvent(event)
