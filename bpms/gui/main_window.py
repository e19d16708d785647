"""The main window: one window whose panels are Qt dock widgets (move, tab, float, close).

Docks: the data table, the status (health light, REC indicator and the link's numbers), the
session and file controls (logging, playback, UDP server), the filter settings, the event log,
and any number of plots and 3D views. Named layouts (:mod:`bpms.gui.layouts`) are saved per
user and the last one is restored at the next launch. The menu bar lists every command with
its shortcut; the toolbar holds Start/Stop, Reset Zero and Record. Everything redraws on
:class:`SessionModel`'s display timer; hidden docks do not repaint.

The window is assembled from parts with one job each (:mod:`bpms.gui.window`): the fixed
panels and their docks (``panels``), the menus and toolbar (``actions``), what depends on
the mode (``mode_wiring``), plots and 3D views (``dynamic_docks``), layouts
(``dock_layout``), the display tick and status (``status``) and the session commands
(``commands``). This module puts them together and closes the window.
"""

from __future__ import annotations

from PyQt6 import sip
from PyQt6.QtCore import QByteArray, QRect, QTimer, pyqtSignal
from PyQt6.QtWidgets import QDockWidget, QMainWindow, QMessageBox, QWidget

from bpms.gui.angle_readout import ContinuousAngles
from bpms.gui.layouts import LayoutStore
from bpms.gui.model import SessionModel
from bpms.gui.modes import MODE_LABELS, SessionRunner
from bpms.gui.plot_data import BlockHistory
from bpms.gui.plots import PlotWindow
from bpms.gui.screen_fit import place_window
from bpms.gui.window.actions import WindowActions
from bpms.gui.window.commands import SessionCommands
from bpms.gui.window.dock_layout import DockLayouts
from bpms.gui.window.dynamic_docks import DynamicDocks
from bpms.gui.window.mode_wiring import ModeWiring
from bpms.gui.window.panels import WindowPanels
from bpms.gui.window.status import StatusDisplay
from bpms.io.frames import FRAME_RATE_HZ
from bpms.io.options import Options


class MainWindow(WindowPanels, WindowActions, ModeWiring, DynamicDocks, DockLayouts,
                 StatusDisplay, SessionCommands, QMainWindow):
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
        self.simulated = runner.mode == "sim"
        self._init_state()
        self._set_up_frame()
        self._build_docks()
        self.layout_store = layout_store if layout_store is not None else LayoutStore()
        self.current_layout = ""
        self._menus()
        # REC and the link light in the status bar: in view whatever the docks (closed,
        # tabbed, scrolled)
        self.statusBar().addPermanentWidget(self.health_panel.rec_badge)
        self.statusBar().addPermanentWidget(self.health_panel.link_badge)
        # the size of the screen before the layout is built (the docks are sized to it)
        self.placement = place_window(self, saved_geometry, available)
        self._first_layout(restore_last)
        self._open_session()

    def _init_state(self) -> None:
        self.plot_windows: list[PlotWindow] = []
        self.view3d_windows: list[QWidget] = []
        self.browser_views: list = []
        self.dynamic_docks: list[QDockWidget] = []
        self._dock_serial = 0
        self.tick_times_s: list[float] = []  # GUI time per display tick (bench/gui.py)
        self._last_recording = None
        self._counters: dict[str, int] = {}
        self._texts_at = -1e9
        self._last_state = ""
        self._source_warning = ""
        self._reinit_count = 0
        self._disturbed: tuple[int, int] | None = None  # IMUs (mag, acc) disturbed now
        self.readout = ContinuousAngles()  # the angles shown, continuous (docs/main-window.md)
        self.history = BlockHistory(max(1, round(self.options.display.plot_history_s
                                                 * FRAME_RATE_HZ)))

    def _set_up_frame(self) -> None:
        title = f"BPMS Suite — {MODE_LABELS[self.runner.mode]}"
        self.setWindowTitle(("SIMULATED — " + title) if self.simulated else title)
        self.setDockNestingEnabled(True)
        self.setDockOptions(QMainWindow.DockOption.AllowTabbedDocks
                            | QMainWindow.DockOption.AllowNestedDocks
                            | QMainWindow.DockOption.AnimatedDocks)

    def _open_session(self) -> None:
        """Show the runner's file warnings, connect the model and attach the session."""
        for problem in getattr(self.runner, "problems", []):
            self.event_log.add(f"file warning: {problem}", "warning")
        self.model.nominal_hz = self._nominal_hz
        self.model.samplesArrived.connect(self._on_samples)
        self.model.healthChanged.connect(self._show_stale)
        self.model.statusChanged.connect(self._on_status)
        self.model.attach(self.runner.session)
        self.model.set_data_on(self.runner.data_on)
        self.event_log.add(f"session opened: {MODE_LABELS[self.runner.mode]}"
                           + (" (SIMULATED data)" if self.simulated else ""))

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

    def showEvent(self, event) -> None:
        super().showEvent(event)
        QTimer.singleShot(0, self.raise_front)

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        QTimer.singleShot(0, self.fit_table)  # the table keeps its rows in view

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
