"""The main window: one window whose panels are Qt dock widgets (move, tab, float, close).

Docks: the data table, the status (health light, REC indicator and the link's numbers), the
session and file controls (logging, playback, UDP server), the filter settings, the event log,
and any number of plots and 3D views. Named layouts (:mod:`bpms.gui.layouts`) are saved per
user and the last one is restored at the next launch. The menu bar lists every command with
its shortcut; the toolbar holds Start/Stop, Reset Zero and Record. Everything redraws on
:class:`SessionModel`'s display timer; hidden docks do not repaint.

The window is built from parts, each with one job and its own state, given what it uses in
its constructor (:mod:`bpms.gui.window`, docs/main-window.md):

- ``panels`` (:class:`WindowPanels`): the fixed panels' widgets and their docks;
- ``commands`` (:class:`SessionCommands`): what the menus and panels ask of the session;
- ``views`` (:class:`ViewDocks`): plots and 3D views, and where a new plot goes;
- ``layouts`` (:class:`DockLayouts`): built-in and named layouts;
- ``mode`` (:class:`ModeControls`): what depends on the mode (playback, UDP server);
- ``menus`` (:class:`WindowMenus`): the actions, menu bar and toolbar;
- ``display`` (:class:`StatusDisplay`): the display tick and the status.

This module makes them, wires their signals in one place (:meth:`MainWindow._wire`) and
closes the window. It holds the session's runner, options and model, which the parts share.
"""

from __future__ import annotations

from PyQt6.QtCore import QByteArray, QRect, QTimer, pyqtSignal
from PyQt6.QtWidgets import QMainWindow, QMessageBox, QWidget

from bpms.gui.angle_readout import ContinuousAngles
from bpms.gui.layouts import LayoutStore
from bpms.gui.model import SessionModel
from bpms.gui.modes import MODE_LABELS, SessionRunner
from bpms.gui.plot_data import BlockHistory
from bpms.gui.screen_fit import place_window
from bpms.gui.window.actions import WindowMenus
from bpms.gui.window.commands import SessionCommands
from bpms.gui.window.dock_layout import DockLayouts
from bpms.gui.window.dynamic_docks import ViewDocks
from bpms.gui.window.mode_wiring import ModeControls, nominal_hz
from bpms.gui.window.panels import WindowPanels
from bpms.gui.window.status import StatusDisplay
from bpms.io.frames import FRAME_RATE_HZ
from bpms.io.options import Options


class MainWindow(QMainWindow):
    """One session's window. ``closed`` is emitted (after the session stopped) on close.

    ``layout_store``: where named layouts live (default: the user's config folder);
    ``restore_last``: start with the layout in use when the last main window closed;
    ``saved_geometry``: the bytes of a ``saveGeometry()``, used only when they fit the
    screen; ``available``: the screen's available geometry (default: the screen's own; the
    window fits it, :mod:`bpms.gui.screen_fit`).
    """

    closed = pyqtSignal()

    def __init__(self, runner: SessionRunner, parent: QWidget | None = None, *,
                 layout_store: LayoutStore | None = None, restore_last: bool = True,
                 saved_geometry: QByteArray | None = None,
                 available: QRect | None = None) -> None:
        super().__init__(parent)
        assert runner.session is not None, "runner.prepare() first"
        self.runner = runner
        self.options: Options = runner.options
        self.model = SessionModel(self.options, self)
        simulated = runner.mode == "sim"
        self._set_up_frame(simulated)
        history = BlockHistory(max(1, round(self.options.display.plot_history_s
                                            * FRAME_RATE_HZ)))
        readout = ContinuousAngles()  # the angles shown, continuous (docs/main-window.md)
        self.panels = WindowPanels(runner, self.options, self, simulated=simulated,
                                   window_frames=history.buffer.capacity)
        self.commands = SessionCommands(self, runner, self.model, self.options, self.panels,
                                        readout)
        self.views = ViewDocks(self, self.model, self.options, self.panels, history,
                               self.commands.reset_zero)
        self.layouts = DockLayouts(self, self.panels, self.views,
                                   layout_store if layout_store is not None
                                   else LayoutStore())
        self.mode = ModeControls(self, runner, self.panels, self.commands)
        self.menus = WindowMenus(self, runner, self.panels, self.commands, self.views,
                                 self.layouts, self.mode)
        self.display = StatusDisplay(self.model, runner, self.panels, self.views, self.mode,
                                     history, readout, self.menus.update_toolbar)
        self._wire()
        # REC and the link light in the status bar: in view whatever the docks (closed,
        # tabbed, scrolled)
        self.statusBar().addPermanentWidget(self.panels.health_panel.rec_badge)
        self.statusBar().addPermanentWidget(self.panels.health_panel.link_badge)
        # the size of the screen before the layout is built (the docks are sized to it)
        self.placement = place_window(self, saved_geometry, available)
        self.layouts.first_layout(runner.replay is not None, restore_last)
        self._open_session()

    def _set_up_frame(self, simulated: bool) -> None:
        title = f"BPMS Suite — {MODE_LABELS[self.runner.mode]}"
        self.setWindowTitle(("SIMULATED — " + title) if simulated else title)
        self.setDockNestingEnabled(True)
        self.setDockOptions(QMainWindow.DockOption.AllowTabbedDocks
                            | QMainWindow.DockOption.AllowNestedDocks
                            | QMainWindow.DockOption.AnimatedDocks)

    def _wire(self) -> None:
        """What the panels' buttons and signals do: the one place the parts are connected."""
        panels, commands, views = self.panels, self.commands, self.views
        panels.plot_button.clicked.connect(views.plot_selection)
        panels.joints_button.clicked.connect(views.open_joint_plot)
        panels.view3d_button.clicked.connect(views.open_3d_view)
        panels.browser_button.clicked.connect(views.open_browser_view)
        panels.unit_combo.currentTextChanged.connect(commands.set_angle_unit)
        panels.status_panel.dataToggled.connect(commands.set_data)
        panels.status_panel.resetZeroClicked.connect(commands.reset_zero)
        panels.file_panel.on_stopped.append(self.display.logging_stopped)
        panels.gains_panel.gainsChanged.connect(commands.set_gains)
        panels.gains_panel.filterChanged.connect(commands.select_filter)
        panels.drop_area.cellsDropped.connect(views.cells_dropped)
        panels.drop_area.jointsDropped.connect(views.joints_dropped)
        commands.dataSwitched.connect(lambda _on: self.menus.update_toolbar())
        # The docks fill the window; the central widget is an empty strip.
        central = QWidget()
        central.setMaximumSize(0, 0)
        self.setCentralWidget(central)

    def _open_session(self) -> None:
        """Show the runner's file warnings, connect the model and attach the session."""
        log = self.panels.event_log
        for problem in getattr(self.runner, "problems", []):
            log.add(f"file warning: {problem}", "warning")
        runner = self.runner
        self.model.nominal_hz = lambda: nominal_hz(runner)
        self.model.samplesArrived.connect(self.display.on_samples)
        self.model.healthChanged.connect(self.display.show_stale)
        self.model.statusChanged.connect(self.display.on_status)
        self.model.attach(self.runner.session)
        self.model.set_data_on(self.runner.data_on)
        log.add(f"session opened: {MODE_LABELS[self.runner.mode]}"
                + (" (SIMULATED data)" if self.runner.mode == "sim" else ""))

    def shutdown(self) -> None:
        """Close plots and 3D views, stop the session (files closed), free the source."""
        if self.panels.file_panel.stopping is not None:
            self.panels.file_panel.stopping.wait(15.0)
        self.views.close_all()
        self.model.attach(None)
        self.runner.close()

    def showEvent(self, event) -> None:
        super().showEvent(event)
        QTimer.singleShot(0, self.layouts.raise_front)

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        QTimer.singleShot(0, self.views.fit_table)  # the table keeps its rows in view

    def closeEvent(self, event) -> None:
        if self.panels.file_panel.logging:
            answer = QMessageBox.question(self, "BPMS Suite",
                                          "Logging is on. Stop logging and close?")
            if answer != QMessageBox.StandardButton.Yes:
                event.ignore()
                return
        self.layouts.layout_store.remember(self.layouts.current_layout_state())
        self.shutdown()
        self.closed.emit()
        super().closeEvent(event)
