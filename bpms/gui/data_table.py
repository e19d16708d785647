"""The standard data view: 18 IMUs (rows) × raw, calibrated, Euler and error-flag columns.

A model/view table: :class:`ImuTableModel` keeps the newest sample's numbers in numpy arrays
and announces one ``dataChanged`` per display tick; Qt asks for the visible cells only.
Calibrated values are :meth:`SensorCalibration.physical_units` (accel m/s², mag gauss,
gyro rad/s, signed board axes); Euler angles (rad or deg, switchable live) are by default the
processor's output angles (``PoseSample.euler_output``: segment angles after Reset Zero), or the
filter's sensor angles (``PoseSample.euler``) — the headers say which; the caller may pass
the continuous readout of them (:mod:`bpms.gui.angle_readout`), and roll and yaw near pitch
±90° are greyed with the reason in their tooltip. The disturbance column marks IMUs whose
magnetometer ("mag") or acceleration ("acc") is disturbed (:mod:`bpms.filter.disturbance`),
in amber, with how long each flag has been up (:mod:`bpms.gui.disturbance_view`).

Every column is as wide as its header in bold (the header of a selected cell's column is
drawn bold) and its widest possible cell (:data:`WIDEST`), so neither is ever cut.
"""

from __future__ import annotations

import time

import numpy as np
from PyQt6.QtCore import QAbstractTableModel, QMimeData, QModelIndex, Qt, pyqtSignal
from PyQt6.QtGui import QColor, QFont, QFontMetrics
from PyQt6.QtWidgets import QAbstractItemView, QHeaderView, QStyle, QTableView, QWidget

from bpms.filter.calibration import SensorCalibration
from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.gui.angle_readout import poorly_defined
from bpms.gui.columns import (
    COLUMNS,
    TEXT_GROUPS,
    calibrated,
    column_values,
    human_joint_name,
    shown_angles,
)
from bpms.gui.disturbance_view import FlagAges
from bpms.gui.drag import CELLS_MIME, JOINTS_MIME, cells_to_mime, joints_to_mime
from bpms.gui.stale import StaleOverlay
from bpms.io.frames import IMU_NAMES, N_IMUS, SENSOR_NAMES
from bpms.pipeline.session import PoseSample

#: Error flags stay red at least this long after the last faulty frame, s.
ERROR_HOLD_S = 2.0


def error_text(flags: np.ndarray) -> str:
    """``[3]`` bool flags (accel, mag, gyro) → "" or e.g. "mag gyro"."""
    return " ".join(name for name, bad in zip(SENSOR_NAMES, flags, strict=True) if bad)


_DISPLAY = Qt.ItemDataRole.DisplayRole
_ALIGN = Qt.ItemDataRole.TextAlignmentRole
_FOREGROUND = Qt.ItemDataRole.ForegroundRole
_RIGHT = Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter
_BACKGROUND = Qt.ItemDataRole.BackgroundRole
_TOOLTIP = Qt.ItemDataRole.ToolTipRole
_RED = QColor("#d62728")
_AMBER = QColor("#c77c00")  # amber, dark enough to read on white
_VAGUE = QColor("#8a8a8a")  # roll / yaw near pitch ±90°
_FAILED_ROW = QColor("#fde0e0")
VAGUE_TIP = ("pitch is near ±90°: roll and yaw are poorly defined here (only their sum or "
             "difference is) and may sweep quickly; the joint angles read right")
_ERRORS_COLUMN = next(k for k, c in enumerate(COLUMNS) if c.group == "errors")
DISTURBANCE_COLUMN = next(k for k, c in enumerate(COLUMNS) if c.group == "disturbance")
_ROLL_YAW = {k for k, c in enumerate(COLUMNS) if c.group == "euler" and c.k in (0, 2)}
#: The widest text each column group can show (numbers at their extremes: the continuous
#: angles pass ±180°, accelerations reach ±16 g, raw counts ±32768, hours-long flags).
WIDEST = {"euler": ("-9999.99", "-99.999"), "raw": ("-32768",), "cal": ("-156.906",),
          "est": ("-156.9060",), "errors": ("accel mag gyro",),
          "disturbance": ("mag 59 min 999 %, acc 59 min 9.9 g",)}


class _DragModel(QAbstractTableModel):
    """A flat table of ``SHAPE`` (rows, columns) whose cells drag as ``MIME``."""

    SHAPE = (0, 0)
    MIME = ""

    def rowCount(self, parent: QModelIndex = QModelIndex()) -> int:  # noqa: B008
        return 0 if parent.isValid() else self.SHAPE[0]

    def columnCount(self, parent: QModelIndex = QModelIndex()) -> int:  # noqa: B008
        return 0 if parent.isValid() else self.SHAPE[1]

    def mimeTypes(self) -> list[str]:
        return [self.MIME]


def _drag_view(view: QTableView, model: _DragModel,
               behaviour: QAbstractItemView.SelectionBehavior) -> StaleOverlay:
    """``view`` showing ``model`` read-only, selecting ``behaviour`` (cells or rows), dragging
    onto plots; returns the veil over its cells while the data is not live."""
    view.setModel(model)
    view.setSelectionMode(QAbstractItemView.SelectionMode.ExtendedSelection)
    view.setSelectionBehavior(behaviour)
    view.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
    view.setDragEnabled(True)
    view.setDragDropMode(QAbstractItemView.DragDropMode.DragOnly)
    view.setAlternatingRowColors(True)
    view.verticalHeader().setDefaultSectionSize(22)
    return StaleOverlay(view.viewport())


class ImuTableModel(_DragModel):
    """Numbers of the newest sample; refreshed by :meth:`update` once per display tick."""

    SHAPE = (N_IMUS, len(COLUMNS))
    MIME = CELLS_MIME

    def __init__(self, calibration: SensorCalibration, angle_unit: str = "deg",
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.calibration = calibration
        self.angle_unit = angle_unit
        self.raw = np.zeros((N_IMUS, 9), np.int16)
        self.cal = np.full((N_IMUS, 9), np.nan)
        self.euler = np.full((N_IMUS, 3), np.nan)
        self.errors = np.zeros((N_IMUS, 3), bool)
        self.error_until = np.zeros((N_IMUS, 3))  # monotonic s until which a flag stays red
        self.mag_disturbed = np.zeros(N_IMUS, bool)
        self.est = np.full((N_IMUS, 6), np.nan)
        self.acc_disturbed = np.zeros(N_IMUS, bool)
        self.flag_ages = FlagAges()
        self.vague = np.zeros(N_IMUS, bool)  # roll and yaw poorly defined (pitch near ±90°)
        #: show the output angles (segment angles after Reset Zero) rather than the sensor's
        self.show_output = True
        #: what the Euler columns hold now: "segment" or "sensor"
        self.angles_kind = "sensor"
        self.has_data = False
        self._text: list[list[str]] = []

    # -- updates ------------------------------------------------------------------------
    def update(self, sample: PoseSample, errors: np.ndarray | None = None,
               now: float | None = None, euler: np.ndarray | None = None) -> None:
        """Show ``sample`` (one ``dataChanged`` for the whole table). ``errors [18, 3]``: the
        flags of every frame since the last update (default: this sample's); a flag stays
        shown for :data:`ERROR_HOLD_S` after the last frame that raised it. ``euler
        [18, 3]`` rad: the angles to show instead of the sample's (the continuous readout
        of the same angles, :mod:`bpms.gui.angle_readout`)."""
        now = time.monotonic() if now is None else now
        flags = sample.errors if errors is None else errors
        self.error_until[flags] = now + ERROR_HOLD_S
        self.raw = sample.raw
        self.cal = calibrated(self.calibration, sample.raw)
        self.euler, kind = shown_angles(sample, self.show_output)
        if euler is not None:
            self.euler = np.asarray(euler, np.float64)
        self.vague = poorly_defined(self.euler[:, 1])
        if kind != self.angles_kind:
            self.angles_kind = kind
            self.headerDataChanged.emit(Qt.Orientation.Horizontal, 0, len(COLUMNS) - 1)
        none = np.zeros(N_IMUS, bool)
        self.est = (np.full((N_IMUS, 6), np.nan) if sample.estimates is None
                    else sample.estimates)
        self.mag_disturbed = none if sample.mag_disturbed is None else sample.mag_disturbed
        self.acc_disturbed = none if sample.acc_disturbed is None else sample.acc_disturbed
        self.flag_ages.update(sample.index, self.mag_disturbed, self.acc_disturbed,
                              sample.mag_strength, sample.mag_heading_deg,
                              sample.acc_strength)
        self.errors = self.error_until > now
        self.has_data = True
        self._format()
        self.dataChanged.emit(self.index(0, 0), self.index(N_IMUS - 1, len(COLUMNS) - 1))

    def _format(self) -> None:
        # All 18 × 22 strings once per tick: Qt then asks for each visible cell (several
        # roles each), and a list lookup keeps those calls cheap.
        deg = self.angle_unit == "deg"
        euler = np.degrees(self.euler) if deg else self.euler
        efmt = "{:.2f}" if deg else "{:.3f}"
        rows = []
        for i in range(N_IMUS):
            raw = [str(v) for v in self.raw[i].tolist()]
            cal = ["–" if v != v else f"{v:.3f}" for v in self.cal[i].tolist()]
            eul = ["–" if v != v else efmt.format(v) for v in euler[i].tolist()]
            dist = self.flag_ages.text(i)
            est = ["–" if v != v else f"{v:.4f}" for v in self.est[i].tolist()]
            rows.append([*eul, error_text(self.errors[i]), *cal, *raw, dist, *est])
        self._text = rows

    def set_show_output(self, on: bool) -> None:
        """True: the output angles (after Reset Zero); False: the sensor angles (from the
        next sample on)."""
        self.show_output = bool(on)

    def set_angle_unit(self, unit: str) -> None:
        """"deg" or "rad": Euler cells and headers change at once."""
        if unit not in ("deg", "rad"):
            raise ValueError(f"angle unit must be 'deg' or 'rad', not {unit!r}")
        self.angle_unit = unit
        if self.has_data:
            self._format()
        self.headerDataChanged.emit(Qt.Orientation.Horizontal, 0, len(COLUMNS) - 1)
        self.dataChanged.emit(self.index(0, 0), self.index(N_IMUS - 1, len(COLUMNS) - 1))

    # -- QAbstractTableModel --------------------------------------------------------------
    def value(self, row: int, col: int) -> float | str:
        """The number (in the header's unit) or text shown at ``row, col``."""
        column = COLUMNS[col]
        if column.group == "errors":
            return error_text(self.errors[row])
        if column.group == "disturbance":
            return self.flag_ages.text(row)
        value = column_values(column, self.raw[row], self.cal[row], self.euler[row],
                              self.angle_unit == "deg", self.est[row])
        return int(value) if column.group == "raw" else float(value)

    def data(self, index: QModelIndex, role: int = _DISPLAY):
        if role == _DISPLAY:
            return self._text[index.row()][index.column()] if self.has_data else ""
        if role == _ALIGN:
            return _RIGHT
        if role == _FOREGROUND and index.column() == _ERRORS_COLUMN:
            return _RED
        if role == _FOREGROUND and index.column() == DISTURBANCE_COLUMN:
            return _AMBER
        if index.column() in _ROLL_YAW and self.vague[index.row()] and self.has_data:
            if role == _FOREGROUND:
                return _VAGUE
            if role == _TOOLTIP:
                return VAGUE_TIP
        if role == _TOOLTIP and index.column() == DISTURBANCE_COLUMN:
            return self.flag_ages.tooltip(index.row()) or None
        if role == _BACKGROUND and self.errors[index.row()].any():
            return _FAILED_ROW  # a failed sensor: the IMU's whole row
        return None

    def flags(self, index: QModelIndex) -> Qt.ItemFlag:
        base = super().flags(index)
        if index.isValid() and COLUMNS[index.column()].group not in TEXT_GROUPS:
            base |= Qt.ItemFlag.ItemIsDragEnabled
        return base

    def mimeData(self, indexes) -> QMimeData:
        """Dragged cells (onto a plot, or onto empty space for a new plot)."""
        cells = sorted({(i.row(), i.column()) for i in indexes
                        if COLUMNS[i.column()].group not in TEXT_GROUPS})
        return cells_to_mime(cells)

    def headerData(self, section: int, orientation: Qt.Orientation,
                   role: int = Qt.ItemDataRole.DisplayRole):
        if role != Qt.ItemDataRole.DisplayRole:
            return None
        if orientation == Qt.Orientation.Horizontal:
            column = COLUMNS[section]
            if column.group == "euler":  # which angles: after Reset Zero or the sensor's
                return f"{column.name} ({self.angles_kind}) [{self.angle_unit}]"
            return column.label(self.angle_unit)
        return f"{section} {IMU_NAMES[section]}"


class DataTable(QTableView):
    """The table view: multi-cell selection (click, Ctrl+click, Shift+click, drag to select);
    dragging selected cells carries them to a plot (or to empty space for a new plot)."""

    #: (cells, None): cells to plot in a new plot (emitted by the main window's drop area).
    plotRequested = pyqtSignal(list, object)

    def __init__(self, model: ImuTableModel, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.stale = _drag_view(self, model, QAbstractItemView.SelectionBehavior.SelectItems)
        self.setDefaultDropAction(Qt.DropAction.CopyAction)
        self.setWordWrap(False)
        header = self.horizontalHeader()
        header.setSectionResizeMode(QHeaderView.ResizeMode.Interactive)
        self.fit_columns()
        header.moveSection(header.visualIndex(DISTURBANCE_COLUMN), _ERRORS_COLUMN + 1)
        # a bound method (PyQt holds it weakly): no reference cycle through the model, so the
        # table goes when its last reference does, never in a garbage collection that may run
        # while Qt delivers an event to it (issue 46.6: a crash in StaleOverlay.eventFilter)
        model.headerDataChanged.connect(self._headers_changed)

    def _headers_changed(self, *_args) -> None:
        self.fit_columns()

    def column_width(self, col: int) -> int:
        """Pixels for column ``col``: its header in bold (a selected cell's column header is
        drawn bold) and its widest possible cell, each with the style's margins."""
        header = self.horizontalHeader()
        bold = QFont(header.font())
        bold.setBold(True)
        text = str(self.model().headerData(col, Qt.Orientation.Horizontal))
        margin = self.style().pixelMetric(QStyle.PixelMetric.PM_HeaderMargin, None, header)
        head = QFontMetrics(bold).horizontalAdvance(text) + 2 * margin + 4
        cells = QFontMetrics(self.font())
        cell_margin = self.style().pixelMetric(QStyle.PixelMetric.PM_FocusFrameHMargin,
                                               None, self) + 1
        widest = max(cells.horizontalAdvance(t) for t in WIDEST[COLUMNS[col].group])
        return max(head, widest + 2 * cell_margin + 6)

    def fit_columns(self) -> None:
        """Every column wide enough for its header and its widest cell (headers change with
        the angle unit and with what the angles are)."""
        header = self.horizontalHeader()
        for col in range(len(COLUMNS)):
            width = self.column_width(col)
            if header.sectionSize(col) < width:
                header.resizeSection(col, width)

    def table_model(self) -> ImuTableModel:
        model = self.model()
        assert isinstance(model, ImuTableModel)
        return model

    def selected_cells(self) -> list[tuple[int, int]]:
        """(row = IMU id, column) of the selected numeric cells, in table order."""
        cells = {(i.row(), i.column()) for i in self.selectionModel().selectedIndexes()}
        return sorted(c for c in cells if COLUMNS[c[1]].group not in TEXT_GROUPS)

    def select_cells(self, cells: list[tuple[int, int]]) -> None:
        """Select exactly ``cells`` (as Ctrl+clicks would)."""
        from PyQt6.QtCore import QItemSelectionModel

        sel = self.selectionModel()
        sel.clearSelection()
        flag = QItemSelectionModel.SelectionFlag.Select
        for row, col in cells:
            sel.select(self.model().index(row, col), flag)


class JointAngleModel(_DragModel):
    """The 28 joint angles of the newest sample: readable name, value in deg or rad.
    Rows drag as joint angles onto plots."""

    SHAPE = (len(JOINT_ANGLE_NAMES), 2)
    MIME = JOINTS_MIME

    def __init__(self, angle_unit: str = "deg", parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.names = [human_joint_name(n) for n in JOINT_ANGLE_NAMES]
        self.angle_unit = angle_unit
        self.values = np.full(len(self.names), np.nan)  # rad
        self._text = ["" for _ in self.names]

    def update(self, sample: PoseSample) -> None:
        self.values = np.asarray(sample.joint_angles, dtype=np.float64)
        self._format()
        self.dataChanged.emit(self.index(0, 1), self.index(len(self.names) - 1, 1))

    def _format(self) -> None:
        deg = self.angle_unit == "deg"
        shown = np.degrees(self.values) if deg else self.values
        fmt = "{:.1f}" if deg else "{:.3f}"
        self._text = ["–" if v != v else fmt.format(v) for v in shown.tolist()]

    def set_angle_unit(self, unit: str) -> None:
        self.angle_unit = unit
        self._format()
        self.headerDataChanged.emit(Qt.Orientation.Horizontal, 1, 1)
        self.dataChanged.emit(self.index(0, 1), self.index(len(self.names) - 1, 1))

    def data(self, index: QModelIndex, role: int = _DISPLAY):
        if role == _DISPLAY:
            return self.names[index.row()] if index.column() == 0 else self._text[index.row()]
        if role == _ALIGN and index.column() == 1:
            return _RIGHT
        return None

    def headerData(self, section: int, orientation: Qt.Orientation,
                   role: int = Qt.ItemDataRole.DisplayRole):
        if role != Qt.ItemDataRole.DisplayRole or orientation != Qt.Orientation.Horizontal:
            return None
        return "joint angle" if section == 0 else f"value [{self.angle_unit}]"

    def flags(self, index: QModelIndex) -> Qt.ItemFlag:
        return super().flags(index) | Qt.ItemFlag.ItemIsDragEnabled

    def mimeData(self, indexes) -> QMimeData:
        """Dragged joint angles (onto a plot, or onto empty space for a new plot)."""
        return joints_to_mime(sorted({i.row() for i in indexes}))


class JointTable(QTableView):
    """The joint-angle list: select rows, drag them onto a plot."""

    def __init__(self, model: JointAngleModel, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.stale = _drag_view(self, model, QAbstractItemView.SelectionBehavior.SelectRows)
        self.verticalHeader().setVisible(False)
        self.horizontalHeader().setStretchLastSection(True)
        self.setColumnWidth(0, 220)

    def selected_joints(self) -> list[int]:
        return sorted({i.row() for i in self.selectionModel().selectedIndexes()})
