"""The data table: values and units per column, deg/rad switch, Ctrl/Shift multi-selection."""

from __future__ import annotations

import numpy as np
from PyQt6.QtCore import Qt
from PyQt6.QtTest import QTest

from bpms.filter.calibration import SensorCalibration
from bpms.gui.data_table import COLUMNS, DataTable, ImuTableModel
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
    assert header[0] == "raw ax [counts]" and header[9] == "ax [m/s²]"
    assert header[12] == "mx [G]" and header[15] == "gx [rad/s]" and header[20] == "yaw [deg]"
    assert model.headerData(17, Qt.Orientation.Vertical) == "17 Head"
    acc, mag, gyr = calibration.physical_units(sample.raw)
    text = model.data(model.index(4, 9))
    assert text == f"{acc[4, 0]:.3f}"
    assert model.data(model.index(4, 12)) == f"{mag[4, 0]:.3f}"
    assert model.data(model.index(4, 17)) == f"{gyr[4, 2]:.3f}"
    assert model.data(model.index(4, 3)) == str(sample.raw[4, 3])
    assert model.data(model.index(2, 18)) == f"{np.degrees(sample.euler[2, 0]):.2f}"
    assert model.data(model.index(4, 21)) == "mag gyro" and model.data(model.index(5, 21)) == ""
    model.set_angle_unit("rad")
    assert model.data(model.index(2, 18)) == f"{sample.euler[2, 0]:.3f}"
    assert model.headerData(20, Qt.Orientation.Horizontal) == "yaw [rad]"


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

    click(0, 0)
    click(3, 18, Qt.KeyboardModifier.ControlModifier)
    click(5, 18, Qt.KeyboardModifier.ShiftModifier)
    assert table.selected_cells() == [(0, 0), (3, 18), (4, 18), (5, 18)]
    click(8, 21, Qt.KeyboardModifier.ControlModifier)  # error flags: not plottable
    assert (8, 21) not in table.selected_cells()
