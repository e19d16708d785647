"""The main window's dynamic docks: plots and 3D views, opened, fed their history, closed
and pruned. Mixed into :class:`bpms.gui.main_window.MainWindow`."""

from __future__ import annotations

from PyQt6 import sip
from PyQt6.QtCore import Qt, QTimer
from PyQt6.QtWidgets import QDockWidget, QWidget

from bpms.gui.docks import make_dock
from bpms.gui.health import stale_text
from bpms.gui.plots import PlotWindow, cells_plot, joint_angle_plot, plot_from

#: A browser view's process still running this long after opening (ms), or said to have ended.
BROWSER_CHECK_MS = 8000


class DynamicDocks:
    """Plot and 3D-view docks: ``plot_windows``, ``view3d_windows``, ``dynamic_docks``."""

    def _next_name(self, kind: str) -> str:
        self._dock_serial += 1
        return f"{kind}-{self._dock_serial}"

    def add_plot_dock(self, plot: PlotWindow, name: str | None = None,
                      area: Qt.DockWidgetArea | None = None) -> QDockWidget:
        """Show ``plot`` in a new dock (closing the dock deletes the plot): under the table,
        beside the plots there (then tabbed), the table keeping its rows in view; or in
        ``area``."""
        dock = make_dock(plot.windowTitle(), name or self._next_name("plot"), plot,
                         dynamic=True)
        plot.setMinimumSize(200, 150)
        plot.cellsDropped.connect(self._cells_dropped)
        plot.jointsDropped.connect(self._joints_dropped)
        if area is None:
            self._place_plot(dock, [d for d in self.dynamic_docks
                                    if isinstance(d.widget(), PlotWindow)])
            QTimer.singleShot(0, self.fit_table)
        else:
            self.addDockWidget(area, dock)
        self.plot_windows.append(plot)
        self.dynamic_docks.append(dock)
        self._backfill(plot)
        plot.stale.show_text(stale_text(self.model.last_health)
                             if self.model.last_health is not None else None)
        plot.redraw()
        return dock

    def add_view3d_dock(self, name: str | None = None,
                        area: Qt.DockWidgetArea | None = None) -> QDockWidget | None:
        """A new 3D view: beside the last docked one (or the table), or in ``area``."""
        if self._view3d is None or not self.view3d_button.isEnabled():
            return None
        view = self._view3d.View3DWindow(self.model)  # type: ignore[attr-defined]
        view.resetZeroRequested.connect(lambda: self.reset_zero("3d-view"))
        dock = make_dock("3D view", name or self._next_name("view3d"), view, dynamic=True)
        views = [d for d in self.dynamic_docks if not isinstance(d.widget(), PlotWindow)
                 and not d.isFloating() and d.parent() is self and not d.isHidden()]
        if area is not None:
            self.addDockWidget(area, dock)
        elif views:
            self.splitDockWidget(views[-1], dock, Qt.Orientation.Horizontal)
        else:
            self.splitDockWidget(self.docks["table"], dock, Qt.Orientation.Horizontal)
        self.view3d_windows.append(view)
        self.dynamic_docks.append(dock)
        return dock

    def _prune(self) -> None:
        """Forget plots and 3D views whose dock the user closed (deleted by Qt). No
        ``destroyed`` slots: they would run while this window itself is torn down."""
        self.dynamic_docks = [d for d in self.dynamic_docks if not sip.isdeleted(d)]
        self.plot_windows = [w for w in self.plot_windows
                             if not sip.isdeleted(w) and not w.closed]
        self.view3d_windows = [w for w in self.view3d_windows if not sip.isdeleted(w)]

    def dock_of(self, widget: QWidget) -> QDockWidget | None:
        return next((dock for dock in self.dynamic_docks if dock.widget() is widget), None)

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
        self.add_plot_dock(window)
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
            self.add_plot_dock(window)
        return window

    def open_joint_plot(self) -> PlotWindow:
        window = joint_angle_plot(self.table_model.angle_unit,
                                  self.options.display.plot_history_s)
        self.add_plot_dock(window)
        return window

    def _backfill(self, window: PlotWindow) -> None:
        """A new plot starts with the window's history (the last plot_history_s seconds)."""
        block = self.history.block(self.table_model.calibration)
        if block is not None:
            window.append(block)

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
            self.event_log.add(f"Browser 3D view not opened: {exc}", "warning")
            return None
        self.browser_views.append(view)
        self.statusBar().showMessage("Browser 3D view: opening in the web browser…", 10000)
        QTimer.singleShot(BROWSER_CHECK_MS, lambda: self._browser_check(view))
        return view

    def _browser_check(self, view) -> None:
        """A browser view whose process ended already: no browser page came (said once)."""
        if view in self.browser_views and not view.alive:
            self.event_log.add("Browser 3D view ended: no web browser page opened "
                               f"(exit status {view.process.returncode})", "warning")
