"""Live plot windows: numpy ring buffers redrawn on the session model's display timer.

- :class:`TickBlock`: the samples of one display tick as arrays (built once per tick, shared by
  every plot window);
- :class:`RingBuffer`: a fixed-capacity history (``Options.display.plot_history_s`` × 50 Hz)
  whose newest ``n`` rows are always one contiguous numpy view (no copy to draw);
- :class:`PlotWindow`: a top-level pyqtgraph window, one curve per selected cell (or joint
  angle), labelled IMU name + quantity + unit. Legend click hides/shows a curve; left-drag
  zooms a rectangle; right-click opens pyqtgraph's menu ("View All"); double-click resets the
  view; Pause freezes the drawing (the history keeps filling).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pyqtgraph as pg
from PyQt6.QtCore import QPointF, Qt
from PyQt6.QtGui import QKeySequence, QShortcut
from PyQt6.QtWidgets import (
    QApplication,
    QGraphicsItem,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from bpms.filter.calibration import SensorCalibration
from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.gui.data_table import COLUMNS, calibrated, column_values
from bpms.io.frames import FRAME_PERIOD_S, FRAME_RATE_HZ, IMU_NAMES
from bpms.pipeline.session import PoseSample

#: The time axis of a following plot moves by this much at a time, s.
PAGE_S = 5.0


@dataclass
class TickBlock:
    """One tick's samples as arrays: t ``[n]`` s (frame index × 20 ms), raw ``[n, 18, 9]``
    counts, cal ``[n, 18, 9]`` (m/s², gauss, rad/s), euler ``[n, 18, 3]`` rad,
    joint_angles ``[n, 28]`` rad."""

    t: np.ndarray
    raw: np.ndarray
    cal: np.ndarray
    euler: np.ndarray
    joint_angles: np.ndarray

    @classmethod
    def from_samples(cls, samples: Sequence[PoseSample],
                     calibration: SensorCalibration) -> TickBlock:
        raw = np.array([s.raw for s in samples])
        return cls(
            t=np.array([s.index for s in samples], np.float64) * FRAME_PERIOD_S,
            raw=raw,
            cal=calibrated(calibration, raw),
            euler=np.array([s.euler for s in samples]),
            joint_angles=np.array([s.joint_angles for s in samples]),
        )


class RingBuffer:
    """The newest ``capacity`` rows of ``width`` float64 values.

    Every row is written twice (at ``i`` and ``i + capacity``) so :meth:`view` is a contiguous
    slice, oldest first, without copying.
    """

    def __init__(self, capacity: int, width: int) -> None:
        if capacity < 1:
            raise ValueError("capacity must be ≥ 1")
        self.capacity = capacity
        self._data = np.full((2 * capacity, width), np.nan)
        self._head = 0  # next write position in [0, capacity)
        self._count = 0

    def __len__(self) -> int:
        return self._count

    def clear(self) -> None:
        self._head = 0
        self._count = 0

    def extend(self, rows: np.ndarray) -> None:
        """Append ``rows [n, width]`` (only the newest ``capacity`` are kept)."""
        rows = np.asarray(rows, np.float64)[-self.capacity:]
        n = len(rows)
        if n == 0:
            return
        cap = self.capacity
        first = min(n, cap - self._head)
        for offset in (0, cap):
            self._data[self._head + offset:self._head + offset + first] = rows[:first]
            self._data[offset:offset + n - first] = rows[first:]
        self._head = (self._head + n) % cap
        self._count = min(cap, self._count + n)

    def view(self) -> np.ndarray:
        """``[len, width]`` rows, oldest first (a view: copy it to keep it)."""
        end = self._head + self.capacity
        return self._data[end - self._count:end]


@dataclass(frozen=True)
class CurveSpec:
    """A curve: its legend label (with unit) and how to take its values from a block."""

    label: str
    values: Callable[[TickBlock], np.ndarray]


def cell_curve(imu: int, col: int, angle_unit: str = "deg") -> CurveSpec:
    """The curve of table cell (IMU ``imu``, column ``col``)."""
    column = COLUMNS[col]
    degrees = angle_unit == "deg"
    unit = angle_unit if column.group == "euler" else column.unit
    label = f"{IMU_NAMES[imu]} {column.name} [{unit}]"
    return CurveSpec(label, lambda b: column_values(column, b.raw, b.cal, b.euler,
                                                    degrees)[:, imu])


def _joint_curve(k: int, degrees: bool) -> CurveSpec:
    unit = "deg" if degrees else "rad"
    return CurveSpec(f"{JOINT_ANGLE_NAMES[k]} [{unit}]",
                     lambda b: np.degrees(b.joint_angles[:, k]) if degrees
                     else b.joint_angles[:, k])


#: Groups of the joint-angle plot: (title, name prefixes).
JOINT_GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("Elbows and knees (flexion)", ("elbow_", "knee_")),
    ("Shoulders", ("shoulder_",)),
    ("Hips", ("hip_",)),
    ("Ankles", ("ankle_",)),
    ("Torso and head", ("torso.", "head.")),
)


def joint_angle_groups(angle_unit: str = "deg") -> list[tuple[str, list[CurveSpec]]]:
    """The 28 joint angles of ``JOINT_ANGLE_NAMES`` in :data:`JOINT_GROUPS`."""
    degrees = angle_unit == "deg"
    return [(title, [_joint_curve(k, degrees) for k, name in enumerate(JOINT_ANGLE_NAMES)
                     if name.startswith(prefixes)])
            for title, prefixes in JOINT_GROUPS]


class PlotWindow(QWidget):
    """A live plot window: ``groups`` of curves, one pyqtgraph plot per group.

    Feed it with :meth:`append` once per display tick; it redraws then (unless paused).
    """

    def __init__(self, title: str, groups: list[tuple[str, list[CurveSpec]]],
                 history_s: float = 60.0, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowFlag(Qt.WindowType.Window)
        self.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        self.setWindowTitle(title)
        self.specs = [spec for _, specs in groups for spec in specs]
        self.buffer = RingBuffer(max(1, round(history_s * FRAME_RATE_HZ)), 1 + len(self.specs))
        self.history_s = history_s
        self.paused = False
        self.closed = False
        self.follow = True  # x range follows the newest data (until the user zooms or pans)
        self._x_end: float | None = None

        layout = QVBoxLayout(self)
        bar = QHBoxLayout()
        self.pause_button = QPushButton("Pause")
        self.pause_button.setCheckable(True)
        self.pause_button.setToolTip("Freeze the drawing (the history keeps filling); Space")
        self.pause_button.toggled.connect(self.set_paused)
        bar.addWidget(self.pause_button)
        bar.addWidget(QLabel(f"history {history_s:g} s · legend click hides a curve · "
                             "drag to zoom · double-click or right-click ▸ View All resets"))
        bar.addStretch(1)
        layout.addLayout(bar)
        self.graphics = pg.GraphicsLayoutWidget()
        layout.addWidget(self.graphics)
        QShortcut(QKeySequence(Qt.Key.Key_Space), self, activated=self.pause_button.toggle)

        self.plots: list[pg.PlotItem] = []
        self.curves: list[pg.PlotCurveItem] = []
        n = len(self.specs)
        for row, (group_title, specs) in enumerate(groups):
            plot = self.graphics.addPlot(row=row, col=0, title=group_title or None)
            legend = plot.addLegend(offset=(5, 5))
            # Text is the slowest thing to paint: the legend and the axes are drawn once into
            # a pixmap and reused while the curves under them change.
            legend.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
            for name in ("left", "bottom"):
                plot.getAxis(name).setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
            plot.setLabel("bottom", "time", units="s")
            plot.getViewBox().setMouseMode(pg.ViewBox.RectMode)
            plot.getViewBox().sigRangeChangedManually.connect(self._manual_range)
            plot.enableAutoRange(axis="x", enable=False)
            for spec in specs:
                # PlotCurveItem, not PlotDataItem: a history of ≤ 60 s × 50 Hz needs no
                # downsampling, and its setData costs a third. Pens 1 px wide: wider ones are
                # much slower to draw.
                curve = pg.PlotCurveItem(
                    name=spec.label, connect="finite",
                    pen=pg.mkPen(pg.intColor(len(self.curves), hues=max(n, 6)), width=1))
                plot.addItem(curve)
                self.curves.append(curve)
            self.plots.append(plot)
        self._last_click = (0.0, QPointF())
        self.graphics.scene().sigMouseClicked.connect(self._clicked)

    def _clicked(self, event) -> None:
        # A double click: pyqtgraph flags it, or (depending on the event sequence the platform
        # sends) two single clicks within the double-click interval.
        if event.button() != Qt.MouseButton.LeftButton:
            return
        now, pos = time.monotonic(), event.screenPos()
        last_t, last_pos = self._last_click
        interval = QApplication.doubleClickInterval() / 1000.0
        near = abs(pos.x() - last_pos.x()) + abs(pos.y() - last_pos.y()) < 6
        if event.double() or (now - last_t < interval and near):
            self.reset_view()
            now = 0.0
        self._last_click = (now, pos)

    def reset_view(self) -> None:
        """Back to following the data: y auto-range, x the newest history."""
        self.follow = True
        self._x_end = None
        for plot in self.plots:
            plot.enableAutoRange(axis="y")
        self.redraw()

    def _manual_range(self, *_args) -> None:
        self.follow = False

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

    def append(self, block: TickBlock) -> None:
        """Add one tick's data and redraw (unless paused). A jump back in time (seek, new
        stream) starts the history again."""
        if len(block.t) == 0:
            return
        if len(self.buffer) and block.t[0] < self.buffer.view()[-1, 0]:
            self.buffer.clear()
        rows = np.empty((len(block.t), 1 + len(self.specs)))
        rows[:, 0] = block.t
        for k, spec in enumerate(self.specs):
            rows[:, k + 1] = spec.values(block)
        self.buffer.extend(rows)
        if not self.paused:
            self.redraw()

    def redraw(self) -> None:
        data = self.buffer.view()
        t = data[:, 0]
        self._follow_time(t)
        for k, curve in enumerate(self.curves):
            curve.setData(t, data[:, k + 1])

    def closeEvent(self, event) -> None:
        self.closed = True
        super().closeEvent(event)


def cells_plot(cells: list[tuple[int, int]], angle_unit: str = "deg",
               history_s: float = 60.0, number: int = 1) -> PlotWindow:
    """A plot window of table cells (IMU, column)."""
    specs = [cell_curve(imu, col, angle_unit) for imu, col in cells]
    return PlotWindow(f"BPMS plot {number}", [("", specs)], history_s)


def joint_angle_plot(angle_unit: str = "deg", history_s: float = 60.0) -> PlotWindow:
    """The 28 joint angles, grouped (docs/body-model.md)."""
    window = PlotWindow("BPMS joint angles", joint_angle_groups(angle_unit), history_s)
    window.resize(900, 900)
    return window
