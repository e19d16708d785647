"""The main window's layout: the built-in layouts, and named layouts saved, loaded and
restored (:mod:`bpms.gui.layouts` stores them). Mixed into
:class:`bpms.gui.main_window.MainWindow`.

Layouts never destroy work. A built-in layout moves the fixed panels to their places and
keeps every plot and 3D view the user opened: the 3D views go where the layout has its view
(the first in front, the others tabbed with it), the plots across the bottom (side by side,
then tabbed); only a dock the layout needs and the window lacks is made (a 3D view, the
joint angles of "playback analysis"). A saved layout re-creates its docks with their contents
(plot curves, locked y ranges and legend, 3D camera and switches, the table's columns) and
keeps the ones the window has and the layout does not. Every plot keeps its history, and a
plot the layout makes starts with the window's history (:class:`BlockHistory`).

Crowding: the data table keeps :data:`TABLE_ROWS` rows in view when the window is tall
enough to leave the plots :data:`MIN_PLOT_HEIGHT`, and as many rows as fit otherwise (at
least 9 on a 1366 × 768 screen). The table, the 3D views beside it and the plots under them
share the left dock area (its rows can be sized; the heights of separate dock areas around
the empty central widget cannot), the status column is the right area.
"""

from __future__ import annotations

import base64
import itertools

from PyQt6 import sip
from PyQt6.QtCore import QByteArray, Qt, QTimer
from PyQt6.QtWidgets import QDockWidget, QInputDialog

from bpms.gui.columns import COLUMNS
from bpms.gui.layouts import CALIBRATION, DEFAULT_LAYOUTS, LIVE, PLAYBACK, Layout
from bpms.gui.plots import PlotWindow, joint_angle_plot, plot_from

_LEFT = Qt.DockWidgetArea.LeftDockWidgetArea
_RIGHT = Qt.DockWidgetArea.RightDockWidgetArea
_H, _V = Qt.Orientation.Horizontal, Qt.Orientation.Vertical

#: The table shows all 18 IMUs when the plots keep at least MIN_PLOT_HEIGHT pixels, and at
#: least TABLE_MIN_ROWS however small the window.
TABLE_ROWS = 18
TABLE_MIN_ROWS = 9
MIN_PLOT_HEIGHT = 320
#: Plots share the bottom row side by side while each keeps this width, then tab.
PLOT_MIN_SIDE_BY_SIDE = 900
#: Widths of the columns at the default size, px: the status tabs and a 3D view.
STATUS_WIDTH, VIEW_WIDTH = 360, 380


class DockLayouts:
    """Where the docks sit: ``layout_store``, ``current_layout``."""

    def _first_layout(self, restore_last: bool) -> None:
        """The mode's built-in layout, then the last one used when ``restore_last``."""
        self.apply_default_layout(LIVE if self.runner.replay is None else PLAYBACK)
        if restore_last and self.layout_store.last is not None:
            self.restore_layout(self.layout_store.last)
        if self.layout_store.problem:
            self.event_log.add(self.layout_store.problem, "warning")

    # -- saved layouts -------------------------------------------------------------------
    def current_layout_state(self) -> Layout:
        """The window's layout now: the docks' places, each dynamic dock with its contents
        (a plot's description, a 3D view's camera) and the table's columns."""
        self._prune()
        docks = []
        for dock in self.dynamic_docks:
            widget = dock.widget()
            if isinstance(widget, PlotWindow):
                docks.append({"kind": "plot", "name": dock.objectName(),
                              "plot": widget.description()})
            elif widget is not None and hasattr(widget, "view_settings"):
                docks.append({"kind": "view3d", "name": dock.objectName(),
                              "view": widget.view_settings()})
        header = bytes(self.table.horizontalHeader().saveState().data())
        return Layout(bytes(self.saveState().data()), docks,
                      {"table_header": base64.b64encode(header).decode("ascii")})

    def restore_layout(self, layout: Layout) -> bool:
        """Make the layout's plots and 3D views (or reuse the window's own of the same name
        and contents), restore the docks' places and the table's columns. Docks the layout
        does not name are kept."""
        self._prune()
        mine = {dock.objectName(): dock for dock in self.dynamic_docks}
        for spec in layout.docks:
            name = str(spec.get("name", ""))
            serial = name.rpartition("-")[2]
            if serial.isdigit():
                self._dock_serial = max(self._dock_serial, int(serial))
            dock = mine.get(name)
            if spec.get("kind") == "plot":
                self._restore_plot(dock, name, spec.get("plot", {}))
            elif spec.get("kind") == "view3d":
                self._restore_view(dock, name, spec.get("view", {}))
        ok = self.restoreState(QByteArray(layout.state))
        if not ok:
            self.event_log.add("a saved layout could not be restored (made by another "
                               "version?)", "warning")
        header = layout.extras.get("table_header")
        if isinstance(header, str):
            try:
                self.table.horizontalHeader().restoreState(
                    QByteArray(base64.b64decode(header)))
            except ValueError:
                self.event_log.add("the saved table columns could not be read", "warning")
            self.table.fit_columns()
        self._tab_leftovers({str(s.get("name", "")) for s in layout.docks})
        return ok

    def _restore_plot(self, dock: QDockWidget | None, name: str, description: dict) -> None:
        widget = dock.widget() if dock is not None else None
        if isinstance(widget, PlotWindow) and _same_curves(widget.description(), description):
            widget.apply_view(description)  # the same plot: its history stays
            return
        if dock is not None:  # another dock took this name in this session: it stays too
            dock.setObjectName(self._next_name("plot" if isinstance(widget, PlotWindow)
                                               else "view3d"))
        plot = plot_from(description, self.table_model.angle_unit,
                         self.options.display.plot_history_s)
        if plot is not None:
            self.add_plot_dock(plot, name)

    def _restore_view(self, dock: QDockWidget | None, name: str, settings: dict) -> None:
        widget = dock.widget() if dock is not None else None
        if widget is None or isinstance(widget, PlotWindow):
            if dock is not None:
                dock.setObjectName(self._next_name("plot"))
            dock = self.add_view3d_dock(name)
            widget = dock.widget() if dock is not None else None
        if widget is not None and isinstance(settings, dict):
            widget.apply_view_settings(settings)

    def _tab_leftovers(self, named: set[str]) -> None:
        """Docks the restored layout does not name: tabbed with one of their kind it has."""
        placed = [d for d in self.dynamic_docks if d.objectName() in named]
        for dock in self.dynamic_docks:
            if dock.objectName() in named or dock.isFloating():
                continue
            plot = isinstance(dock.widget(), PlotWindow)
            host = next((d for d in placed if isinstance(d.widget(), PlotWindow) == plot
                         and not d.isFloating()), None)
            if host is not None:
                self.tabifyDockWidget(host, dock)

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

    # -- built-in layouts ----------------------------------------------------------------
    def apply_default_layout(self, name: str, views3d: int | None = None) -> None:
        """One of :data:`DEFAULT_LAYOUTS`, built here (the user's saved version of the same
        name wins in :meth:`load_layout`); ``views3d``: how many 3D views it has at least.

        - live monitoring: the table with a 3D view beside it, the status / session /
          filter tabs on the right over the event log, plots across the bottom;
        - playback analysis: the same, the session tab (the playback slider) in front and
          the joint angles across the bottom;
        - calibration check: the table large, scrolled to the calibrated and raw columns,
          with plots and the event log under it; the filter settings (in front of status
          and session) on the right over a 3D view.
        """
        self._prune()
        d = self.docks
        plots = [dk for dk in self.dynamic_docks if isinstance(dk.widget(), PlotWindow)
                 and not dk.isFloating()]
        views = [dk for dk in self.dynamic_docks if not isinstance(dk.widget(), PlotWindow)
                 and not dk.isFloating()]
        for dock in (*d.values(), *plots, *views):
            dock.setFloating(False)
            self.removeDockWidget(dock)
        want3d = 1 if views3d is None else views3d
        while len(views) < want3d:
            dock = self.add_view3d_dock(area=_LEFT)
            if dock is None:
                break
            self.removeDockWidget(dock)
            views.append(dock)
        if name == PLAYBACK and not any(dk.widget().kind == "joints" for dk in plots):
            joints = joint_angle_plot(self.table_model.angle_unit,
                                      self.options.display.plot_history_s)
            plots.insert(0, self.add_plot_dock(joints, area=_LEFT))
            self.removeDockWidget(plots[0])
        # (split before tabbing: a dock split off a tabbed one would become another tab)
        self.addDockWidget(_LEFT, d["table"])
        self.addDockWidget(_RIGHT, d["status"])
        if name == CALIBRATION:
            self.splitDockWidget(d["table"], d["events"], _V)
            anchor, beside = d["status"], _V  # the 3D views under the status column
        else:
            self.splitDockWidget(d["status"], d["events"], _V)
            anchor, beside = d["table"], _H  # the 3D views beside the table
        if views:
            self.splitDockWidget(anchor, views[0], beside)
        self.tabifyDockWidget(d["status"], d["session"])
        self.tabifyDockWidget(d["status"], d["filter"])
        if views:
            for extra in views[1:]:
                self.tabifyDockWidget(views[0], extra)
            views[0].raise_()
        for k, dock in enumerate(plots):
            self._place_plot(dock, plots[:k])
        for dock in (*d.values(), *plots, *views):
            dock.show()
        self._front = [d[{CALIBRATION: "filter", PLAYBACK: "session"}.get(name, "status")],
                       *plots[:1]]
        self.raise_front()
        if name == CALIBRATION:
            first_cal = next(k for k, c in enumerate(COLUMNS) if c.group == "cal")
            # the calibrated, then raw columns first in view (left edge)
            header = self.table.horizontalHeader()
            self.table.horizontalScrollBar().setValue(header.visualIndex(first_cal))
        self.current_layout = name
        self._size_docks(name)

    def raise_front(self) -> None:
        """The layout's tabs in front (the playback slider in "playback analysis"); again
        once the window is shown (a tab raised before that does not stay in front)."""
        for dock in getattr(self, "_front", []):
            if not sip.isdeleted(dock):
                dock.raise_()

    def _place_plot(self, dock: QDockWidget, before: list[QDockWidget]) -> None:
        """The bottom row of the left area (under the table and the 3D views): beside the
        plots there, then tabbed onto the last."""
        docked = [dk for dk in before if dk is not dock and not dk.isFloating()
                  and dk.parent() is self and self.dockWidgetArea(dk) == _LEFT]
        if not docked:
            self.addDockWidget(_LEFT, dock, _V)
            return
        row = [dk for dk in docked if not self.tabifiedDockWidgets(dk)
               or dk is docked[-1]]
        width = self.width() - self.docks["status"].width()
        if width / (len(row) + 1) >= PLOT_MIN_SIDE_BY_SIDE:
            self.splitDockWidget(docked[-1], dock, _H)
        else:
            self.tabifyDockWidget(docked[-1], dock)
        QTimer.singleShot(0, lambda: None if sip.isdeleted(dock) else dock.raise_())

    def tile_plots(self) -> None:
        """View ▸ Tile plots: every docked plot in view at once, in a grid under the table
        (1 row up to 3 plots, 2 rows up to 8, then 3)."""
        self._prune()
        plots = [dk for dk in self.dynamic_docks if isinstance(dk.widget(), PlotWindow)
                 and not dk.isFloating()]
        if not plots:
            return
        rows = 1 if len(plots) <= 3 else 2 if len(plots) <= 8 else 3
        columns = -(-len(plots) // rows)
        for dock in plots:
            self.removeDockWidget(dock)
        top = plots[:columns]
        self.addDockWidget(_LEFT, top[0], _V)
        for left, right in itertools.pairwise(top):
            self.splitDockWidget(left, right, _H)
        for k, dock in enumerate(plots[columns:]):
            self.splitDockWidget(plots[k], dock, _V)  # under the plot k of the row above
        for dock in plots:
            dock.show()
        QTimer.singleShot(0, self.fit_table)

    def _size_docks(self, name: str) -> None:
        """Column widths, and the table's height (now and once the window is laid out)."""
        d = self.docks

        def sizes() -> None:
            if sip.isdeleted(self):
                return
            widths = [(d["status"], STATUS_WIDTH)]
            views = [dk for dk in self.dynamic_docks
                     if not isinstance(dk.widget(), PlotWindow) and not dk.isFloating()]
            if views and name != CALIBRATION:
                table = max(300, self.width() - STATUS_WIDTH - VIEW_WIDTH)
                widths += [(d["table"], table), (views[0], VIEW_WIDTH)]
            alive = [(dk, n) for dk, n in widths if dk.parent() is self]
            self.resizeDocks([dk for dk, _ in alive], [n for _, n in alive], _H)
            if name == CALIBRATION:
                self.resizeDocks([d["events"]], [150], _V)
            else:
                self.resizeDocks([d["events"]], [max(120, self.height() // 4)], _V)
            self.fit_table()
            self.raise_front()

        sizes()
        QTimer.singleShot(0, sizes)  # again once the window is laid out

    def fit_table(self) -> None:
        """Give the table the height of :data:`TABLE_ROWS` rows when the plots under it keep
        :data:`MIN_PLOT_HEIGHT`, else as many rows as fit beside that (at least
        :data:`TABLE_MIN_ROWS`)."""
        if sip.isdeleted(self):
            return
        table = self.docks["table"]
        plots = [dk for dk in self.dynamic_docks if isinstance(dk.widget(), PlotWindow)
                 and not dk.isFloating() and dk.isVisible()
                 and self.dockWidgetArea(dk) == _LEFT and dk.y() > table.y()]
        if not plots or not table.isVisible() or self.dockWidgetArea(table) != _LEFT:
            return
        view = self.table
        chrome = table.height() - view.viewport().height()  # title, buttons, tabs, header
        row = view.verticalHeader().defaultSectionSize()
        between = plots[0].y() - (table.y() + table.height())  # the splitter
        total = table.height() + between + plots[0].height()
        rows = min(TABLE_ROWS, max(TABLE_MIN_ROWS,
                                   (total - between - MIN_PLOT_HEIGHT - chrome) // row))
        want = chrome + rows * row + 2
        if abs(table.height() - want) > 2:
            self.resizeDocks([table, plots[0]], [want, total - between - want], _V)


def _same_curves(a: dict, b: dict) -> bool:
    """Two plot descriptions draw the same curves (view settings aside)."""
    keys = ("kind", "cells", "joints")
    return all(_as_lists(a.get(k)) == _as_lists(b.get(k)) for k in keys)


def _as_lists(value):
    return [_as_lists(v) for v in value] if isinstance(value, (list, tuple)) else value
