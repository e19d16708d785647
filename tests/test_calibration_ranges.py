"""Calibration values outside the sensors' physical ranges are refused per IMU (issue 26.4):
that IMU gets its factory record and a warning, as NaN does; every other IMU keeps its
values. The bounds below are written from the data sheets (docs/configuration.md), not
read from the code."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from bpms.io.calib_file import CalibrationTable, checked, parse_legacy

ROOT = Path(__file__).resolve().parents[1]


def factory_rows() -> np.ndarray:
    """Table 2.2 from the shipped CSV (the dissertation's numbers), read with csv only."""
    with open(ROOT / "calib" / "calibration-table-2.2.csv", newline="") as f:
        rows = list(csv.reader(f))
    return np.array([[float(v) for v in r[2:]] for r in rows[1:]])


def legacy_text(values: np.ndarray) -> str:
    return ";\n".join(",".join(repr(float(v)) for v in row) for row in values) + "\n"


FIELD = {name: k for k, name in enumerate((
    "Gravity", "AxMin", "AxMax", "AyMin", "AyMax", "AzMin", "AzMax", "MxMin", "MxMax", "MyMin",
    "MyMax", "MzMin", "MzMax", "GxAvg", "GyAvg", "GzAvg"))}

# (field, value, refused?): just inside and just outside each data-sheet bound.
CASES = [
    ("Gravity", 1e-300, True),  # the example
    ("Gravity", 0.2, True),
    ("Gravity", 231.0, False),  # ADXL345 minimum sensitivity 230 counts/g
    ("Gravity", 305.0, False),  # maximum 282 + 10 %
    ("Gravity", 320.0, True),
    ("GxAvg", 30000.0, True),  # the example: ±30,000 counts
    ("GzAvg", -30000.0, True),
    ("GyAvg", 560.0, False),  # ITG-3200 zero-rate output ±40 °/s = ±575 counts
    ("GyAvg", -600.0, True),
    ("MxMax", 2040.0, False),  # HMC5883L 12 bits: up to 2047
    ("MxMax", 3000.0, True),
    ("MyMin", -5000.0, True),
]


@pytest.mark.parametrize(("field", "value", "refused"), CASES)
def test_one_absurd_value_costs_only_that_imu(field, value, refused):
    truth = factory_rows()
    values = truth.copy()
    values[:, FIELD["GxAvg"]] += 3.0  # a user's table: differs from the factory everywhere
    values[7, FIELD[field]] = value
    table = parse_legacy(legacy_text(values), "user.cfg")
    others = [i for i in range(18) if i != 7]
    np.testing.assert_array_equal(table.values[others], values[others])
    if refused:
        np.testing.assert_array_equal(table.values[7], truth[7])
        assert len(table.problems) == 1
        text = str(table.problems[0])
        assert "IMU 7" in text and "factory values used for IMU 7" in text
    else:
        np.testing.assert_array_equal(table.values[7], values[7])
        assert table.problems == []


def test_narrow_or_offset_axes_are_refused():
    """An accelerometer half-range that is not 1 g, an offset beyond the chip's 0 g offset,
    a magnetometer range no Earth field can give."""
    truth = factory_rows()
    values = truth.copy()
    values[2, FIELD["AxMin"]], values[2, FIELD["AxMax"]] = -2.0, 2.0  # 1 g = 2 counts?
    values[3, FIELD["AyMin"]], values[3, FIELD["AyMax"]] = -160.0, 360.0  # offset 100
    values[4, FIELD["MzMin"]], values[4, FIELD["MzMax"]] = -20.0, 20.0  # field = 20 counts
    table = parse_legacy(legacy_text(values), "user.cfg")
    np.testing.assert_array_equal(table.values[[2, 3, 4]], truth[[2, 3, 4]])
    assert [p.where.split(" (")[0] for p in table.problems] == ["IMU 2", "IMU 3", "IMU 4"]


def test_a_table_handed_over_in_memory_goes_through_the_same_check():
    """The door every table passes (recording headers, the Python API)."""
    truth = factory_rows()
    values = truth.copy()
    values[11, FIELD["Gravity"]] = 1e-300
    out = checked(CalibrationTable(values, source="header"))
    np.testing.assert_array_equal(out.values[11], truth[11])
    assert [p.where for p in out.problems] == ["IMU 11 field 1 (Gravity)"]


def test_the_factory_table_is_inside_every_range():
    table = parse_legacy(legacy_text(factory_rows()), "factory.cfg")
    assert table.problems == []
