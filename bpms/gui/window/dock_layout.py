"""The main window's layout: the built-in layouts, and named layouts saved, loaded and
restored (:mod:`bpms.gui.layouts` stores them). Mixed into
:class:`bpms.gui.main_window.MainWindow`."""

from __future__ import annotations

from PyQt6 import sip
from PyQt6.QtCore import QByteArray, Qt, QTimer
from PyQt6.QtWidgets import QInputDialog

from bpms.gui.layouts import CALIBRATION, DEFAULT_LAYOUTS, LIVE, PLAYBACK, Layout
from bpms.gui.plots import PlotWindow, joint_angle_plot, plot_from

_LEFT = Qt.DockWidgetArea.LeftDockWidgetArea
_RIGHT = Qt.DockWidgetArea.RightDockWidgetArea
_BOTTOM = Qt.DockWidgetArea.BottomDockWidgetArea


class DockLayouts:
    """Where the docks sit: ``layout_store``, ``current_layout``."""

    def _first_layout(self, restore_last: bool) -> None:
        """The mode's built-in layout, then the last one used when ``restore_last``."""
        self.apply_default_layout(LIVE if self.runner.replay is None else PLAYBACK)
        if restore_last and self.layout_store.last is not None:
            self.restore_layout(self.layout_store.last)
        if self.layout_store.problem:
            self.event_log.add(self.layout_store.problem, "warning")

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
