"""The data table: values and units per column, deg/rad switch, Ctrl/Shift multi-selection."""

from __future__ import annotations

import numpy as np
from PyQt6.QtCore import Qt
from PyQt6.QtGui import QFont, QFontMetrics
from PyQt6.QtTest import QTest
from PyQt6.QtWidgets import QStyle

from bpms.filter.calibration import SensorCalibration
from bpms.gui.columns import COLUMNS
from bpms.gui.data_table import DISTURBANCE_COLUMN, DataTable, ImuTableModel
from bpms.io.calib_file import load_factory_calibration
from bpms.pipeline.session import PoseSample


def _sample() -> PoseSample:
    rng = np.random.default_rng(3)
    raw = rng.integers(-2000, 2000, (18, 9)).astype(np.int16)
    errors = np.zeros((18, 3), bool)
    errors[4, 1] = errors[4, 2] = True
    euler = rng.uniform(-3, 3, (18, 3))
    eye = np.broadcast_to(np.eye(3), (18, 3, 3))
    return PoseSample(7, 0.0, b"", raw, errors, euler, eye, eye, np.zeros(28),
                      np.zeros((21, 3)), 0.0)


def test_table_shows_raw_calibrated_euler_and_flags_with_units(qtbot):
    calibration = SensorCalibration.from_table(load_factory_calibration())
    model = ImuTableModel(calibration, "deg")
    table = DataTable(model)
    qtbot.addWidget(table)
    sample = _sample()
    model.update(sample)
    header = [model.headerData(c, Qt.Orientation.Horizontal) for c in range(len(COLUMNS))]
    # what matters first: angles, error flags, calibrated, raw
    assert header[:4] == ["roll (sensor) [deg]", "pitch (sensor) [deg]", "yaw (sensor) [deg]",
                          "errors"]
    assert header[4] == "acc x [m/s²]" and header[7] == "mag x [G]"
    assert header[10] == "gyro x [rad/s]" and header[13] == "raw acc x [counts]"
    assert model.headerData(17, Qt.Orientation.Vertical) == "17 Head"
    acc, mag, gyr = calibration.physical_units(sample.raw)
    assert model.data(model.index(4, 4)) == f"{acc[4, 0]:.3f}"
    assert model.data(model.index(4, 7)) == f"{mag[4, 0]:.3f}"
    assert model.data(model.index(4, 12)) == f"{gyr[4, 2]:.3f}"
    assert model.data(model.index(4, 16)) == str(sample.raw[4, 3])
    assert model.data(model.index(2, 0)) == f"{np.degrees(sample.euler[2, 0]):.2f}"
    assert model.data(model.index(4, 3)) == "mag gyro" and model.data(model.index(5, 3)) == ""
    model.set_angle_unit("rad")
    assert model.data(model.index(2, 0)) == f"{sample.euler[2, 0]:.3f}"
    assert model.headerData(2, Qt.Orientation.Horizontal) == "yaw (sensor) [rad]"
    _nothing_clipped(table)


def _nothing_clipped(table: DataTable) -> None:
    """Every header, in bold (as drawn when a cell of its column is selected), and every cell
    fits its column with the style's margins."""
    model = table.table_model()
    header = table.horizontalHeader()
    bold = QFont(header.font())
    bold.setBold(True)
    head_margin = table.style().pixelMetric(QStyle.PixelMetric.PM_HeaderMargin)
    cell_margin = table.style().pixelMetric(QStyle.PixelMetric.PM_FocusFrameHMargin) + 1
    for c in range(len(COLUMNS)):
        text = model.headerData(c, Qt.Orientation.Horizontal)
        assert QFontMetrics(bold).horizontalAdvance(text) + 2 * head_margin \
            <= table.columnWidth(c), text
        for r in range(18):
            cell = model.data(model.index(r, c))
            assert table.fontMetrics().horizontalAdvance(cell) + 2 * cell_margin \
                <= table.columnWidth(c), (text, cell)


def _extreme(index: int) -> PoseSample:
    """Counts at their limits, every error flag and both disturbance flags up."""
    base = _sample()
    raw = np.full((18, 9), -32768, np.int16)
    raw[::2] = 32767
    flags = np.ones(18, bool)
    return PoseSample(index, 0.0, b"", raw, np.ones((18, 3), bool), base.euler, base.R, base.C,
                      base.joint_angles, base.joint_positions, mag_disturbed=flags,
                      acc_disturbed=flags, estimates=np.full((18, 6), -156.906))


def test_no_header_or_cell_is_clipped_at_the_default_widths(qtbot):
    """Extreme values: every error flag, both disturbance flags up for 40 min, angles past
    ±180° (the continuous readout), counts at their limits, 16 g."""
    calibration = SensorCalibration.from_table(load_factory_calibration())
    for unit in ("deg", "rad"):
        model = ImuTableModel(calibration, unit)
        table = DataTable(model)
        qtbot.addWidget(table)
        base = _sample()
        model.update(_extreme(base.index), euler=np.full((18, 3), np.radians(-999.99)))
        later = _extreme(base.index + 40 * 60 * 50)
        model.update(later, euler=np.full((18, 3), np.radians(-999.99)))
        assert model.data(model.index(0, DISTURBANCE_COLUMN)) == "mag 40 min, acc 40 min"
        assert model.data(model.index(0, 3)) == "accel mag gyro"
        _nothing_clipped(table)
        for role in (True, False):  # the sensor angles' headers too
            model.set_show_output(role)
            model.update(later)
            _nothing_clipped(table)


def test_error_flags_are_red_held_two_seconds_and_colour_the_row(qtbot):
    model = ImuTableModel(SensorCalibration.from_table(load_factory_calibration()))
    faulty = _sample()
    eye = np.broadcast_to(np.eye(3), (18, 3, 3))
    clean = PoseSample(8, 0.0, b"", faulty.raw, np.zeros((18, 3), bool), faulty.euler, eye,
                       eye, np.zeros(28), np.zeros((21, 3)), 0.0)
    red = model.data(model.index(4, 3), Qt.ItemDataRole.ForegroundRole)
    assert red is not None and red.red() > 200 and red.green() < 80
    model.update(faulty, now=100.0)
    assert model.data(model.index(4, 3)) == "mag gyro"
    assert model.data(model.index(4, 0), Qt.ItemDataRole.BackgroundRole) is not None
    assert model.data(model.index(5, 0), Qt.ItemDataRole.BackgroundRole) is None
    model.update(clean, now=101.9)  # a clean frame 1.9 s later: still shown
    assert model.data(model.index(4, 3)) == "mag gyro"
    model.update(clean, now=102.1)  # 2.1 s after the last faulty frame: cleared
    assert model.data(model.index(4, 3)) == ""
    assert model.data(model.index(4, 0), Qt.ItemDataRole.BackgroundRole) is None
    # a fault in an earlier frame of the same tick counts too
    model.update(clean, errors=faulty.errors, now=103.0)
    assert model.data(model.index(4, 3)) == "mag gyro"


def test_ctrl_and_shift_click_select_several_cells(qtbot):
    model = ImuTableModel(SensorCalibration.from_table(load_factory_calibration()))
    table = DataTable(model)
    qtbot.addWidget(table)
    table.resize(1600, 600)
    table.show()
    qtbot.waitExposed(table)

    def click(row: int, col: int, mod=Qt.KeyboardModifier.NoModifier) -> None:
        rect = table.visualRect(model.index(row, col))
        QTest.mouseClick(table.viewport(), Qt.MouseButton.LeftButton, mod, rect.center())

    click(0, 13)
    click(3, 0, Qt.KeyboardModifier.ControlModifier)
    click(5, 0, Qt.KeyboardModifier.ShiftModifier)
    assert table.selected_cells() == [(0, 13), (3, 0), (4, 0), (5, 0)]
    click(8, 3, Qt.KeyboardModifier.ControlModifier)  # error flags: not plottable
    assert (8, 3) not in table.selected_cells()


def test_a_flag_shows_its_kind_since_when_and_how_strong(qtbot):
    # the strengths as the detector gives them (bpms.filter.disturbance): the field 35 % of the
    # earth's away from it with a 14° heading error, 0.3 g of linear acceleration
    model = ImuTableModel(SensorCalibration.from_table(load_factory_calibration()))
    base = _sample()
    up = np.zeros(18, bool)
    up[5] = True
    strength = np.zeros(18)
    strength[5] = 0.35
    heading = np.full(18, 14.0)
    lin = np.full(18, 0.3)
    for k in (0, 600):  # 12 s later: 601 frames up
        model.update(PoseSample(base.index + k, 0.0, b"", base.raw, base.errors, base.euler,
                                mag_disturbed=up, acc_disturbed=up, mag_strength=strength,
                                mag_heading_deg=heading, acc_strength=lin))
    assert model.data(model.index(5, DISTURBANCE_COLUMN)) == "mag 12 s 35 %, acc 12 s 0.3 g"
    tip = model.data(model.index(5, DISTURBANCE_COLUMN), Qt.ItemDataRole.ToolTipRole)
    assert "35 % of the earth's field" in tip and "14°" in tip and "0.3 g RMS" in tip
    assert model.data(model.index(4, DISTURBANCE_COLUMN)) == ""
