"""The main window: one window whose panels are Qt dock widgets (move, tab, float, close).

Docks: the data table, the status (health light, REC indicator and the link's numbers), the
session and file controls (logging, playback, UDP server), the filter settings, the event log,
and any number of plots and 3D views. Named layouts (:mod:`bpms.gui.layouts`) are saved per
user and the last one is restored at the next launch. The menu bar lists every command with
its shortcut; the toolbar holds Start/Stop, Reset Zero and Record. Everything redraws on
:class:`SessionModel`'s display timer; hidden docks do not repaint.
"""

from __future__ import annotations

import importlib
import time

import numpy as np
from PyQt6 import sip
from PyQt6.QtCore import QByteArray, Qt, QTimer, pyqtSignal
from PyQt6.QtGui import QAction, QKeySequence
from PyQt6.QtWidgets import (
    QComboBox,
    QDockWidget,
    QHBoxLayout,
    QInputDialog,
    QLabel,
    QMainWindow,
    QMessageBox,
    QPushButton,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from bpms.gui.controls import FilePanel, GainsPanel, PlaybackPanel, StatusPanel, UdpServerPanel
from bpms.gui.data_table import DataTable, ImuTableModel, JointAngleModel, JointTable
from bpms.gui.docks import make_dock
from bpms.gui.event_log import EventLog
from bpms.gui.health import HealthPanel, LinkHealth
from bpms.gui.layouts import CALIBRATION, DEFAULT_LAYOUTS, LIVE, PLAYBACK, Layout, LayoutStore
from bpms.gui.model import SessionModel
from bpms.gui.modes import MODE_LABELS, ModeError, SessionRunner
from bpms.gui.plots import (
    PlotDropArea,
    PlotWindow,
    TickBlock,
    cells_plot,
    joint_angle_plot,
    plot_from,
)
from bpms.gui.safety import guard_wheel
from bpms.io.frames import FRAME_PERIOD_S
from bpms.io.options import Options
from bpms.pipeline.session import LiveStatus

#: Status numbers are refreshed this often, s (the link light at every display tick).
TEXT_PERIOD_S = 0.25
#: Reset Zero warns when an IMU turned more than this during the averaging window, deg.
RESET_MOTION_DEG = 5.0

_LEFT = Qt.DockWidgetArea.LeftDockWidgetArea
_RIGHT = Qt.DockWidgetArea.RightDockWidgetArea
_BOTTOM = Qt.DockWidgetArea.BottomDockWidgetArea
_TOP = Qt.DockWidgetArea.TopDockWidgetArea


def optional_module(name: str) -> tuple[object | None, str]:
    """Import ``name`` lazily: (module, "") or (None, why it is unavailable)."""
    try:
        return importlib.import_module(name), ""
    except Exception as exc:
        return None, f"{name} is not available ({type(exc).__name__}: {exc})"


class MainWindow(QMainWindow):
    """One session's window. ``closed`` is emitted (after the session stopped) on close.

    ``layout_store``: where named layouts live (default: the user's config folder);
    ``restore_last``: start with the layout in use when the last main window closed.
    """

    closed = pyqtSignal()

    def __init__(self, runner: SessionRunner, parent: QWidget | None = None, *,
                 layout_store: LayoutStore | None = None, restore_last: bool = True) -> None:
        super().__init__(parent)
        assert runner.session is not None, "runner.prepare() first"
        self.runner = runner
        self.options: Options = runner.options
        self.model = SessionModel(self.options, self)
        self.plot_windows: list[PlotWindow] = []
        self.view3d_windows: list[QWidget] = []
        self.dynamic_docks: list[QDockWidget] = []
        self._dock_serial = 0
        self.tick_times_s: list[float] = []  # GUI time per display tick (bench/gui.py)
        self.simulated = runner.mode == "sim"
        title = f"BPMS Suite — {MODE_LABELS[runner.mode]}"
        self.setWindowTitle(("SIMULATED — " + title) if self.simulated else title)
        self.setDockNestingEnabled(True)
        self.setDockOptions(QMainWindow.DockOption.AllowTabbedDocks
                            | QMainWindow.DockOption.AllowNestedDocks
                            | QMainWindow.DockOption.AnimatedDocks)
        calibration = runner.session.processor.sensor_calibration
        self.health = LinkHealth()
        self._recent_R: list[np.ndarray] = []  # filter DCMs of the last Reset Zero window
        self._last_recording = None
        self._counters: dict[str, int] = {}
        self._texts_at = -1e9
        self._last_state = ""
        self._source_warning = ""
        self._reinit_count = 0
        self._disturbed: tuple[int, int] | None = None  # IMUs (mag, acc) disturbed now

        # -- the table dock ----------------------------------------------------------------
        self.table_model = ImuTableModel(calibration, self.options.display.angle_unit, self)
        self.table = DataTable(self.table_model)
        table_box = QWidget()
        table_layout = QVBoxLayout(table_box)
        table_layout.setContentsMargins(2, 2, 2, 2)
        top = QHBoxLayout()
        self.plot_button = QPushButton("Plot selection")
        self.plot_button.setToolTip("Select cells (Ctrl/Shift+click), then plot them (Ctrl+P); "
                                    "or drag cells onto a plot, or onto empty space")
        self.plot_button.clicked.connect(self.plot_selection)
        self.joints_button = QPushButton("Joint angles")
        self.joints_button.setToolTip("Plot the 28 joint angles (Ctrl+J)")
        self.joints_button.clicked.connect(self.open_joint_plot)
        self.view3d_button = QPushButton("3D View")
        self.view3d_button.clicked.connect(self.open_3d_view)
        self._view3d, why = optional_module("bpms.gui.view3d")
        if self._view3d is None or not hasattr(self._view3d, "View3DWindow"):
            self.view3d_button.setEnabled(False)
            self.view3d_button.setToolTip(why or "bpms.gui.view3d has no View3DWindow")
        else:
            self.view3d_button.setToolTip("Another 3D view dock (Ctrl+3)")
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
        self.unit_combo.setToolTip("Unit of angles in the table and new plots (Ctrl+U)")
        self.unit_combo.currentTextChanged.connect(self.set_angle_unit)
        guard_wheel(self.unit_combo)
        for widget in (self.plot_button, self.joints_button, self.view3d_button,
                       self.browser_button):
            top.addWidget(widget)
        top.addStretch(1)
        top.addWidget(QLabel("Angles"))
        top.addWidget(self.unit_combo)
        table_layout.addLayout(top)
        self.joint_model = JointAngleModel(self.options.display.angle_unit, self)
        self.joint_table = JointTable(self.joint_model)
        self.table_tabs = QTabWidget()
        self.table_tabs.setDocumentMode(True)
        self.table_tabs.addTab(self.table, "IMUs")
        self.table_tabs.addTab(self.joint_table, "Joint angles")
        table_layout.addWidget(self.table_tabs)

        # -- side panels -------------------------------------------------------------------
        self.health_panel = HealthPanel(self.simulated, listening=self._listening())
        self.status_panel = StatusPanel()
        self.status_panel.set_sources(runner.calibration_source, runner.options_source)
        self.status_panel.dataToggled.connect(self.set_data)
        self.status_panel.resetZeroClicked.connect(self.reset_zero)
        status_box = QWidget()
        status_layout = QVBoxLayout(status_box)
        status_layout.setContentsMargins(2, 2, 2, 2)
        status_layout.addWidget(self.health_panel)
        status_layout.addWidget(self.status_panel)
        status_layout.addStretch(1)
        self.gains_panel = GainsPanel(self.options.filter)
        self.gains_panel.gainsChanged.connect(self._set_gains)
        self.gains_panel.filterChanged.connect(self.select_filter)
        self.file_panel = FilePanel(runner)
        self.file_panel.on_stopped.append(self._logging_stopped)
        self.playback_panel = PlaybackPanel(runner) if runner.replay is not None else None
        self.udp_panel = UdpServerPanel(runner) if runner.mode in ("suit", "sim") else None
        session_box = QWidget()
        session_layout = QVBoxLayout(session_box)
        session_layout.setContentsMargins(2, 2, 2, 2)
        for panel in (self.playback_panel, self.file_panel, self.udp_panel):
            if panel is not None:
                session_layout.addWidget(panel)
        session_layout.addStretch(1)
        filter_box = QWidget()
        filter_layout = QVBoxLayout(filter_box)
        filter_layout.addWidget(self.gains_panel)
        filter_layout.addStretch(1)
        self.event_log = EventLog()

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
        self.layout_store = layout_store if layout_store is not None else LayoutStore()
        self.current_layout = ""
        self._menus()
        self.resize(1500, 860)
        self.apply_default_layout(LIVE if runner.replay is None else PLAYBACK)
        if restore_last and self.layout_store.last is not None:
            self.restore_layout(self.layout_store.last)
        if self.layout_store.problem:
            self.event_log.add(self.layout_store.problem, "warning")
        for problem in getattr(runner, "problems", []):
            self.event_log.add(f"file warning: {problem}", "warning")

        self.model.samplesArrived.connect(self._on_samples)
        self.model.statusChanged.connect(self._on_status)
        self.model.attach(runner.session)
        self.event_log.add(f"session opened: {MODE_LABELS[runner.mode]}"
                           + (" (SIMULATED data)" if self.simulated else ""))

    def _listening(self) -> str | None:
        """The UDP client's listening address (host:port), else None."""
        source = self.runner.session.source if self.runner.session is not None else None
        udp = getattr(source, "udp", None)
        return str(udp.listening) if udp is not None and hasattr(udp, "listening") else None

    # -- menus and toolbar ---------------------------------------------------------------
    def _action(self, text: str, slot, keys: str | None = None, tip: str = "") -> QAction:
        action = QAction(text, self)
        if keys:
            action.setShortcut(QKeySequence(keys))
            action.setShortcutContext(Qt.ShortcutContext.WindowShortcut)
        if tip:
            action.setToolTip(tip)
            action.setStatusTip(tip)
        action.triggered.connect(lambda *_: slot())
        self.addAction(action)
        return action

    def _menus(self) -> None:
        a = self._action
        self.actions_by_name: dict[str, QAction] = {
            "data": a("Start/Stop Data", lambda: self.set_data(not self.runner.data_on),
                      "Ctrl+Space", "Start or stop the stream (play/pause a recording)"),
            "reset_zero": a("Reset Zero", self.reset_zero, "Ctrl+R",
                            "Stand in the calibration pose, then press"),
            "record": a("Start/Stop Logging", self.file_panel.toggle_logging, "Ctrl+L",
                        "Record raw and/or filtered files (Session dock)"),
            "plot": a("Plot selection", self.plot_selection, "Ctrl+P",
                      "A new plot of the selected table cells"),
            "joints": a("Joint angles plot", self.open_joint_plot, "Ctrl+J"),
            "view3d": a("New 3D view", self.open_3d_view, "Ctrl+3"),
            "browser": a("Browser 3D view", self.open_browser_view),
            "unit": a("Angles deg/rad", self._toggle_unit, "Ctrl+U"),
            "step_back": a("Previous frame", lambda: self.step_frames(-1), "Ctrl+Left",
                           "Playback, paused: one frame back"),
            "step_fwd": a("Next frame", lambda: self.step_frames(1), "Ctrl+Right",
                          "Playback, paused: one frame forward"),
            "step_back10": a("Back 1 s", lambda: self.step_frames(-50), "Ctrl+Shift+Left"),
            "step_fwd10": a("Forward 1 s", lambda: self.step_frames(50), "Ctrl+Shift+Right"),
            "save_layout": a("Save layout as…", self.save_layout_dialog, "Ctrl+Shift+S"),
            "quit": a("Close window", self.close, "Ctrl+Q"),
            "sensor_angles": a("Sensor angles (uncorrected)", self._sensor_angles_toggled,
                               tip="Table and plots show the sensor angles, without Reset "
                                   "Zero (off: the segment angles after Reset Zero)"),
            "corrected": a("Reset Zero correction of the output angles",
                           self._corrected_toggled, "V",
                           "The angles shown, recorded and streamed: segment angles after "
                           "Reset Zero (on) or the sensor angles (off); v in the table"),
            "drift": a("Drift check…", self.open_drift_check,
                       tip="Each segment's attitude change between the calibration pauses at "
                           "the start and the end of the recording (playback)"),
            "lsl": a("Stream to LSL", self._lsl_toggled,
                     tip="Stream the session as Lab Streaming Layer outlets (docs/lsl.md)"),
        }
        acts = self.actions_by_name
        acts["sensor_angles"].setCheckable(True)
        acts["corrected"].setCheckable(True)
        processor = getattr(self.runner.session, "processor", None)
        acts["corrected"].setChecked(bool(getattr(processor, "corrected_output", True)))
        # the original's v key, in the table (the 3D view keeps its own v: figure alignment)
        self.removeAction(acts["corrected"])
        acts["corrected"].setShortcutContext(Qt.ShortcutContext.WidgetWithChildrenShortcut)
        self.table_tabs.addAction(acts["corrected"])
        acts["lsl"].setCheckable(True)
        acts["lsl"].setChecked(self.runner.lsl_on)
        self.actions_by_name["view3d"].setEnabled(self.view3d_button.isEnabled())
        self.actions_by_name["browser"].setEnabled(self.browser_button.isEnabled())
        acts = self.actions_by_name
        bar = self.menuBar()
        menu = bar.addMenu("&File")
        for key in ("record", "quit"):
            menu.addAction(acts[key])
        menu = bar.addMenu("&Data")
        for key in ("data", "reset_zero", "corrected", "lsl"):
            menu.addAction(acts[key])
        if self.runner.replay is not None:
            menu.addSeparator()
            for key in ("step_back", "step_fwd", "step_back10", "step_fwd10"):
                menu.addAction(acts[key])
            menu.addSeparator()
            menu.addAction(acts["drift"])
        menu = bar.addMenu("&View")
        for key in ("plot", "joints", "view3d", "browser", "unit", "sensor_angles"):
            menu.addAction(acts[key])
        menu.addSeparator()
        for dock in self.docks.values():
            menu.addAction(dock.toggleViewAction())
        self.layouts_menu = bar.addMenu("&Layouts")
        self.layouts_menu.aboutToShow.connect(self._fill_layouts_menu)
        self._fill_layouts_menu()
        help_menu = bar.addMenu("&Help")
        help_menu.addAction(a("Keys and mouse…", self.show_keys, "F1"))

        toolbar = self.addToolBar("Session")
        toolbar.setObjectName("toolbar")
        self.toolbar = toolbar
        self.start_action = toolbar.addAction("▶ Start", lambda: self.set_data(True))
        self.start_action.setToolTip("Start Data (Ctrl+Space)")
        self.stop_action = toolbar.addAction("■ Stop", lambda: self.set_data(False))
        self.stop_action.setToolTip("Stop Data (Ctrl+Space)")
        toolbar.addAction(acts["reset_zero"])
        self.record_action = toolbar.addAction("● Record", self.file_panel.toggle_logging)
        self.record_action.setToolTip("Start/Stop Logging (Ctrl+L)")
        toolbar.addAction(acts["lsl"])
        toolbar.addSeparator()
        self.drop_area.setMinimumWidth(300)
        toolbar.addWidget(self.drop_area)
        self._update_toolbar()

    def _fill_layouts_menu(self) -> None:
        menu = self.layouts_menu
        menu.clear()
        for name in DEFAULT_LAYOUTS:
            if name not in self.layout_store.names():
                menu.addAction(name.capitalize(), lambda n=name: self.apply_default_layout(n))
        saved = self.layout_store.names()
        if saved:
            menu.addSeparator()
            for name in saved:
                menu.addAction(name, lambda n=name: self.load_layout(n))
        menu.addSeparator()
        menu.addAction(self.actions_by_name["save_layout"])

    def _update_toolbar(self) -> None:
        on = self.runner.data_on
        self.start_action.setEnabled(not on)
        self.stop_action.setEnabled(on)
        self.actions_by_name["reset_zero"].setEnabled(on)
        self.record_action.setText("■ Stop recording" if self.file_panel.logging
                                   else "● Record")

    def show_keys(self) -> None:
        text = "\n".join(f"{act.shortcut().toString():<18} {act.text()}"
                         for act in self.actions_by_name.values() if not act.shortcut().isEmpty())
        text += ("\n\n3D view (click it first): arrows pan, c centre on the body, v cycle "
                 "front/side/top, p toggle perspective, = / - zoom, 0 reset, x/y/z look along "
                 "an axis, d IMU axes, t joint trail\nPlots: drag table cells onto a plot (or "
                 "onto empty space for a new one); click a legend name to hide/show; "
                 "double-click resets the view; Space pauses")
        box = QMessageBox(QMessageBox.Icon.Information, "Keys and mouse", text, parent=self)
        box.open()

    # -- docks -----------------------------------------------------------------------------
    def _next_name(self, kind: str) -> str:
        self._dock_serial += 1
        return f"{kind}-{self._dock_serial}"

    def add_plot_dock(self, plot: PlotWindow, name: str | None = None,
                      area: Qt.DockWidgetArea = _BOTTOM) -> QDockWidget:
        """Show ``plot`` in a new dock (closing the dock deletes the plot)."""
        dock = make_dock(plot.windowTitle(), name or self._next_name("plot"), plot,
                         dynamic=True)
        plot.setMinimumSize(200, 150)
        plot.cellsDropped.connect(self._cells_dropped)
        plot.jointsDropped.connect(self._joints_dropped)
        self.addDockWidget(area, dock)
        self.plot_windows.append(plot)
        self.dynamic_docks.append(dock)
        plot.redraw()
        return dock

    def add_view3d_dock(self, name: str | None = None,
                        area: Qt.DockWidgetArea = _RIGHT) -> QDockWidget | None:
        if self._view3d is None or not self.view3d_button.isEnabled():
            return None
        view = self._view3d.View3DWindow(self.model)  # type: ignore[attr-defined]
        view.resetZeroRequested.connect(self.reset_zero)
        dock = make_dock("3D view", name or self._next_name("view3d"), view, dynamic=True)
        self.addDockWidget(area, dock)
        self.view3d_windows.append(view)
        self.dynamic_docks.append(dock)
        return dock

    def _forget(self, window: QWidget) -> None:
        if window in self.plot_windows:
            self.plot_windows.remove(window)
        if window in self.view3d_windows:
            self.view3d_windows.remove(window)

    def _prune(self) -> None:
        """Forget plots and 3D views whose dock the user closed (deleted by Qt). No
        ``destroyed`` slots: they would run while this window itself is torn down."""
        self.dynamic_docks = [d for d in self.dynamic_docks if not sip.isdeleted(d)]
        self.plot_windows = [w for w in self.plot_windows
                             if not sip.isdeleted(w) and not w.closed]
        self.view3d_windows = [w for w in self.view3d_windows if not sip.isdeleted(w)]

    def clear_dynamic_docks(self) -> None:
        """Remove every plot and 3D view dock."""
        self._prune()
        for dock in list(self.dynamic_docks):
            widget = dock.widget()
            self._forget(widget)
            self.removeDockWidget(dock)
            # Out of the window at once: restoreState() looks docks up by object name among
            # the window's children, and must never find one that is about to be deleted.
            dock.setObjectName("")
            dock.setParent(None)
            if widget is not None:
                widget.close()
            dock.deleteLater()
        self.dynamic_docks.clear()

    def dock_of(self, widget: QWidget) -> QDockWidget | None:
        for dock in self.dynamic_docks:
            if dock.widget() is widget:
                return dock
        return None

    # -- layouts -----------------------------------------------------------------------------
    def current_layout_state(self) -> Layout:
        """The window's layout now (fixed docks, dynamic docks with their contents)."""
        self._prune()
        docks = []
        for dock in self.dynamic_docks:
            widget = dock.widget()
            if isinstance(widget, PlotWindow):
                docks.append({"kind": "plot", "name": dock.objectName(),
                              "plot": widget.description()})
            else:
                docks.append({"kind": "view3d", "name": dock.objectName()})
        return Layout(bytes(self.saveState().data()), docks)

    def restore_layout(self, layout: Layout) -> bool:
        """Re-create the layout's plots and 3D views, then restore the dock state."""
        self.clear_dynamic_docks()
        for spec in layout.docks:
            name = str(spec.get("name", ""))
            if spec.get("kind") == "plot":
                plot = plot_from(spec.get("plot", {}), self.table_model.angle_unit,
                                 self.options.display.plot_history_s)
                if plot is not None:
                    self.add_plot_dock(plot, name)
            elif spec.get("kind") == "view3d":
                self.add_view3d_dock(name)
            serial = name.rpartition("-")[2]
            if serial.isdigit():
                self._dock_serial = max(self._dock_serial, int(serial))
        ok = self.restoreState(QByteArray(layout.state))
        if not ok:
            self.event_log.add("a saved layout could not be restored (made by another "
                               "version?)", "warning")
        return ok

    def save_layout(self, name: str) -> Layout:
        """Save the current layout under ``name`` (per user)."""
        layout = self.current_layout_state()
        self.layout_store.put(name, layout)
        self.current_layout = name
        self.event_log.add(f"layout saved: {name}")
        return layout

    def load_layout(self, name: str) -> bool:
        layout = self.layout_store.get(name)
        if layout is None:
            if name in DEFAULT_LAYOUTS:
                self.apply_default_layout(name)
                return True
            return False
        self.current_layout = name
        return self.restore_layout(layout)

    def save_layout_dialog(self) -> None:
        dialog = QInputDialog(self)
        dialog.setWindowTitle("Save layout")
        dialog.setLabelText("Layout name (an existing name is replaced)")
        dialog.setTextValue(self.current_layout or "my layout")
        dialog.textValueSelected.connect(lambda text: text.strip()
                                         and self.save_layout(text.strip()))
        dialog.open()

    def apply_default_layout(self, name: str, views3d: int | None = None) -> None:
        """One of :data:`DEFAULT_LAYOUTS`, built here (the user's saved version of the same
        name wins in :meth:`load_layout`). ``views3d`` overrides the number of 3D views.

        - live monitoring: table over the event log on the left, the 3D view beside the
          table, status / session / filter tabs on the right;
        - playback analysis: the same top row (session tab first, with the playback slider),
          the joint angles and new plots across the bottom, the event log tabbed with them;
        - calibration check: the table (raw and calibrated columns) large, filter settings and
          status on the right, a 3D view under them, the event log under the table.
        """
        self.clear_dynamic_docks()
        d = self.docks
        for dock in d.values():
            dock.setFloating(False)
            self.removeDockWidget(dock)
        want3d = 1 if views3d is None else views3d
        self.addDockWidget(_LEFT, d["table"])
        self.addDockWidget(_RIGHT, d["status"])
        if name == CALIBRATION:
            self.tabifyDockWidget(d["status"], d["filter"])
            self.tabifyDockWidget(d["status"], d["session"])
            d["filter"].raise_()
            self.splitDockWidget(d["table"], d["events"], Qt.Orientation.Vertical)
            for _ in range(want3d):
                dock = self.add_view3d_dock(area=_RIGHT)
                if dock is not None:
                    self.splitDockWidget(d["status"], dock, Qt.Orientation.Vertical)
            heights = [(d["events"], 160)]
        else:
            self.tabifyDockWidget(d["status"], d["session"])
            self.tabifyDockWidget(d["status"], d["filter"])
            d["status"].raise_()
            if name == PLAYBACK:
                d["session"].raise_()  # the playback slider first
                joints = joint_angle_plot(self.table_model.angle_unit,
                                          self.options.display.plot_history_s)
                self.add_plot_dock(joints, area=_BOTTOM)
                self.addDockWidget(_BOTTOM, d["events"])
                self.tabifyDockWidget(self.dock_of(joints), d["events"])
                self.dock_of(joints).raise_()
                heights = [(self.dock_of(joints), 420)]
            else:
                self.splitDockWidget(d["table"], d["events"], Qt.Orientation.Vertical)
                heights = [(d["events"], 160)]
            for _ in range(want3d):
                dock = self.add_view3d_dock(area=_RIGHT)
                if dock is not None:
                    self.splitDockWidget(d["table"], dock, Qt.Orientation.Horizontal)
        for dock in d.values():
            dock.show()
        widths = [(d["table"], 760), (d["status"], 360)]
        views = [dk for dk in self.dynamic_docks if not isinstance(dk.widget(), PlotWindow)]
        if views and name != CALIBRATION:
            widths.append((views[0], 380))

        def sizes() -> None:
            if sip.isdeleted(self):
                return
            for pairs, orientation in ((widths, Qt.Orientation.Horizontal),
                                       (heights, Qt.Orientation.Vertical)):
                alive = [(dk, n) for dk, n in pairs if not sip.isdeleted(dk)
                         and dk.parent() is self]
                self.resizeDocks([dk for dk, _ in alive], [n for _, n in alive], orientation)

        sizes()
        QTimer.singleShot(0, sizes)  # again once the window is laid out
        self.current_layout = name

    # -- commands ------------------------------------------------------------------------
    def set_data(self, on: bool) -> None:
        """Start Data / Stop Data."""
        if on == self.runner.data_on:
            return
        if on:
            try:
                session = self.runner.start_data()
            except ModeError as exc:
                self.statusBar().showMessage(str(exc), 10000)
                self.event_log.add(f"cannot start data: {exc}", "warning")
                return
            if session is not self.model.session:
                self.model.attach(session)
                self.health_panel.set_listening(self._listening())
            self.health.start()
            self.event_log.add("data started")
        else:
            self.runner.stop_data()
            self.health.stop()
            self.event_log.add("data stopped")
        self.status_panel.set_streaming(self.runner.data_on)
        self._update_toolbar()

    def reset_zero(self) -> None:
        """Reset Zero at the next frame (stand in the calibration pose); warns when an IMU
        turned during the averaging window that ends there."""
        if self.runner.session is None or not self.runner.data_on:
            return
        self.runner.session.reset_zero()
        self.statusBar().showMessage("Reset Zero requested", 3000)
        self.event_log.add("Reset Zero")
        moved = self._motion_in_window_deg()
        if moved is not None and moved[0] > RESET_MOTION_DEG:
            self.event_log.add(f"Reset Zero: the subject moved during its window "
                               f"({moved[0]:.0f}° on IMU {moved[1]}); stand still in the "
                               "calibration pose and press again", "warning")

    def _motion_in_window_deg(self) -> tuple[float, int] | None:
        """Largest rotation of one IMU's filter DCM over the last Reset Zero window, deg."""
        if len(self._recent_R) < 2:
            return None
        R = np.asarray(self._recent_R)  # [n, 18, 3, 3]
        rel = np.einsum("ikj,nikl->nijl", R[0], R)  # R0^T R_n
        trace = np.clip((np.trace(rel, axis1=2, axis2=3) - 1.0) / 2.0, -1.0, 1.0)
        angles = np.degrees(np.arccos(trace))
        angles = np.where(np.isfinite(angles), angles, 0.0).max(axis=0)
        k = int(np.argmax(angles))
        return float(angles[k]), k

    def _sensor_angles_toggled(self) -> None:
        """View ▸ Sensor angles (uncorrected): the table and the angle plots show ``euler``
        (checked) or the output angles ``euler_output`` (unchecked, the default)."""
        sensor = self.actions_by_name["sensor_angles"].isChecked()
        self.table_model.set_show_output(not sensor)
        self.statusBar().showMessage("angles shown: " + ("sensor angles (uncorrected)" if sensor
                                     else "output angles (after Reset Zero)"), 3000)

    def _corrected_toggled(self) -> None:
        """The original's v key: the session's output angles corrected by Reset Zero or not
        (what is shown, recorded and streamed), from the next frame."""
        on = self.actions_by_name["corrected"].isChecked()
        if self.runner.session is not None:
            self.runner.session.set_corrected_output(on)
        self.options.pose.corrected_output = on  # a new session (UDP restart) follows
        self.event_log.add("Reset Zero correction of the output angles "
                           + ("on (segment angles)" if on else "off (sensor angles)"))

    def _lsl_toggled(self) -> None:
        """Stream to LSL on/off (SessionRunner.set_lsl); the reason when it cannot start."""
        action = self.actions_by_name["lsl"]
        on = action.isChecked()
        why = self.runner.set_lsl(on)
        if why:
            action.setChecked(False)
            self.statusBar().showMessage(f"LSL: {why}", 10000)
            self.event_log.add(f"LSL streaming not started: {why}", "warning")
            return
        action.setChecked(self.runner.lsl_on)
        self.event_log.add("LSL streaming " + ("on" if self.runner.lsl_on else "off"))

    def _set_gains(self, gains: dict) -> None:
        if self.runner.session is not None:
            try:
                self.runner.session.set_gains(**gains)
            except ValueError as exc:  # outside the valid range: refused, said why
                self.statusBar().showMessage(str(exc), 8000)
                return
            for name, value in gains.items():
                setattr(self.options.filter, name, value)

    def select_filter(self, algorithm: str) -> None:
        """Switch the attitude filter of all 18 IMUs (Reset Zero is kept)."""
        if self.runner.session is not None:
            self.runner.session.select_filter(algorithm)
        self.options.filter.algorithm = algorithm
        self.statusBar().showMessage(f"filter: {algorithm}", 3000)
        self.event_log.add(f"filter re-initialised: {algorithm} on all 18 IMUs")

    def set_angle_unit(self, unit: str) -> None:
        self.table_model.set_angle_unit(unit)
        self.joint_model.set_angle_unit(unit)
        self.options.display.angle_unit = unit

    def _toggle_unit(self) -> None:
        self.unit_combo.setCurrentText("rad" if self.unit_combo.currentText() == "deg" else "deg")

    def step_frames(self, n: int) -> None:
        """Playback, paused: move ``n`` frames (the frame is shown in every view)."""
        if self.playback_panel is not None and not self.runner.replay.playing:
            self.playback_panel.step(n)

    def plot_selection(self) -> PlotWindow | None:
        """A new plot dock of the selected cells (one curve each), or of the selected joint
        angles when their tab is in front."""
        if self.table_tabs.currentWidget() is self.joint_table:
            joints = self.joint_table.selected_joints()
            if joints:
                return self._joints_dropped(joints, None)
        cells = self.table.selected_cells()
        if not cells:
            self.statusBar().showMessage("Select one or more numeric cells first "
                                         "(Ctrl/Shift+click)", 5000)
            return None
        return self._new_cells_plot(cells)

    def _new_cells_plot(self, cells: list[tuple[int, int]]) -> PlotWindow:
        number = 1 + sum(isinstance(d.widget(), PlotWindow) for d in self.dynamic_docks)
        window = cells_plot(cells, self.table_model.angle_unit,
                            self.options.display.plot_history_s, number)
        self._show_plot(window)
        return window

    def _cells_dropped(self, cells: list, plot: object) -> None:
        """Cells dragged from the table: onto a plot (added there) or elsewhere (new plot)."""
        if isinstance(plot, PlotWindow):
            plot.add_cells(cells)
        elif cells:
            self._new_cells_plot(cells)

    def _joints_dropped(self, joints: list, plot: object) -> PlotWindow | None:
        """Joint angles dragged from their list: onto a plot or elsewhere (new plot)."""
        if isinstance(plot, PlotWindow):
            plot.add_joints(joints, self.table_model.angle_unit)
            return plot
        if not joints:
            return None
        number = 1 + sum(isinstance(d.widget(), PlotWindow) for d in self.dynamic_docks)
        window = plot_from({"kind": "cells", "title": f"Plot {number}", "joints": joints},
                           self.table_model.angle_unit, self.options.display.plot_history_s)
        if window is not None:
            self._show_plot(window)
        return window

    def open_joint_plot(self) -> PlotWindow:
        window = joint_angle_plot(self.table_model.angle_unit,
                                  self.options.display.plot_history_s)
        return self._show_plot(window)

    def _show_plot(self, window: PlotWindow) -> PlotWindow:
        self.add_plot_dock(window)
        block = self._history_block()
        if block is not None:
            window.append(block)
        return window

    def _history_block(self) -> TickBlock | None:
        latest = self.model.latest
        if latest is None:
            return None
        return TickBlock.from_samples([latest], self.table_model.calibration,
                                      self.table_model.show_output)

    def open_3d_view(self) -> QWidget | None:
        """A new 3D view dock (when bpms.gui.view3d is available)."""
        dock = self.add_view3d_dock()
        return None if dock is None else dock.widget()

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
        self._prune()
        self.health.frames_arrived()
        last = samples[-1]
        self.table_model.update(last, np.any([s.errors for s in samples], axis=0))
        if last.mag_disturbed is not None and last.acc_disturbed is not None:
            self._disturbed = (int(np.count_nonzero(last.mag_disturbed)),
                               int(np.count_nonzero(last.acc_disturbed)))
        if self.joint_table.isVisible():
            self.joint_model.update(samples[-1])
        window = max(2, round(self.options.pose.reset_window_s / FRAME_PERIOD_S))
        self._recent_R.extend(s.R for s in samples[-window:])
        del self._recent_R[:-window]
        if self.plot_windows:
            block = TickBlock.from_samples(samples, self.table_model.calibration,
                                           self.table_model.show_output)
            for plot in self.plot_windows:
                plot.append(block)
        self.tick_times_s.append(time.perf_counter() - start)
        del self.tick_times_s[:-20000]

    def _nominal_hz(self) -> float | None:
        replay = self.runner.replay
        if replay is None:
            return 50.0
        return None if replay.speed is None else 50.0 * replay.speed

    def _on_status(self, st: LiveStatus) -> None:
        now = time.monotonic()
        if self.runner.replay is not None and self.runner.data_on \
                and not self.runner.replay.playing:
            # paused from elsewhere (end of file): the light goes grey, not red
            self.health.stop()
        health = self.health.evaluate(now, st.rate_hz, st.error_bits, st.source.state,
                                      self._nominal_hz())
        if health.transition == "lost":
            self.event_log.add(f"link lost: no frame for {self.health.silent_s:g} s "
                               f"({st.source.description})", "warning")
        elif health.transition == "recovered":
            self.event_log.add("link recovered")
        self.health_panel.set_colour(health.colour)
        # Text changes re-lay out their panels: the numbers are refreshed 4 times a second,
        # the light at every tick (and at once when the state changes).
        if now - self._texts_at >= TEXT_PERIOD_S or health.state != self._last_state:
            self._texts_at, self._last_state = now, health.state
            self.health_panel.show_health(health, st, now)
            self.health_panel.show_disturbance(*(self._disturbed or (None, None)))
            self.status_panel.show_status(st, health.state if self.runner.data_on else None)
            self.file_panel.show_status(st)
        self.event_log.merge_session_events(st.events)
        self._watch_counters(st)
        self._watch_recording(st)
        if self.playback_panel is not None:
            self.playback_panel.show_status(st)
            if self.runner.replay is not None and self.runner.replay.ended \
                    and self.runner.data_on:
                self.set_data(False)
                self.statusBar().showMessage("end of the recording", 5000)
                self.event_log.add("end of the recording")
        if self.udp_panel is not None:
            self.udp_panel.show_status(st)
        self._update_toolbar()

    def _watch_counters(self, st: LiveStatus) -> None:
        """What deserves an event when it appears or grows: another UDP sender (the source's
        warning, or its ``foreign`` counter growing while no warning is shown), each filter
        re-initialisation by the state guard (``reinit_count``)."""
        warning = st.source.warning
        foreign = st.source.counters.get("foreign", 0)
        grew = foreign > self._counters.get("foreign", 0)
        self._counters["foreign"] = foreign
        if warning and warning != self._source_warning:
            self.event_log.add(f"UDP: {warning}" if "sender" in warning else warning,
                               "warning")
        elif grew and not warning:
            self.event_log.add(f"UDP: another sender on this port ({foreign} datagrams "
                               "ignored)", "warning")
        self._source_warning = warning
        if st.reinit_count < self._reinit_count:  # a new session (UDP client restarted)
            self._reinit_count = 0
        # the session's own line for this count (rate-limited) says it already
        said = any(e.endswith(f"; {st.reinit_count} so far") and "re-initialised" in e
                   for e in st.events[-5:])
        if st.reinit_count > self._reinit_count and not said:
            new = st.reinit_count - self._reinit_count
            self.event_log.add(f"filter re-initialised by the state guard ({new} "
                               f"re-initialisation{'s' if new > 1 else ''}, "
                               f"{st.reinit_count} so far)", "warning")
        self._reinit_count = st.reinit_count

    def _watch_recording(self, st: LiveStatus) -> None:
        rec = st.recording
        if rec is not None and rec is not self._last_recording:
            names = ", ".join(str(p) for p in (rec.raw_path, rec.filtered_path) if p)
            self.event_log.add(f"logging started: {names}")
        if rec is not None and rec.error and not getattr(rec, "_logged_error", False):
            self.event_log.add(f"file warning: {rec.error}", "warning")
            rec._logged_error = True  # type: ignore[attr-defined]
        self._last_recording = rec

    def _logging_stopped(self, rec) -> None:
        if rec is None:
            return
        parts = []
        if rec.raw_path is not None:
            parts.append(f"{rec.raw_path.name} ({rec.raw_records} frames)")
        if rec.filtered_path is not None:
            parts.append(rec.filtered_path.name)
        self.event_log.add("logging stopped: " + ", ".join(parts))
        self._update_toolbar()

    def open_drift_check(self):
        """A dock with the drift check of the recording being played (computed in the
        background with the playback's calibration, options and filter); None when no
        recording is played."""
        from bpms.gui.drift_panel import drift_dock

        if self.runner.replay is None or not self.runner.config.path:
            return None
        dock, panel = drift_dock(self)
        self.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, dock)
        runner = self.runner
        panel.start(runner.config.path, runner.playback_calibration, runner.playback_options,
                    runner.options.filter.algorithm)
        return panel

    # -- closing ---------------------------------------------------------------------------
    def shutdown(self) -> None:
        """Close plots and 3D views, stop the session (files closed), free the source."""
        if self.file_panel.stopping is not None:
            self.file_panel.stopping.wait(15.0)
        for view in self.browser_views:
            self.model.samplesArrived.disconnect(view.feed)
            view.close()
        self.browser_views.clear()
        self._prune()
        for view in list(self.view3d_windows):
            if not sip.isdeleted(view):
                view.close()
        self.model.attach(None)
        self.runner.close()

    def closeEvent(self, event) -> None:
        if self.file_panel.logging:
            answer = QMessageBox.question(self, "BPMS Suite",
                                          "Logging is on. Stop logging and close?")
            if answer != QMessageBox.StandardButton.Yes:
                event.ignore()
                return
        self.layout_store.remember(self.current_layout_state())
        self.shutdown()
        self.closed.emit()
        super().closeEvent(event)
