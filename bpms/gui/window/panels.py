"""The main window's fixed panels and their docks: the data table (with its buttons), the
status, the session and files (playback, logging, UDP server), the filter settings and the
event log, plus the drop area for new plots.

:class:`WindowPanels` makes these widgets and owns them; it calls nothing outside itself.
What their buttons and signals do is wired in :class:`bpms.gui.main_window.MainWindow`.
"""

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

from bpms.gui.controls import FilePanel, GainsPanel, PlaybackPanel, StatusPanel, UdpServerPanel
from bpms.gui.data_table import DataTable, ImuTableModel, JointAngleModel, JointTable
from bpms.gui.docks import make_dock
from bpms.gui.event_log import EventLog
from bpms.gui.health import HealthPanel
from bpms.gui.modes import SessionRunner
from bpms.gui.optional import optional_module
from bpms.gui.plots import PlotDropArea
from bpms.gui.safety import guard_wheel
from bpms.gui.widgets import button, row
from bpms.io.options import Options
from bpms.io.timebase import stream_time


def _column() -> tuple[QWidget, QVBoxLayout]:
    box = QWidget()
    layout = QVBoxLayout(box)
    layout.setContentsMargins(2, 2, 2, 2)
    return box, layout


def listening_address(runner: SessionRunner) -> str | None:
    """The UDP client's listening address (host:port), else None."""
    source = runner.session.source if runner.session is not None else None
    udp = getattr(source, "udp", None)
    return str(udp.listening) if udp is not None and hasattr(udp, "listening") else None


class WindowPanels:
    """``docks`` (the fixed panels by name) and the widgets inside them.

    ``parent``: the window (parent of the table models); ``simulated``: the health light says
    SIMULATED; ``window_frames``: how many frames a paused playback seek redraws (the plots'
    history). ``playback_panel`` is None unless a file plays, ``udp_panel`` unless a suit
    (real or simulated) streams. ``view3d_module`` / ``vpython_module``: the optional 3D
    modules, None (their button disabled, saying why) when they cannot load.
    """

    def __init__(self, runner: SessionRunner, options: Options, parent: QWidget, *,
                 simulated: bool, window_frames: int) -> None:
        self._runner = runner
        self._options = options
        table_box = self._build_table_box(parent)
        status_box = self._build_status_box(simulated)
        session_box = self._build_session_box(window_frames)
        filter_box = self._build_filter_box()
        self.event_log = EventLog()
        if self.playback_panel is not None:  # one clock in playback: the recording's
            panel = self.playback_panel
            self.event_log.use_recording_clock(lambda: stream_time(panel.shown))
        self.gains_panel.logged.connect(lambda text, level: self.event_log.add(text, level))
        self.docks: dict[str, QDockWidget] = {
            "table": make_dock("Data table", "table", table_box),
            "status": make_dock("Status", "status", status_box, scroll=True),
            "session": make_dock("Session and files", "session", session_box, scroll=True),
            "filter": make_dock("Filter settings", "filter", filter_box, scroll=True),
            "events": make_dock("Event log", "events", self.event_log),
        }
        self.drop_area = PlotDropArea()

    def _build_table_box(self, parent: QWidget) -> QWidget:
        """The IMU table and the joint-angle table as tabs, under their buttons."""
        calibration = self._runner.session.processor.sensor_calibration
        unit = self._options.display.angle_unit
        self.table_model = ImuTableModel(calibration, unit, parent)
        self.table = DataTable(self.table_model)
        table_box, table_layout = _column()
        table_layout.addLayout(self._table_buttons())
        self.joint_model = JointAngleModel(unit, parent)
        self.joint_table = JointTable(self.joint_model)
        self.table_tabs = QTabWidget()
        self.table_tabs.setDocumentMode(True)
        self.table_tabs.addTab(self.table, "IMUs")
        self.table_tabs.addTab(self.joint_table, "Joint angles")
        table_layout.addWidget(self.table_tabs)
        return table_box

    def _table_buttons(self) -> QHBoxLayout:
        self.plot_button = button("Plot selection", None,
                                  "Select cells (Ctrl/Shift+click), then plot them (Ctrl+P); "
                                  "or drag cells onto a plot, or onto empty space")
        self.joints_button = button("Joint angles", None, "Plot the 28 joint angles (Ctrl+J)")
        self._offer_view3d()
        self._offer_browser_view()
        self.unit_combo = QComboBox()
        self.unit_combo.addItems(["deg", "rad"])
        self.unit_combo.setCurrentText(self._options.display.angle_unit)
        self.unit_combo.setToolTip("Unit of angles in the table and new plots (Ctrl+U)")
        guard_wheel(self.unit_combo)
        return row(self.plot_button, self.joints_button, self.view3d_button,
                   self.browser_button, None, QLabel("Angles"), self.unit_combo)

    def _offer_view3d(self) -> None:
        """The 3D View button, disabled (saying why) when bpms.gui.view3d cannot load."""
        self.view3d_button = button("3D View")
        self.view3d_module, why = optional_module("bpms.gui.view3d")
        if self.view3d_module is None or not hasattr(self.view3d_module, "View3DWindow"):
            self.view3d_button.setEnabled(False)
            self.view3d_button.setToolTip(why or "bpms.gui.view3d has no View3DWindow")
        else:
            self.view3d_button.setToolTip("Another 3D view dock (Ctrl+3)")

    def _offer_browser_view(self) -> None:
        """The Browser 3D view button, disabled (saying why) without the vpython extra."""
        self.browser_button = button("Browser 3D view")
        self.vpython_module, why = optional_module("bpms.gui.vpython_views")
        vpython = self.vpython_module
        problem = why or (vpython.vpython_problem()  # type: ignore[union-attr]
                          if hasattr(vpython, "vpython_problem") else None)
        if problem or not hasattr(vpython, "open_browser_view"):
            self.browser_button.setEnabled(False)
            self.browser_button.setToolTip(problem or "no open_browser_view in "
                                                      "bpms.gui.vpython_views")
        else:
            self.browser_button.setToolTip("The stick figure in a web browser (vpython)")

    def _build_status_box(self, simulated: bool) -> QWidget:
        """The health light and the link's numbers over the session status."""
        self.health_panel = HealthPanel(simulated, listening=listening_address(self._runner))
        self.status_panel = StatusPanel()
        self.status_panel.set_sources(self._runner.calibration_source,
                                      self._runner.options_source)
        status_box, status_layout = _column()
        status_layout.addWidget(self.health_panel)
        status_layout.addWidget(self.status_panel)
        status_layout.addStretch(1)
        return status_box

    def _build_session_box(self, window_frames: int) -> QWidget:
        """Playback (file mode), logging, UDP server (suit modes)."""
        runner = self._runner
        self.file_panel = FilePanel(runner)
        self.playback_panel = PlaybackPanel(runner) if runner.replay is not None else None
        if self.playback_panel is not None:  # a paused seek redraws the plots' whole window
            self.playback_panel.window_frames = window_frames
            # the options' source says a filter chosen
            self.playback_panel.filterChosen.connect(
                lambda: self.status_panel.set_sources(runner.calibration_source,
                                                      runner.options_source))
        self.udp_panel = UdpServerPanel(runner) if runner.mode in ("suit", "sim") else None
        session_box, session_layout = _column()
        for panel in (self.playback_panel, self.file_panel, self.udp_panel):
            if panel is not None:
                session_layout.addWidget(panel)
        session_layout.addStretch(1)
        return session_box

    def _build_filter_box(self) -> QWidget:
        # the values in force, the session's processor's (playback: the recording's own);
        # from then on the panel shows what the session's status reports
        self.gains_panel = GainsPanel(self._runner.session.processor.options.filter)
        filter_box = QWidget()
        filter_layout = QVBoxLayout(filter_box)
        filter_layout.addWidget(self.gains_panel)
        filter_layout.addStretch(1)
        return filter_box
