"""Live plot windows, redrawn on the session model's display timer from the numpy ring
buffers of :mod:`bpms.gui.plot_data`.

- :class:`PlotWindow`: a top-level pyqtgraph window, one curve per selected cell (or joint
  angle), labelled IMU name + quantity + unit. The legend sits beside the data and folds away
  (Legend); a click on a name hides/shows its curve; left-drag zooms a rectangle; right-click
  opens pyqtgraph's menu ("View All"); double-click resets the view; Pause (Space) freezes the
  drawing (the history keeps filling); Lock y keeps each plot's y range as it is. Data that
  is not live is veiled (``stale``, :mod:`bpms.gui.stale`). Pens, axes and the legend:
  :mod:`bpms.gui.plot_style`; keys: :data:`bpms.gui.view3d_keys.PLOT_BINDINGS`.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import pyqtgraph as pg
from PyQt6.QtCore import QPointF, QSignalBlocker, Qt, pyqtSignal
from PyQt6.QtGui import QKeySequence, QShortcut
from PyQt6.QtWidgets import QApplication, QLabel, QVBoxLayout, QWidget

from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.gui.columns import COLUMNS, TEXT_GROUPS
from bpms.gui.drag import accept_drag, take_drop
from bpms.gui.plot_data import (
    CurveSpec,
    RingBuffer,
    TickBlock,
    cell_curve,
    group_by_unit,
    joint_angle_groups,
    joint_curve,
    peak_decimate,
)
from bpms.gui.plot_style import (
    MIN_DATA_WIDTH,
    RoomyAxis,
    SideLegend,
    curve_pen,
    curve_pens,
    fit_axis_title,
    style_axes,
)
from bpms.gui.stale import StaleOverlay
from bpms.gui.view3d_keys import PLOT_BINDINGS
from bpms.gui.widgets import button, label, row
from bpms.io.frames import FRAME_RATE_HZ, IMU_NAMES

#: The time axis of a following plot moves by this much at a time, s.
PAGE_S = 5.0
class PlotWindow(QWidget):
    """A live plot: ``groups`` of curves, one pyqtgraph plot (one y axis, one unit) per group,
    x axes linked. It lives in a dock of the main window (or stands alone).

    Feed it with :meth:`append` once per display tick; it redraws then, unless paused or
    hidden (a hidden plot keeps its history and redraws when shown). Table cells dropped on it
    are added (``cellsDropped(cells, self)`` lets the main window do it).
    """

    cellsDropped = pyqtSignal(list, object)
    jointsDropped = pyqtSignal(list, object)

    def __init__(self, title: str, groups: list[tuple[str, list[CurveSpec]]],
                 history_s: float = 60.0, parent: QWidget | None = None,
                 kind: str = "cells", columns: int = 1) -> None:
        super().__init__(parent)
        self.setWindowFlag(Qt.WindowType.Window)
        self.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        self.setWindowTitle(title)
        self.setAcceptDrops(True)
        self.kind = kind
        self.history_s = history_s
        self.capacity = max(1, round(history_s * FRAME_RATE_HZ))
        self.paused = False
        self.closed = False
        self.follow = True  # x range follows the newest data (until the user zooms or pans)
        self._x_end: float | None = None
        self._dirty = False
        self.redraws = 0  # (bench/gui.py)

        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        self.pause_button = button("Pause", tip="Freeze the drawing (the history keeps "
                                   "filling); Space", checkable=True)
        self.pause_button.toggled.connect(self.set_paused)
        self.follow_button = button("Follow", tip="The time axis follows the newest data "
                                    "(double-click the plot or View All turns it back on)",
                                    checkable=True, checked=True)
        self.follow_button.toggled.connect(self._follow_toggled)  # (bound: no cycle)
        self.lock_button = button("Lock y", tip="Keep each plot's y range as it is now (Follow "
                                  "and double-click no longer rescale it)", checkable=True)
        self.lock_button.toggled.connect(self.lock_y)
        self.legend_button = button("Legend", self._legend_chosen, "The curves' names beside "
                                    "the data: show or fold away", checkable=True, checked=True)
        self.legend_button.toggled.connect(self.show_legends)
        self.legend_auto = True  # fold the legends when the plot is too narrow for them
        hint = label(f"{history_s:g} s", wrap=False, style="color: #666",
                     tip=f"{history_s:g} s of history · drop table cells here to add them · "
                         "click a legend name to hide/show its curve")
        layout.addLayout(row(self.pause_button, self.follow_button, self.lock_button,
                             self.legend_button, hint, grow=hint))
        self.graphics = pg.GraphicsLayoutWidget()
        self.graphics.setBackground("w")
        self.graphics.setMinimumSize(150, 100)
        self.graphics.setAcceptDrops(False)  # drops land on this widget
        layout.addWidget(self.graphics)
        for binding in PLOT_BINDINGS:  # the keys of the F1 table (Space: pause)
            for key, _shift in binding.presses:
                QShortcut(QKeySequence(key), self, activated=getattr(self, binding.command))
        self.stale = StaleOverlay(self.graphics.viewport())

        self.specs: list[CurveSpec] = []
        self.plots: list[pg.PlotItem] = []
        self.legends: list[SideLegend] = []
        self.titles: list[tuple[str, str]] = []  # per plot: y-axis title, and its short form
        self.curves: list[pg.PlotCurveItem] = []
        self._plot_unit: dict[str, pg.PlotItem] = {}
        self.columns = max(1, columns)
        self.auto_columns = kind == "joints"  # the grid follows the plot's shape
        self.buffer = RingBuffer(self.capacity, 1)
        for group_title, specs in groups:
            plot = self._new_plot(group_title, specs[0].unit if specs else "")
            for spec in specs:
                self._add_curve(plot, spec)
        self._restyle()
        self.buffer = RingBuffer(self.capacity, 1 + len(self.specs))
        self._last_click = (0.0, QPointF())
        self.graphics.scene().sigMouseClicked.connect(self._clicked)

    # -- building ---------------------------------------------------------------------------
    def _new_plot(self, title: str, unit: str) -> pg.PlotItem:
        # The group's name goes on its y axis (a title row would take a fifth of a small
        # plot); the legend goes in the grid cell to the right of its plot.
        n = len(self.plots)
        row, col = n // self.columns, 2 * (n % self.columns)
        plot = self.graphics.addPlot(row=row, col=col, axisItems={
            "left": RoomyAxis("left"), "bottom": RoomyAxis("bottom")})
        self.legends.append(SideLegend(self.graphics.ci, plot, row, col + 1))
        self.legends[-1].show(self.legend_button.isChecked())
        style_axes(plot)
        if title:  # a group of the joint angles: its name over it, small
            plot.setTitle(title, size="8pt", color="k")
            plot.layout.setRowFixedHeight(0, 14)
        short = f"[{unit}]" if unit else ""
        self.titles.append((short, short))
        if short:
            plot.setLabel("left", short)
        plot.showGrid(x=True, y=True, alpha=0.25)
        plot.setClipToView(True)
        plot.setDownsampling(auto=True, mode="peak")
        box = plot.getViewBox()
        box.setMouseMode(pg.ViewBox.RectMode)
        box.sigRangeChangedManually.connect(self._manual_range)
        box.menu.viewAll.triggered.connect(self.reset_view)  # View All: follow again
        box.sigResized.connect(self._fit_titles)
        plot.enableAutoRange(axis="x", enable=False)
        if self.lock_button.isChecked():
            plot.enableAutoRange(axis="y", enable=False)
        if self.plots:
            plot.setXLink(self.plots[0])
        self.plots.append(plot)
        self._plot_unit.setdefault(unit, plot)
        self._time_axes()
        return plot

    def _time_axes(self) -> None:
        """Time labels only under the lowest plot of each column (the x axes are linked):
        no row of tick labels and titles between two stacked plots."""
        for n, plot in enumerate(self.plots):
            lowest = n + self.columns >= len(self.plots)
            axis = plot.getAxis("bottom")
            axis.setStyle(showValues=lowest)
            if lowest:
                plot.setLabel("bottom", "time [s]")
            else:
                plot.showLabel("bottom", False)

    def _fit_titles(self, *_args) -> None:
        for plot, (full, short) in zip(self.plots, self.titles, strict=True):
            if full:
                fit_axis_title(plot.getAxis("left"), full, short)

    def _add_curve(self, plot: pg.PlotItem, spec: CurveSpec) -> pg.PlotCurveItem:
        k = sum(1 for c in self.curves if c.getViewBox() is plot.getViewBox())
        # PlotCurveItem, not PlotDataItem: a history of ≤ 60 s × 50 Hz needs no
        # downsampling, and its setData costs a third.
        curve = pg.PlotCurveItem(name=spec.label, connect="finite", pen=curve_pen(k))
        plot.addItem(curve)
        self.curves.append(curve)
        self.specs.append(spec)
        return curve

    def add_cells(self, cells: Sequence[tuple[int, int]], angle_unit: str | None = None) -> int:
        """Add curves for table cells not shown yet (on the plot of their unit, a new plot for
        a new unit). Returns how many were added; their history starts now."""
        unit = angle_unit or next((s.unit for s in self.specs if s.cell
                                   and COLUMNS[s.cell[1]].group == "euler"), "deg")
        shown = {s.cell for s in self.specs}
        return self._add_specs([cell_curve(r, c, unit) for r, c in cells if (r, c) not in shown])

    def add_joints(self, joints: Sequence[int], angle_unit: str = "deg") -> int:
        """Add curves for joint angles not shown yet. Returns how many were added."""
        shown = {s.joint for s in self.specs}
        return self._add_specs([joint_curve(k, angle_unit) for k in joints if k not in shown])

    def _add_specs(self, new: list[CurveSpec]) -> int:
        if not new:
            return 0
        for spec in new:
            plot = self._plot_unit.get(spec.unit) or self._new_plot("", spec.unit)
            self._add_curve(plot, spec)
        self._restyle()
        old = self.buffer.view().copy()
        self.buffer = RingBuffer(self.capacity, 1 + len(self.specs))
        if len(old):
            rows = np.full((len(old), 1 + len(self.specs)), np.nan)
            rows[:, :old.shape[1]] = old
            self.buffer.extend(rows)
        self.redraw()
        return len(new)

    def _restyle(self) -> None:
        """Each subplot's pens from its curves' limbs (:func:`curve_pens`)."""
        for plot in self.plots:
            box = plot.getViewBox()
            mine = [(c, s) for c, s in zip(self.curves, self.specs, strict=True)
                    if c.getViewBox() is box]
            pens = curve_pens([s.cell[0] if s.cell else None for _, s in mine])
            for (curve, _), pen in zip(mine, pens, strict=True):
                curve.setPen(pen)

    def description(self) -> dict[str, Any]:
        """What a saved layout needs to re-create this plot: its curves, the locked y ranges
        (or None) and whether the legend is shown."""
        joints = self.kind == "joints"  # the 28 angles, plus any cells dropped on it
        described = {"kind": "joints" if joints else "cells", "title": self.windowTitle(),
                     "cells": [list(s.cell) for s in self.specs if s.cell is not None]}
        if not joints:
            described["joints"] = [s.joint for s in self.specs if s.joint is not None]
        return {**described,
                "y_lock": self.y_ranges() if self.lock_button.isChecked() else None,
                "legend": "auto" if self.legend_auto else self.legend_button.isChecked()}

    def apply_view(self, description: dict[str, Any]) -> None:
        """The view settings of a :meth:`description`: legend shown (or folded; "auto" when
        left to the plot's width), y ranges locked."""
        legend = description.get("legend", "auto")
        self.legend_auto = legend == "auto"
        if not self.legend_auto:
            self.show_legends(bool(legend))
        ranges = description.get("y_lock")
        if isinstance(ranges, list) and all(isinstance(r, list) and len(r) == 2
                                            for r in ranges):
            self.set_y_ranges(ranges)

    # -- drag and drop ------------------------------------------------------------------------
    def dragEnterEvent(self, event) -> None:
        accept_drag(event)

    dragMoveEvent = dragEnterEvent

    def dropEvent(self, event) -> None:
        # a listener (the main window) adds them; without one the plot does
        for items, signal, add in zip(take_drop(event), (self.cellsDropped, self.jointsDropped),
                                      (self.add_cells, self.add_joints), strict=True):
            if items and self.receivers(signal):
                signal.emit(items, self)
            elif items:
                add(items)

    # -- mouse --------------------------------------------------------------------------------
    def _clicked(self, event) -> None:
        if event.button() != Qt.MouseButton.LeftButton:
            return
        # A click on a legend's name toggles its curve (pyqtgraph only toggles on the swatch).
        for plot in self.plots:
            legend = plot.legend
            if legend is None:
                continue
            for sample, name in legend.items:
                if name.sceneBoundingRect().contains(event.scenePos()):
                    self.toggle_curve(sample.item)
                    return
        # A double click: pyqtgraph flags it, or (depending on the event sequence the platform
        # sends) two single clicks within the double-click interval.
        now, pos = time.monotonic(), event.screenPos()
        last_t, last_pos = self._last_click
        interval = QApplication.doubleClickInterval() / 1000.0
        near = abs(pos.x() - last_pos.x()) + abs(pos.y() - last_pos.y()) < 6
        if event.double() or (now - last_t < interval and near):
            self.reset_view()
            now = 0.0
        self._last_click = (now, pos)

    def toggle_curve(self, curve: pg.PlotCurveItem) -> None:
        """Hide or show ``curve``; its legend entry is greyed while hidden."""
        curve.setVisible(not curve.isVisible())
        for plot in self.plots:
            if plot.legend is None:
                continue
            for sample, name in plot.legend.items:
                if sample.item is curve:
                    name.setOpacity(1.0 if curve.isVisible() else 0.4)
                    sample.update()

    def reset_view(self) -> None:
        """Back to following the data: y auto-range (unless locked), x the newest history."""
        self.follow = True
        self._x_end = None
        with QSignalBlocker(self.follow_button):
            self.follow_button.setChecked(True)
        for plot in self.plots:
            if not self.lock_button.isChecked():
                plot.enableAutoRange(axis="y")
            plot.enableAutoRange(axis="x", enable=False)
        self.redraw()

    def lock_y(self, on: bool) -> None:
        """Keep every plot's y range as it is (on), or rescale to the data again (off)."""
        if self.lock_button.isChecked() != on:
            self.lock_button.setChecked(on)  # comes back here through toggled
            return
        for plot in self.plots:
            plot.enableAutoRange(axis="y", enable=not on)
            plot.setMouseEnabled(y=not on)
        self.redraw()

    def y_ranges(self) -> list[list[float]]:
        """Each plot's y range now, [[low, high], …]."""
        return [[float(v) for v in plot.getViewBox().viewRange()[1]] for plot in self.plots]

    def set_y_ranges(self, ranges: Sequence[Sequence[float]]) -> None:
        """Lock the plots' y ranges at ``ranges`` (as :meth:`y_ranges` gives them)."""
        for plot, (low, high) in zip(self.plots, ranges, strict=False):
            plot.setYRange(float(low), float(high), padding=0.0)
        self.lock_y(True)

    def show_legends(self, on: bool) -> None:
        """The legends beside the plots (on) or folded away (off)."""
        if self.legend_button.isChecked() != on:
            self.legend_button.setChecked(on)
            return
        for legend in self.legends:
            legend.show(on)

    def _legend_chosen(self, on: bool) -> None:
        """The user's choice (the Legend button) wins over the automatic folding."""
        self.legend_auto = False

    def legends_fit(self) -> bool:
        """Every column of plots keeps MIN_DATA_WIDTH beside its widest legend."""
        widest = [0] * self.columns
        for n, legend in enumerate(self.legends):
            widest[n % self.columns] = max(widest[n % self.columns], legend.width())
        return self.graphics.width() >= sum(w + MIN_DATA_WIDTH + 60 for w in widest)

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        if self.auto_columns:
            self.arrange(best_columns(len(self.plots), self.graphics.width(),
                                      self.graphics.height()))
        if self.legend_auto and self.legends:
            fit = self.legends_fit()
            if fit != self.legend_button.isChecked():
                self.show_legends(fit)

    def arrange(self, columns: int) -> None:
        """Lay the plots out in ``columns`` columns (each with its legend beside it)."""
        columns = max(1, columns)
        if columns == self.columns:
            return
        self.columns = columns
        grid = self.graphics.ci
        shown = [legend.shown for legend in self.legends]
        for plot, legend in zip(self.plots, self.legends, strict=True):
            grid.removeItem(plot)
            legend.show(False)
        for n, (plot, legend) in enumerate(zip(self.plots, self.legends, strict=True)):
            legend.row, legend.col = n // columns, 2 * (n % columns) + 1
            grid.addItem(plot, row=legend.row, col=legend.col - 1)
            legend.show(shown[n])
        self._time_axes()

    def toggle_pause(self) -> None:
        """Space: pause or resume the drawing."""
        self.pause_button.toggle()

    def _follow_toggled(self, on: bool) -> None:
        if on:
            self.reset_view()
        else:
            self._manual_range()

    def _manual_range(self, *_args) -> None:
        self.follow = False
        with QSignalBlocker(self.follow_button):
            self.follow_button.setChecked(False)

    def _follow_time(self, t: np.ndarray) -> None:
        # The time axis moves in pages of PAGE_S, not at every tick: redrawing an axis's
        # tick labels is the costliest part of a plot's paint (text rendering).
        if not self.follow or len(t) == 0:
            return
        page = min(PAGE_S, self.history_s / 4)
        end = float(np.ceil(t[-1] / page + 1e-9) * page)
        if end == self._x_end:
            return
        self._x_end = end
        start = max(float(np.floor(t[0])), end - self.history_s - page)
        for plot in self.plots:
            plot.setXRange(start, end, padding=0.0)

    def set_paused(self, paused: bool) -> None:
        self.paused = paused
        self.pause_button.setText("Resume" if paused else "Pause")
        if self.pause_button.isChecked() != paused:
            self.pause_button.setChecked(paused)
        if not paused:
            self.redraw()

    # -- data ---------------------------------------------------------------------------------
    def append(self, block: TickBlock) -> None:
        """Add one tick's data and redraw (unless paused or hidden). A jump back in time
        (seek, new stream) starts the history again."""
        if len(block.t) == 0:
            return
        if len(self.buffer) and block.t[0] < self.buffer.view()[-1, 0]:
            self.buffer.clear()
        rows = np.empty((len(block.t), 1 + len(self.specs)))
        rows[:, 0] = block.t
        for k, spec in enumerate(self.specs):
            rows[:, k + 1] = spec.values(block)
        self.buffer.extend(rows)
        if self.paused:
            return
        if self.isVisible():
            self.redraw()
        else:
            self._dirty = True

    def showEvent(self, event) -> None:
        super().showEvent(event)
        if self._dirty:
            self.redraw()

    def redraw(self) -> None:
        self._dirty = False
        self.redraws += 1
        data = self.buffer.view()
        self._follow_time(data[:, 0])
        if self.follow and self.plots:
            data = peak_decimate(data, int(self.plots[0].getViewBox().width()))
        t = data[:, 0]
        # Gaps (NaN) need the slower "finite" path; most of the time there are none.
        finite = bool(np.isfinite(data).all())
        connect = "all" if finite else "finite"
        for k, curve in enumerate(self.curves):
            curve.setData(t, data[:, k + 1], connect=connect, skipFiniteCheck=finite)

    def closeEvent(self, event) -> None:
        self.closed = True
        super().closeEvent(event)


#: Wide plots read best for time series: the grid's columns are chosen for cells about this
#: many times wider than high.
CELL_ASPECT = 2.5


def best_columns(n: int, width: int, height: int) -> int:
    """Columns (1, 2, 3 or n) for ``n`` plots in ``width`` × ``height`` px whose cells come
    nearest :data:`CELL_ASPECT`."""
    if n <= 1 or width <= 0 or height <= 0:
        return 1
    # the aspect of a cell in c columns (of -(-n // c) rows); a tie goes to fewer columns
    return min((c for c in sorted({1, 2, 3, n}) if c <= n),
               key=lambda c: abs(np.log((width / c) / (height / -(-n // c)) / CELL_ASPECT)))


class PlotDropArea(QLabel):
    """Empty space of the main window: table cells dropped here open a new plot
    (``cellsDropped(cells, None)``)."""

    cellsDropped = pyqtSignal(list, object)
    jointsDropped = pyqtSignal(list, object)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Drag table cells here for a new plot", parent)
        self.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.setAcceptDrops(True)
        self.setStyleSheet("color: #888; border: 1px dashed #bbb; margin: 2px")
        self.setMinimumHeight(28)

    def dragEnterEvent(self, event) -> None:
        accept_drag(event)

    dragMoveEvent = dragEnterEvent

    def dropEvent(self, event) -> None:
        cells, joints = take_drop(event)
        if cells:
            self.cellsDropped.emit(cells, None)
        if joints:
            self.jointsDropped.emit(joints, None)


def cells_plot(cells: list[tuple[int, int]], angle_unit: str = "deg",
               history_s: float = 60.0, number: int = 1) -> PlotWindow:
    """A plot of table cells (IMU, column): one y axis per unit."""
    specs = [cell_curve(imu, col, angle_unit) for imu, col in cells]
    return PlotWindow(f"Plot {number}", group_by_unit(specs), history_s)


def joint_angle_plot(angle_unit: str = "deg", history_s: float = 60.0) -> PlotWindow:
    """The 28 joint angles, grouped by joint (docs/body-model.md)."""
    window = PlotWindow("Joint angles", joint_angle_groups(angle_unit), history_s,
                        kind="joints", columns=2)
    window.resize(900, 900)
    return window


def plot_from(description: dict[str, Any], angle_unit: str = "deg",
              history_s: float = 60.0) -> PlotWindow | None:
    """The plot of :meth:`PlotWindow.description` (None when it describes nothing usable)."""
    cells = []
    for item in description.get("cells", []):
        try:
            r, c = int(item[0]), int(item[1])
        except (TypeError, ValueError, IndexError):
            continue
        if 0 <= r < len(IMU_NAMES) and 0 <= c < len(COLUMNS) \
                and COLUMNS[c].group not in TEXT_GROUPS:
            cells.append((r, c))
    if description.get("kind") == "joints":
        window = joint_angle_plot(angle_unit, history_s)
        if cells:
            window.add_cells(cells, angle_unit)
        window.apply_view(description)
        return window
    joints = [int(k) for k in description.get("joints", [])
              if isinstance(k, int) and 0 <= k < len(JOINT_ANGLE_NAMES)]
    if not cells and not joints:
        return None
    specs = [cell_curve(r, c, angle_unit) for r, c in cells] \
        + [joint_curve(k, angle_unit) for k in joints]
    window = PlotWindow(str(description.get("title", "Plot")), group_by_unit(specs), history_s)
    window.apply_view(description)
    return window
