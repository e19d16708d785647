"""The main window's layout: the built-in layouts, and named layouts saved, loaded and
restored (:mod:`bpms.gui.layouts` stores them): :class:`DockLayouts`, which owns the layout
store and the name of the layout in use, and moves the fixed panels' docks and the
dynamic ones (:class:`~bpms.gui.window.dynamic_docks.ViewDocks` makes them).

Layouts never destroy work. A built-in layout moves the fixed panels to their places and
keeps every plot and 3D view the user opened: the 3D views go where the layout has its view
(the first in front, the others tabbed with it), the plots across the bottom (side by side,
then tabbed); only a dock the layout needs and the window lacks is made (a 3D view, the
joint angles of "playback analysis"). A saved layout re-creates its docks with their contents
(plot curves, locked y ranges and legend, 3D camera and switches, the table's columns) and
keeps the ones the window has and the layout does not. Every plot keeps its history, and a
plot the layout makes starts with the window's history (:class:`BlockHistory`).

Crowding: the data table keeps 18 rows in view when the window is tall enough to leave the
plots 320 px, and as many rows as fit otherwise (at least 9 on a 1366 × 768 screen;
:meth:`~bpms.gui.window.dynamic_docks.ViewDocks.fit_table`). The table, the 3D views
beside it and the plots under them share the left dock area (its rows can be sized; the
heights of separate dock areas around the empty central widget cannot), the status column
is the right area.
"""

from __future__ import annotations

import base64
import itertools

from PyQt6 import sip
from PyQt6.QtCore import QByteArray, Qt, QTimer
from PyQt6.QtWidgets import QDockWidget, QInputDialog, QMainWindow

from bpms.gui.columns import COLUMNS
from bpms.gui.layouts import CALIBRATION, DEFAULT_LAYOUTS, LIVE, PLAYBACK, Layout, LayoutStore
from bpms.gui.plots import PlotWindow
from bpms.gui.window.dynamic_docks import ViewDocks
from bpms.gui.window.panels import WindowPanels

_LEFT = Qt.DockWidgetArea.LeftDockWidgetArea
_RIGHT = Qt.DockWidgetArea.RightDockWidgetArea
_H, _V = Qt.Orientation.Horizontal, Qt.Orientation.Vertical

#: Widths of the columns at the default size, px: the status tabs and a 3D view.
STATUS_WIDTH, VIEW_WIDTH = 360, 380


class DockLayouts:
    """Where the docks of ``window`` sit: ``layout_store`` (the named layouts),
    ``current_layout`` (the name of the one in use, "" before the first)."""

    def __init__(self, window: QMainWindow, panels: WindowPanels, views: ViewDocks,
                 layout_store: LayoutStore) -> None:
        self._window = window
        self._panels = panels
        self._views = views
        self.layout_store = layout_store
        self.current_layout = ""
        self._front: list[QDockWidget] = []

    def first_layout(self, playback: bool, restore_last: bool) -> None:
        """The mode's built-in layout, then the last one used when ``restore_last``."""
        self.apply_default_layout(PLAYBACK if playback else LIVE)
        if restore_last and self.layout_store.last is not None:
            self.restore_layout(self.layout_store.last)
        if self.layout_store.problem:
            self._panels.event_log.add(self.layout_store.problem, "warning")

    # -- saved layouts -------------------------------------------------------------------
    def current_layout_state(self) -> Layout:
        """The window's layout now: the docks' places, each dynamic dock with its contents
        (a plot's description, a 3D view's camera) and the table's columns."""
        self._views.prune()
        docks = []
        for dock in self._views.dynamic_docks:
            widget = dock.widget()
            if isinstance(widget, PlotWindow):
                docks.append({"kind": "plot", "name": dock.objectName(),
                              "plot": widget.description()})
            elif widget is not None and hasattr(widget, "view_settings"):
                docks.append({"kind": "view3d", "name": dock.objectName(),
                              "view": widget.view_settings()})
        header = bytes(self._panels.table.horizontalHeader().saveState().data())
        return Layout(bytes(self._window.saveState().data()), docks,
                      {"table_header": base64.b64encode(header).decode("ascii")})

    def restore_layout(self, layout: Layout) -> bool:
        """Make the layout's plots and 3D views (or reuse the window's own of the same name
        and contents), restore the docks' places and the table's columns. Docks the layout
        does not name are kept."""
        self._views.prune()
        mine = {dock.objectName(): dock for dock in self._views.dynamic_docks}
        for spec in layout.docks:
            name = str(spec.get("name", ""))
            self._views.note_name(name)
            dock = mine.get(name)
            if spec.get("kind") == "plot":
                self._restore_plot(dock, name, spec.get("plot", {}))
            elif spec.get("kind") == "view3d":
                self._restore_view(dock, name, spec.get("view", {}))
        ok = self._window.restoreState(QByteArray(layout.state))
        if not ok:
            self._panels.event_log.add("a saved layout could not be restored (made by another "
                               "version?)", "warning")
        header = layout.extras.get("table_header")
        if isinstance(header, str):
            try:
                self._panels.table.horizontalHeader().restoreState(
                    QByteArray(base64.b64decode(header)))
            except ValueError:
                self._panels.event_log.add("the saved table columns could not be read", "warning")
            self._panels.table.fit_columns()
        self._tab_leftovers({str(s.get("name", "")) for s in layout.docks})
        return ok

    def _restore_plot(self, dock: QDockWidget | None, name: str, description: dict) -> None:
        widget = dock.widget() if dock is not None else None
        if isinstance(widget, PlotWindow) and _same_curves(widget.description(), description):
            widget.apply_view(description)  # the same plot: its history stays
            return
        if dock is not None:  # another dock took this name in this session: it stays too
            dock.setObjectName(self._views.next_name("plot" if isinstance(widget, PlotWindow)
                                               else "view3d"))
        plot = self._views.new_plot_from(description)
        if plot is not None:
            self._views.add_plot_dock(plot, name)

    def _restore_view(self, dock: QDockWidget | None, name: str, settings: dict) -> None:
        widget = dock.widget() if dock is not None else None
        if widget is None or isinstance(widget, PlotWindow):
            if dock is not None:
                dock.setObjectName(self._views.next_name("plot"))
            dock = self._views.add_view3d_dock(name)
            widget = dock.widget() if dock is not None else None
        if widget is not None and isinstance(settings, dict):
            widget.apply_view_settings(settings)

    def _tab_leftovers(self, named: set[str]) -> None:
        """Docks the restored layout does not name: tabbed with one of their kind it has."""
        placed = [d for d in self._views.dynamic_docks if d.objectName() in named]
        for dock in self._views.dynamic_docks:
            if dock.objectName() in named or dock.isFloating():
                continue
            plot = isinstance(dock.widget(), PlotWindow)
            host = next((d for d in placed if isinstance(d.widget(), PlotWindow) == plot
                         and not d.isFloating()), None)
            if host is not None:
                self._window.tabifyDockWidget(host, dock)

    def save_layout(self, name: str) -> Layout:
        """Save the current layout under ``name`` (per user)."""
        layout = self.current_layout_state()
        self.layout_store.put(name, layout)
        self.current_layout = name
        self._panels.event_log.add(f"layout saved: {name}")
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
        dialog = QInputDialog(self._window)
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
        self._views.prune()
        d = self._panels.docks
        plots = [dk for dk in self._views.dynamic_docks if isinstance(dk.widget(), PlotWindow)
                 and not dk.isFloating()]
        views = [dk for dk in self._views.dynamic_docks if not isinstance(dk.widget(), PlotWindow)
                 and not dk.isFloating()]
        for dock in (*d.values(), *plots, *views):
            dock.setFloating(False)
            self._window.removeDockWidget(dock)
        want3d = 1 if views3d is None else views3d
        while len(views) < want3d:
            dock = self._views.add_view3d_dock(area=_LEFT)
            if dock is None:
                break
            self._window.removeDockWidget(dock)
            views.append(dock)
        if name == PLAYBACK and not any(dk.widget().kind == "joints" for dk in plots):
            joints = self._views.new_joint_plot()
            plots.insert(0, self._views.add_plot_dock(joints, area=_LEFT))
            self._window.removeDockWidget(plots[0])
        # (split before tabbing: a dock split off a tabbed one would become another tab)
        self._window.addDockWidget(_LEFT, d["table"])
        self._window.addDockWidget(_RIGHT, d["status"])
        if name == CALIBRATION:
            self._window.splitDockWidget(d["table"], d["events"], _V)
            anchor, beside = d["status"], _V  # the 3D views under the status column
        else:
            self._window.splitDockWidget(d["status"], d["events"], _V)
            anchor, beside = d["table"], _H  # the 3D views beside the table
        if views:
            self._window.splitDockWidget(anchor, views[0], beside)
        self._window.tabifyDockWidget(d["status"], d["session"])
        self._window.tabifyDockWidget(d["status"], d["filter"])
        if views:
            for extra in views[1:]:
                self._window.tabifyDockWidget(views[0], extra)
            views[0].raise_()
        for k, dock in enumerate(plots):
            self._views.place_plot(dock, plots[:k])
        for dock in (*d.values(), *plots, *views):
            dock.show()
        self._front = [d[{CALIBRATION: "filter", PLAYBACK: "session"}.get(name, "status")],
                       *plots[:1]]
        self.raise_front()
        if name == CALIBRATION:
            first_cal = next(k for k, c in enumerate(COLUMNS) if c.group == "cal")
            # the calibrated, then raw columns first in view (left edge)
            header = self._panels.table.horizontalHeader()
            self._panels.table.horizontalScrollBar().setValue(header.visualIndex(first_cal))
        self.current_layout = name
        self._size_docks(name)

    def raise_front(self) -> None:
        """The layout's tabs in front (the playback slider in "playback analysis"); again
        once the window is shown (a tab raised before that does not stay in front)."""
        for dock in self._front:
            if not sip.isdeleted(dock):
                dock.raise_()

    def tile_plots(self) -> None:
        """View ▸ Tile plots: every docked plot in view at once, in a grid under the table
        (1 row up to 3 plots, 2 rows up to 8, then 3)."""
        self._views.prune()
        plots = [dk for dk in self._views.dynamic_docks if isinstance(dk.widget(), PlotWindow)
                 and not dk.isFloating()]
        if not plots:
            return
        rows = 1 if len(plots) <= 3 else 2 if len(plots) <= 8 else 3
        columns = -(-len(plots) // rows)
        for dock in plots:
            self._window.removeDockWidget(dock)
        top = plots[:columns]
        self._window.addDockWidget(_LEFT, top[0], _V)
        for left, right in itertools.pairwise(top):
            self._window.splitDockWidget(left, right, _H)
        for k, dock in enumerate(plots[columns:]):
            self._window.splitDockWidget(plots[k], dock, _V)  # under the plot k of the row above
        for dock in plots:
            dock.show()
        QTimer.singleShot(0, self._views.fit_table)

    def _size_docks(self, name: str) -> None:
        """Column widths, and the table's height (now and once the window is laid out)."""
        d = self._panels.docks

        def sizes() -> None:
            if sip.isdeleted(self._window):
                return
            widths = [(d["status"], STATUS_WIDTH)]
            views = [dk for dk in self._views.dynamic_docks
                     if not isinstance(dk.widget(), PlotWindow) and not dk.isFloating()]
            if views and name != CALIBRATION:
                table = max(300, self._window.width() - STATUS_WIDTH - VIEW_WIDTH)
                widths += [(d["table"], table), (views[0], VIEW_WIDTH)]
            alive = [(dk, n) for dk, n in widths if dk.parent() is self._window]
            self._window.resizeDocks([dk for dk, _ in alive], [n for _, n in alive], _H)
            if name == CALIBRATION:
                self._window.resizeDocks([d["events"]], [150], _V)
            else:
                self._window.resizeDocks([d["events"]], [max(120, self._window.height() // 4)], _V)
            self._views.fit_table()
            self.raise_front()

        sizes()
        QTimer.singleShot(0, sizes)  # again once the window is laid out


def _same_curves(a: dict, b: dict) -> bool:
    """Two plot descriptions draw the same curves (view settings aside)."""
    keys = ("kind", "cells", "joints")
    return all(_as_lists(a.get(k)) == _as_lists(b.get(k)) for k in keys)


def _as_lists(value):
    return [_as_lists(v) for v in value] if isinstance(value, (list, tuple)) else value
