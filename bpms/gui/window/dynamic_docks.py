"""The main window's dynamic docks: plots and 3D views, opened, placed, fed their history,
closed and pruned, and the browser 3D views.

:class:`ViewDocks` owns the lists of them (``plot_windows``, ``view3d_windows``,
``browser_views``, ``dynamic_docks``) and where a new plot goes: the bottom row of the left
dock area, under the table, which keeps its rows in view (:meth:`ViewDocks.fit_table`).
"""

from __future__ import annotations

from collections.abc import Callable

from PyQt6 import sip
from PyQt6.QtCore import Qt, QTimer
from PyQt6.QtWidgets import QDockWidget, QMainWindow, QWidget

from bpms.gui.docks import make_dock
from bpms.gui.health import stale_text
from bpms.gui.model import SessionModel
from bpms.gui.plot_data import BlockHistory
from bpms.gui.plots import PlotWindow, cells_plot, joint_angle_plot, plot_from
from bpms.gui.window.panels import WindowPanels
from bpms.io.options import Options

#: A browser view's process still running this long after opening (ms), or said to have ended.
BROWSER_CHECK_MS = 8000

_LEFT = Qt.DockWidgetArea.LeftDockWidgetArea
_H, _V = Qt.Orientation.Horizontal, Qt.Orientation.Vertical

#: The table shows all 18 IMUs when the plots keep at least MIN_PLOT_HEIGHT pixels, and at
#: least TABLE_MIN_ROWS however small the window.
TABLE_ROWS = 18
TABLE_MIN_ROWS = 9
MIN_PLOT_HEIGHT = 320
#: Plots share the bottom row side by side while each keeps this width, then tab.
PLOT_MIN_SIDE_BY_SIDE = 900


class ViewDocks:
    """Plot and 3D-view docks in ``window``: ``plot_windows``, ``view3d_windows``,
    ``dynamic_docks`` (both kinds, in the order made) and ``browser_views``. A new plot
    starts with ``history``; a 3D view's Reset Zero key calls ``reset_zero("3d-view")``."""

    def __init__(self, window: QMainWindow, model: SessionModel, options: Options,
                 panels: WindowPanels, history: BlockHistory,
                 reset_zero: Callable[[str], None]) -> None:
        self._window = window
        self._model = model
        self._options = options
        self._panels = panels
        self._history = history
        self._reset_zero = reset_zero
        self.plot_windows: list[PlotWindow] = []
        self.view3d_windows: list[QWidget] = []
        self.browser_views: list = []
        self.dynamic_docks: list[QDockWidget] = []
        self._serial = 0

    def next_name(self, kind: str) -> str:
        """A dock name not used yet in this window: ``kind-N``."""
        self._serial += 1
        return f"{kind}-{self._serial}"

    def note_name(self, name: str) -> None:
        """A dock name taken (a saved layout's): :meth:`next_name` goes beyond it."""
        serial = name.rpartition("-")[2]
        if serial.isdigit():
            self._serial = max(self._serial, int(serial))

    def add_plot_dock(self, plot: PlotWindow, name: str | None = None,
                      area: Qt.DockWidgetArea | None = None) -> QDockWidget:
        """Show ``plot`` in a new dock (closing the dock deletes the plot): under the table,
        beside the plots there (then tabbed), the table keeping its rows in view; or in
        ``area``."""
        dock = make_dock(plot.windowTitle(), name or self.next_name("plot"), plot,
                         dynamic=True)
        plot.setMinimumSize(200, 150)
        plot.cellsDropped.connect(self.cells_dropped)
        plot.jointsDropped.connect(self.joints_dropped)
        if area is None:
            self.place_plot(dock, [d for d in self.dynamic_docks
                                   if isinstance(d.widget(), PlotWindow)])
            QTimer.singleShot(0, self.fit_table)
        else:
            self._window.addDockWidget(area, dock)
        self.plot_windows.append(plot)
        self.dynamic_docks.append(dock)
        self._backfill(plot)
        health = self._model.last_health
        plot.stale.show_text(stale_text(health) if health is not None else None)
        plot.redraw()
        return dock

    def add_view3d_dock(self, name: str | None = None,
                        area: Qt.DockWidgetArea | None = None) -> QDockWidget | None:
        """A new 3D view: beside the last docked one (or the table), or in ``area``."""
        module = self._panels.view3d_module
        if module is None or not self._panels.view3d_button.isEnabled():
            return None
        window = self._window
        view = module.View3DWindow(self._model)  # type: ignore[attr-defined]
        view.resetZeroRequested.connect(lambda: self._reset_zero("3d-view"))
        dock = make_dock("3D view", name or self.next_name("view3d"), view, dynamic=True)
        views = [d for d in self.dynamic_docks if not isinstance(d.widget(), PlotWindow)
                 and not d.isFloating() and d.parent() is window and not d.isHidden()]
        if area is not None:
            window.addDockWidget(area, dock)
        elif views:
            window.splitDockWidget(views[-1], dock, Qt.Orientation.Horizontal)
        else:
            window.splitDockWidget(self._panels.docks["table"], dock,
                                   Qt.Orientation.Horizontal)
        self.view3d_windows.append(view)
        self.dynamic_docks.append(dock)
        return dock

    def prune(self) -> None:
        """Forget plots and 3D views whose dock the user closed (deleted by Qt). No
        ``destroyed`` slots: they would run while the window itself is torn down."""
        self.dynamic_docks = [d for d in self.dynamic_docks if not sip.isdeleted(d)]
        self.plot_windows = [w for w in self.plot_windows
                             if not sip.isdeleted(w) and not w.closed]
        self.view3d_windows = [w for w in self.view3d_windows if not sip.isdeleted(w)]

    def close_all(self) -> None:
        """Close the browser views and the 3D views (at the window's close)."""
        for view in self.browser_views:
            self._model.samplesArrived.disconnect(view.feed)
            view.close()
        self.browser_views.clear()
        self.prune()
        for view in list(self.view3d_windows):
            if not sip.isdeleted(view):
                view.close()

    def dock_of(self, widget: QWidget) -> QDockWidget | None:
        return next((dock for dock in self.dynamic_docks if dock.widget() is widget), None)

    def plot_selection(self) -> PlotWindow | None:
        """A new plot dock of the selected cells (one curve each), or of the selected joint
        angles when their tab is in front."""
        panels = self._panels
        if panels.table_tabs.currentWidget() is panels.joint_table:
            joints = panels.joint_table.selected_joints()
            if joints:
                return self.joints_dropped(joints, None)
        cells = panels.table.selected_cells()
        if not cells:
            self._window.statusBar().showMessage("Select one or more numeric cells first "
                                                 "(Ctrl/Shift+click)", 5000)
            return None
        return self._new_cells_plot(cells)

    def _new_cells_plot(self, cells: list[tuple[int, int]]) -> PlotWindow:
        number = 1 + sum(isinstance(d.widget(), PlotWindow) for d in self.dynamic_docks)
        window = cells_plot(cells, self._panels.table_model.angle_unit,
                            self._options.display.plot_history_s, number)
        self.add_plot_dock(window)
        return window

    def cells_dropped(self, cells: list, plot: object) -> None:
        """Cells dragged from the table: onto a plot (added there) or elsewhere (new plot)."""
        if isinstance(plot, PlotWindow):
            plot.add_cells(cells)
        elif cells:
            self._new_cells_plot(cells)

    def joints_dropped(self, joints: list, plot: object) -> PlotWindow | None:
        """Joint angles dragged from their list: onto a plot or elsewhere (new plot)."""
        unit = self._panels.table_model.angle_unit
        if isinstance(plot, PlotWindow):
            plot.add_joints(joints, unit)
            return plot
        if not joints:
            return None
        number = 1 + sum(isinstance(d.widget(), PlotWindow) for d in self.dynamic_docks)
        window = plot_from({"kind": "cells", "title": f"Plot {number}", "joints": joints},
                           unit, self._options.display.plot_history_s)
        if window is not None:
            self.add_plot_dock(window)
        return window

    def new_joint_plot(self) -> PlotWindow:
        """A joint-angle plot, not docked yet."""
        return joint_angle_plot(self._panels.table_model.angle_unit,
                                self._options.display.plot_history_s)

    def new_plot_from(self, description: dict) -> PlotWindow | None:
        """A plot made from its description (a saved layout's), not docked yet."""
        return plot_from(description, self._panels.table_model.angle_unit,
                         self._options.display.plot_history_s)

    def open_joint_plot(self) -> PlotWindow:
        window = self.new_joint_plot()
        self.add_plot_dock(window)
        return window

    def _backfill(self, window: PlotWindow) -> None:
        """A new plot starts with the window's history (the last plot_history_s seconds)."""
        block = self._history.block(self._panels.table_model.calibration)
        if block is not None:
            window.append(block)

    def open_3d_view(self) -> QWidget | None:
        """A new 3D view dock (when bpms.gui.view3d is available)."""
        dock = self.add_view3d_dock()
        return None if dock is None else dock.widget()

    def open_browser_view(self) -> object | None:
        """The figure in a browser (the vpython extra), fed from the window's model."""
        module = self._panels.vpython_module
        if module is None or not self._panels.browser_button.isEnabled():
            return None
        say = self._window.statusBar().showMessage
        try:
            view = module.open_browser_view(self._model)  # type: ignore[attr-defined]
        except (RuntimeError, OSError) as exc:
            say(f"Browser 3D view: {exc}", 10000)
            self._panels.event_log.add(f"Browser 3D view not opened: {exc}", "warning")
            return None
        self.browser_views.append(view)
        say("Browser 3D view: opening in the web browser…", 10000)
        QTimer.singleShot(BROWSER_CHECK_MS, lambda: self._browser_check(view))
        return view

    def _browser_check(self, view) -> None:
        """A browser view whose process ended already: no browser page came (said once)."""
        if view in self.browser_views and not view.alive:
            self._panels.event_log.add("Browser 3D view ended: no web browser page opened "
                                       f"(exit status {view.process.returncode})", "warning")

    # -- where plots go ------------------------------------------------------------------
    def place_plot(self, dock: QDockWidget, before: list[QDockWidget]) -> None:
        """The bottom row of the left area (under the table and the 3D views): beside the
        plots there, then tabbed onto the last."""
        window = self._window
        docked = [dk for dk in before if dk is not dock and not dk.isFloating()
                  and dk.parent() is window and window.dockWidgetArea(dk) == _LEFT]
        if not docked:
            window.addDockWidget(_LEFT, dock, _V)
            return
        row = [dk for dk in docked if not window.tabifiedDockWidgets(dk)
               or dk is docked[-1]]
        width = window.width() - self._panels.docks["status"].width()
        if width / (len(row) + 1) >= PLOT_MIN_SIDE_BY_SIDE:
            window.splitDockWidget(docked[-1], dock, _H)
        else:
            window.tabifyDockWidget(docked[-1], dock)
        QTimer.singleShot(0, lambda: None if sip.isdeleted(dock) else dock.raise_())

    def fit_table(self) -> None:
        """Give the table the height of :data:`TABLE_ROWS` rows when the plots under it keep
        :data:`MIN_PLOT_HEIGHT`, else as many rows as fit beside that (at least
        :data:`TABLE_MIN_ROWS`)."""
        window = self._window
        if sip.isdeleted(window):
            return
        table = self._panels.docks["table"]
        plots = [dk for dk in self.dynamic_docks if isinstance(dk.widget(), PlotWindow)
                 and not dk.isFloating() and dk.isVisible()
                 and window.dockWidgetArea(dk) == _LEFT and dk.y() > table.y()]
        if not plots or not table.isVisible() or window.dockWidgetArea(table) != _LEFT:
            return
        view = self._panels.table
        chrome = table.height() - view.viewport().height()  # title, buttons, tabs, header
        row = view.verticalHeader().defaultSectionSize()
        between = plots[0].y() - (table.y() + table.height())  # the splitter
        total = table.height() + between + plots[0].height()
        rows = min(TABLE_ROWS, max(TABLE_MIN_ROWS,
                                   (total - between - MIN_PLOT_HEIGHT - chrome) // row))
        want = chrome + rows * row + 2
        if abs(table.height() - want) > 2:
            window.resizeDocks([table, plots[0]], [want, total - between - want], _V)
