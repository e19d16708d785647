"""The main window's fixed panels and their docks: the data table (with its buttons), the
status, the session and files, the filter settings and the event log, plus the drop area
for new plots. Mixed into :class:`bpms.gui.main_window.MainWindow`."""

from __future__ import annotations

from PyQt6.QtWidgets import (
    QComboBox,
    QDockWidget,
    QHBoxLayout,
    QLabel,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from bpms.gui.controls import FilePanel, GainsPanel, StatusPanel
from bpms.gui.data_table import DataTable, ImuTableModel, JointAngleModel, JointTable
from bpms.gui.docks import make_dock
from bpms.gui.event_log import EventLog
from bpms.gui.health import HealthPanel
from bpms.gui.optional import optional_module
from bpms.gui.plots import PlotDropArea
from bpms.gui.safety import guard_wheel
from bpms.gui.widgets import button, row
from bpms.io.timebase import stream_time


def _column() -> tuple[QWidget, QVBoxLayout]:
    box = QWidget()
    layout = QVBoxLayout(box)
    layout.setContentsMargins(2, 2, 2, 2)
    return box, layout


class WindowPanels:
    """``docks`` (the fixed panels by name) and the widgets inside them."""

    def _build_docks(self) -> None:
        table_box = self._build_table_box()
        status_box = self._build_status_box()
        session_box = self._build_session_box()
        filter_box = self._build_filter_box()
        self.event_log = EventLog()
        if self.playback_panel is not None:  # one clock in playback: the recording's
            panel = self.playback_panel
            self.event_log.use_recording_clock(lambda: stream_time(panel.shown))
        self.docks: dict[str, QDockWidget] = {
            "table": make_dock("Data table", "table", table_box),
            "status": make_dock("Status", "status", status_box, scroll=True),
            "session": make_dock("Session and files", "session", session_box, scroll=True),
            "filter": make_dock("Filter settings", "filter", filter_box, scroll=True),
            "events": make_dock("Event log", "events", self.event_log),
        }
        self.drop_area = PlotDropArea()
        self.drop_area.cellsDropped.connect(self._cells_dropped)
        self.drop_area.jointsDropped.connect(self._joints_dropped)
        # The docks fill the window; the central widget is an empty strip.
        central = QWidget()
        central.setMaximumSize(0, 0)
        self.setCentralWidget(central)

    def _build_table_box(self) -> QWidget:
        """The IMU table and the joint-angle table as tabs, under their buttons."""
        calibration = self.runner.session.processor.sensor_calibration
        self.table_model = ImuTableModel(calibration, self.options.display.angle_unit, self)
        self.table = DataTable(self.table_model)
        table_box, table_layout = _column()
        table_layout.addLayout(self._table_buttons())
        self.joint_model = JointAngleModel(self.options.display.angle_unit, self)
        self.joint_table = JointTable(self.joint_model)
        self.table_tabs = QTabWidget()
        self.table_tabs.setDocumentMode(True)
        self.table_tabs.addTab(self.table, "IMUs")
        self.table_tabs.addTab(self.joint_table, "Joint angles")
        table_layout.addWidget(self.table_tabs)
        return table_box

    def _table_buttons(self) -> QHBoxLayout:
        self.plot_button = button("Plot selection", self.plot_selection,
                                  "Select cells (Ctrl/Shift+click), then plot them (Ctrl+P); "
                                  "or drag cells onto a plot, or onto empty space")
        self.joints_button = button("Joint angles", self.open_joint_plot,
                                    "Plot the 28 joint angles (Ctrl+J)")
        self._offer_view3d()
        self._offer_browser_view()
        self.unit_combo = QComboBox()
        self.unit_combo.addItems(["deg", "rad"])
        self.unit_combo.setCurrentText(self.options.display.angle_unit)
        self.unit_combo.setToolTip("Unit of angles in the table and new plots (Ctrl+U)")
        self.unit_combo.currentTextChanged.connect(self.set_angle_unit)
        guard_wheel(self.unit_combo)
        return row(self.plot_button, self.joints_button, self.view3d_button,
                   self.browser_button, None, QLabel("Angles"), self.unit_combo)

    def _offer_view3d(self) -> None:
        """The 3D View button, disabled (saying why) when bpms.gui.view3d cannot load."""
        self.view3d_button = button("3D View", self.open_3d_view)
        self._view3d, why = optional_module("bpms.gui.view3d")
        if self._view3d is None or not hasattr(self._view3d, "View3DWindow"):
            self.view3d_button.setEnabled(False)
            self.view3d_button.setToolTip(why or "bpms.gui.view3d has no View3DWindow")
        else:
            self.view3d_button.setToolTip("Another 3D view dock (Ctrl+3)")

    def _offer_browser_view(self) -> None:
        """The Browser 3D view button, disabled (saying why) without the vpython extra."""
        self.browser_button = button("Browser 3D view", self.open_browser_view)
        self._vpython, why = optional_module("bpms.gui.vpython_views")
        problem = why or (self._vpython.vpython_problem()  # type: ignore[union-attr]
                          if hasattr(self._vpython, "vpython_problem") else None)
        if problem or not hasattr(self._vpython, "open_browser_view"):
            self.browser_button.setEnabled(False)
            self.browser_button.setToolTip(problem or "no open_browser_view in "
                                                      "bpms.gui.vpython_views")
        else:
            self.browser_button.setToolTip("The stick figure in a web browser (vpython)")

    def _build_status_box(self) -> QWidget:
        """The health light and the link's numbers over the session status."""
        self.health_panel = HealthPanel(self.simulated, listening=self._listening())
        self.status_panel = StatusPanel()
        self.status_panel.set_sources(self.runner.calibration_source,
                                      self.runner.options_source)

        self.status_panel.dataToggled.connect(self.set_data)
        self.status_panel.resetZeroClicked.connect(self.reset_zero)
        status_box, status_layout = _column()
        status_layout.addWidget(self.health_panel)
        status_layout.addWidget(self.status_panel)
        status_layout.addStretch(1)
        return status_box

    def _build_session_box(self) -> QWidget:
        """Playback (file mode), logging, UDP server (suit modes)."""
        self.file_panel = FilePanel(self.runner)
        self.file_panel.on_stopped.append(self._logging_stopped)
        self._build_mode_panels()
        if self.playback_panel is not None:  # the options' source says a filter chosen
            self.playback_panel.filterChosen.connect(
                lambda: self.status_panel.set_sources(self.runner.calibration_source,
                                                      self.runner.options_source))
        session_box, session_layout = _column()
        for panel in (self.playback_panel, self.file_panel, self.udp_panel):
            if panel is not None:
                session_layout.addWidget(panel)
        session_layout.addStretch(1)
        return session_box

    def _build_filter_box(self) -> QWidget:
        # playback: the recording's own filter and values (its processor's), not the app's
        processor = getattr(self.runner.session, "processor", None)
        shown = processor.options.filter if self.runner.replay is not None \
            and processor is not None else self.options.filter
        self.gains_panel = GainsPanel(shown)
        self.gains_panel.gainsChanged.connect(self._set_gains)
        self.gains_panel.filterChanged.connect(self.select_filter)
        self.gains_panel.logged.connect(lambda text, level: self.event_log.add(text, level))
        filter_box = QWidget()
        filter_layout = QVBoxLayout(filter_box)
        filter_layout.addWidget(self.gains_panel)
        filter_layout.addStretch(1)
        return filter_box
