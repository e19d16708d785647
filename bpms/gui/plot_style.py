"""How a plot reads: its curves' pens, its axes and its legend beside the data.

- :data:`PALETTE`: Okabe & Ito's eight colour-blind-safe colours (2008), ordered so that the
  first three — often roll, pitch, yaw — are the most distinct (blue, vermilion, black) and
  no two neighbours are alike; from the ninth curve on the colours repeat dashed, then dotted
  (:func:`curve_pen`). Lines are :data:`LINE_WIDTH` px. A plot of several limbs gives each
  limb its own colour, its quantities solid, dashed, dotted (:func:`curve_pens`): the hand,
  arm and forearm never share a hue.
- :func:`style_axes`: black axes and ticks, and no SI prefix: an angle axis stays in degrees
  (pyqtgraph would relabel a small range "(x0.001)" or "m[deg]").
- :class:`SideLegend`: the legend in its own column of the plot grid, beside the data, never
  over it; it folds away (and unfolds) as a whole.
- :func:`fit_axis_title`: a y-axis title that does not fit the axis's height is shortened to
  its unit, so titles of stacked plots never run into each other.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import pyqtgraph as pg
from PyQt6.QtCore import Qt
from PyQt6.QtGui import QFont, QFontMetrics
from PyQt6.QtWidgets import QGraphicsItem, QSizePolicy

PALETTE = ("#0072B2", "#D55E00", "#000000", "#009E73", "#E69F00", "#CC79A7", "#56B4E9",
           "#F0E442")
_STYLES = (Qt.PenStyle.SolidLine, Qt.PenStyle.DashLine, Qt.PenStyle.DotLine)


#: Curve width, px (1 px reads poorly beside a grid; wider costs more to draw).
LINE_WIDTH = 2


def curve_pen(k: int) -> Any:
    """The pen of the ``k``-th curve of one plot: the eight colours, then dashed, dotted."""
    colour = PALETTE[k % len(PALETTE)]
    style = _STYLES[(k // len(PALETTE)) % len(_STYLES)]
    return pg.mkPen(colour, width=LINE_WIDTH, style=style)


def curve_pens(limbs: Sequence[int | None]) -> list[Any]:
    """The pens of one plot's curves, given each curve's limb (IMU index, None for a curve
    of no limb). One limb or none: :func:`curve_pen` in order. Several: a colour per limb
    (in order of first appearance), its curves solid, dashed, dotted."""
    distinct = list(dict.fromkeys(limb for limb in limbs if limb is not None))
    if len(distinct) <= 1:
        return [curve_pen(k) for k in range(len(limbs))]
    pens: list[Any] = []
    count: dict[int, int] = {}
    for k, limb in enumerate(limbs):
        if limb is None:
            pens.append(curve_pen(len(distinct) + k))
            continue
        j = count.get(limb, 0)
        count[limb] = j + 1
        pens.append(pg.mkPen(PALETTE[distinct.index(limb) % len(PALETTE)], width=LINE_WIDTH,
                             style=_STYLES[j % len(_STYLES)]))
    return pens


#: Tick labels and axis titles, points: small plots keep room for their numbers.
AXIS_FONT_PT = 8


def style_axes(plot: pg.PlotItem) -> None:
    """Black axes, cached (text is the slowest thing to paint), without SI prefixes, tick
    labels in :data:`AXIS_FONT_PT`."""
    font = QFont()
    font.setPointSize(AXIS_FONT_PT)
    for name in ("left", "bottom"):
        axis = plot.getAxis(name)
        axis.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
        axis.setPen("k")
        axis.setTextPen("k")
        axis.setStyle(tickFont=font)
        axis.label.setFont(font)
        axis.enableAutoSIPrefix(False)


def fit_axis_title(axis: pg.AxisItem, title: str, short: str) -> None:
    """``title`` on the (vertical) axis when it fits its height, else ``short``."""
    metrics = QFontMetrics(axis.label.font())
    text = title if metrics.horizontalAdvance(title) + 8 <= axis.height() else short
    if axis.labelText != text:
        axis.setLabel(text)


#: A plot keeps at least this width beside its legend, px; narrower, the legends fold.
MIN_DATA_WIDTH = 220
_LEGEND_FONT_PT = 8


def legend_width(names: list[str]) -> int:
    """Pixels a legend of ``names`` needs beside its plot (swatch, spacing, longest name)."""
    font = QFont()
    font.setPointSize(_LEGEND_FONT_PT)
    metrics = QFontMetrics(font)
    return 50 + max((metrics.horizontalAdvance(n) for n in names), default=0)


class RoomyAxis(pg.AxisItem):
    """An axis whose tick labels never run into each other: pyqtgraph chooses the tick
    spacing from the axis's length alone (a 40-px axis gets ticks 13 px apart, labels 12 px
    high); this one widens the spacing until each label has room, dropping a finer level
    that has none."""

    def tickSpacing(self, minVal, maxVal, size):
        levels = super().tickSpacing(minVal, maxVal, size)
        span = abs(maxVal - minVal)
        if not levels or span == 0 or size <= 0:
            return levels
        metrics = QFontMetrics(self.style["tickFont"]) if self.style.get("tickFont") \
            else QFontMetrics(self.font())
        if self.orientation in ("left", "right"):
            room = 1.6 * metrics.height()
        else:
            widest = max(abs(minVal), abs(maxVal))
            room = metrics.horizontalAdvance(f"-{widest:.4g}") + 12
        per_value = size / span  # px per unit
        major, offset = levels[0]
        steps = (2.0, 2.5, 2.0)  # 1 → 2 → 5 → 10 …
        k = 0
        while major * per_value < room:
            major *= steps[k % 3]
            k += 1
        finer = [(s, o) for s, o in levels[1:] if s * per_value >= room and s < major]
        return [(major, offset), *finer]


class SideLegend:
    """The legend of ``plot``, in the cell right of it in ``grid`` (a pg GraphicsLayout)."""

    def __init__(self, grid: pg.GraphicsLayout, plot: pg.PlotItem, row: int, col: int) -> None:
        self.grid, self.row, self.col = grid, row, col
        self.item = pg.LegendItem(labelTextColor="k", brush=pg.mkBrush(255, 255, 255, 0),
                                  verSpacing=-6, labelTextSize=f"{_LEGEND_FONT_PT}pt")
        self.item.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
        # as tall as its names, at the top of its cell (not spread over the plot's height)
        self.item.setSizePolicy(QSizePolicy(QSizePolicy.Policy.Preferred,
                                            QSizePolicy.Policy.Maximum))
        plot.legend = self.item  # PlotItem.addItem(curve, name=…) adds it here
        self.shown = False
        self.show(True)

    def width(self) -> int:
        """What this legend needs beside its plot, px."""
        return legend_width([label.text for _sample, label in self.item.items])

    def show(self, on: bool) -> None:
        """Beside the plot (True) or folded away (False)."""
        if on == self.shown:
            return
        self.shown = on
        if on:
            self.grid.addItem(self.item, row=self.row, col=self.col)
            self.grid.layout.setAlignment(self.item, Qt.AlignmentFlag.AlignTop
                                          | Qt.AlignmentFlag.AlignLeft)
            self.item.show()
        else:
            self.grid.removeItem(self.item)
            self.item.hide()
