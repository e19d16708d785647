"""Calibration (Calib.cfg) and options files: round trips, factory values, bad files."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from bpms.io.calib_file import (
    FIELDS,
    format_legacy,
    load_calibration,
    load_factory_calibration,
    parse_legacy,
    save_legacy,
)
from bpms.io.options import Options, format_options, load_options, save_options
from bpms.io.paths import factory_options_path

TABLE_CSV = Path(__file__).resolve().parents[1] / "calib" / "calibration-table-2.2.csv"


def test_factory_calibration_is_table_2_2():
    rows = list(csv.DictReader(TABLE_CSV.open()))
    expected = np.array([[float(row[f]) for f in FIELDS] for row in rows])
    table = load_factory_calibration()
    np.testing.assert_array_equal(table.values, expected)
    assert table.problems == []


def test_legacy_round_trip(tmp_path):
    table = load_factory_calibration()
    table.values[4, 7] = -500.25
    path = tmp_path / "Calib.cfg"
    save_legacy(table, path)
    again = load_calibration(path)
    np.testing.assert_array_equal(again.values, table.values)
    assert again.problems == [] and again.source == str(path)


def test_legacy_single_line_form_is_read():
    table = load_factory_calibration()
    one_line = ";".join(",".join(str(v) for v in row) for row in table.values)
    np.testing.assert_allclose(parse_legacy(one_line).values, table.values)


def test_missing_calibration_falls_back_with_a_warning(tmp_path):
    table = load_calibration(tmp_path / "nope.cfg")
    np.testing.assert_array_equal(table.values, load_factory_calibration().values)
    assert len(table.problems) == 1
    assert "nope.cfg" in str(table.problems[0]) and "cannot be read" in str(table.problems[0])


@pytest.mark.parametrize(
    ("mutate", "where", "what"),
    [
        (lambda recs: recs[:17], "whole file", "holds 17 IMU records"),
        (lambda recs: [*recs[:3], recs[3].replace("-24.19666667", "abc", 1), *recs[4:]],
         "IMU 3 (line 4) field 14 (GxAvg)", "'abc' is not a number"),
        (lambda recs: [*recs[:5], ",".join(recs[5].split(",")[:15]), *recs[6:]],
         "IMU 5 (line 6)", "has 15 values"),
        (lambda recs: [*recs[:2], recs[2].replace("-269.0,268.0", "300.0,268.0", 1), *recs[3:]],
         "IMU 2 (line 3)", "AxMin ≥ AxMax"),
        (lambda recs: [*recs[:7], recs[7].replace("2.49", "nan", 1), *recs[8:]],
         "IMU 7 (line 8) field 14 (GxAvg)", "not a finite number"),
    ],
)
def test_bad_calibration_names_the_place_and_falls_back(tmp_path, mutate, where, what):
    records = format_legacy(load_factory_calibration()).rstrip().rstrip(";").split(";\n")
    path = tmp_path / "Calib.cfg"
    path.write_text(";\n".join(mutate(records)))
    table = load_calibration(path)
    assert len(table.problems) == 1
    problem = table.problems[0]
    assert problem.where == where and what in problem.message
    assert "factory" in problem.fallback
    np.testing.assert_array_equal(table.values, load_factory_calibration().values)


def test_truncated_binary_calibration_file(tmp_path):
    path = tmp_path / "Calib.cfg"
    path.write_bytes(b"\x00\xff\xfe garbage")
    table = load_calibration(path)
    assert table.problems and "records" in table.problems[0].message


def test_replace_one_imu_keeps_the_others():
    base = load_factory_calibration()
    new = base.copy()
    new.values[:] = 1.0
    merged = base.replace_imus(new, [6])
    assert (merged.values[6] == 1.0).all()
    np.testing.assert_array_equal(np.delete(merged.values, 6, 0), np.delete(base.values, 6, 0))


def test_shipped_options_are_the_factory_options():
    options = load_options(factory_options_path())
    assert options.problems == []
    assert options == Options()


def test_options_round_trip(tmp_path):
    options = Options()
    options.filter.kp_yaw = 0.5
    options.display.angle_unit = "rad"
    options.udp.forward_to = ["10.0.0.2:6000", "239.1.2.3:5005"]
    options.body.thigh = 0.45
    path = tmp_path / "options.toml"
    save_options(options, path)
    again = load_options(path)
    assert again == options and again.problems == []
    assert "# yaw proportional gain" in format_options(options)


@pytest.mark.parametrize(
    ("text", "where", "what"),
    [
        ("[filter]\nkp_yaw = 'fast'\n", "filter.kp_yaw", "not a number"),
        ("[filter]\nkp_yaw = -1.0\n", "filter.kp_yaw", "outside the valid range [0, 50]"),
        ("[display]\nangle_unit = 'grad'\n", "display.angle_unit", "not one of"),
        ("[sensors]\nmag_signs = [1, -1]\n", "sensors.mag_signs", "three signs"),
        ("[udp]\nforward_to = ['nowhere']\n", "udp.forward_to", "host:port"),
        ("[serial]\nbaud = 9600.5\n", "serial.baud", "whole number"),
        ("[filter]\nspeed = 3\n", "filter.speed", "unknown option"),
        ("[gui]\nx = 1\n", "[gui]", "unknown section"),
        ("[filter\nkp_yaw = 1\n", "syntax", "line 1"),
    ],
)
def test_bad_options_name_the_key_and_use_factory_values(tmp_path, text, where, what):
    path = tmp_path / "options.toml"
    path.write_text(text)
    options = load_options(path)
    assert len(options.problems) == 1
    assert options.problems[0].where == where
    assert what in options.problems[0].message
    assert options.filter.kp_yaw == Options().filter.kp_yaw


def test_good_values_survive_next_to_bad_ones(tmp_path):
    path = tmp_path / "options.toml"
    path.write_text("[filter]\nkp_yaw = 0.7\nki_yaw = 'x'\n")
    options = load_options(path)
    assert options.filter.kp_yaw == 0.7
    assert options.filter.ki_yaw == Options().filter.ki_yaw
    assert len(options.problems) == 1


def test_unreadable_options_file(tmp_path):
    path = tmp_path / "options.toml"
    path.write_bytes(b"\xff\xfe\x00binary")
    options = load_options(path)
    assert options == Options() and options.problems
    missing = load_options(tmp_path / "missing.toml")
    assert missing == Options() and "cannot be read" in missing.problems[0].message
