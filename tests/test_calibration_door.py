"""Every calibration number is checked at the door: a zero, NaN or absurd value (Calib.cfg,
JSON, a recording's header) gives a warning naming the IMU and the field, and that IMU's
factory record; never a traceback, never silent NaN output."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bpms.firmware.sim.arbiter import MotionSource
from bpms.io.calib_file import FIELDS, format_legacy, load_calibration, load_factory_calibration
from bpms.io.calib_modern import ModernCalibration, load_modern, save_modern
from bpms.io.rawfile import new_header, write_raw

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[1]
N = 150


@pytest.fixture(scope="module")
def motion():
    return MotionSource.simulated(duration_s=4.0, seed=2)


def recording(folder: Path, name: str, motion, calibration) -> Path:
    path = folder / f"{name}.bpmsraw"
    frames = b"".join(motion.frame(j) for j in range(N))
    write_raw(path, 1.7e9 + np.arange(N) * 0.02, frames, new_header(calibration=calibration))
    return path


def bpms(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bpms", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=100)


def rows(path: Path) -> list[list[str]]:
    with path.open() as f:
        return [row for row in csv.reader(f) if row and not row[0].startswith("#")]


@pytest.fixture(scope="module")
def factory_csv(tmp_path_factory, motion):
    """The same frames filtered with the factory calibration in the header."""
    folder = tmp_path_factory.mktemp("factory")
    raw = recording(folder, "factory", motion, load_factory_calibration().values)
    out = folder / "factory.csv"
    done = bpms("filter", str(raw), "-o", str(out))
    assert done.returncode == 0, done.stderr
    return rows(out)


@pytest.mark.parametrize("bad", ["zero", "nan"])
def test_filter_with_a_zero_or_nan_header_calibration(tmp_path, motion, factory_csv, bad):
    values = np.zeros((18, 16)) if bad == "zero" else np.full((18, 16), np.nan)
    raw = recording(tmp_path, bad, motion, values)
    out = tmp_path / f"{bad}.csv"
    done = bpms("filter", str(raw), "-o", str(out))
    assert done.returncode == 0 and "Traceback" not in done.stderr
    for imu in range(18):
        assert f"IMU {imu} field 1 (Gravity)" in done.stderr
    assert "factory values used for IMU 17" in done.stderr
    got = rows(out)
    assert not any(math.isnan(float(v)) for row in got[1:] for v in row[1:] if v)
    assert got == factory_csv  # exactly the factory records were used


def test_one_bad_field_in_a_header_names_its_imu_and_field(tmp_path, motion, factory_csv):
    values = load_factory_calibration().values.copy()
    values[7, FIELDS.index("MyMax")] = values[7, FIELDS.index("MyMin")]  # zero range
    raw = recording(tmp_path, "one", motion, values)
    out = tmp_path / "one.csv"
    done = bpms("filter", str(raw), "-o", str(out))
    assert done.returncode == 0
    lines = [line for line in done.stderr.splitlines() if "factory values used" in line]
    assert lines and all("IMU 7: MyMin ≥ MyMax" in line for line in lines)
    assert rows(out) == factory_csv


@pytest.mark.parametrize("command", [
    ("export", "opensim"), ("export", "bvh"), ("export", "matlab"), ("rom",), ("track",)])
def test_analysis_commands_on_a_zero_calibration(tmp_path, motion, command):
    raw = recording(tmp_path, "zero", motion, np.zeros((18, 16)))
    out = tmp_path / "out"
    done = bpms(*command, str(raw), "-o", str(out))
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr and "ZeroDivisionError" not in done.stderr
    assert "IMU 0 field 1 (Gravity)" in done.stderr


def test_calib_cfg_with_an_absurd_gyro_average(tmp_path):
    table = load_factory_calibration()
    table.values[4, FIELDS.index("GxAvg")] = 1e308
    table.values[9, FIELDS.index("AzMin")] = table.values[9, FIELDS.index("AzMax")]
    path = tmp_path / "Calib.cfg"
    path.write_text(format_legacy(table))
    loaded = load_calibration(path)
    factory = load_factory_calibration()
    assert np.array_equal(loaded.values[[4, 9]], factory.values[[4, 9]])
    wheres = [p.where for p in loaded.problems]
    assert len(wheres) == 2
    assert wheres[0].startswith("IMU 4") and "(GxAvg)" in wheres[0]
    assert wheres[1] == "IMU 9 (line 10)" and "AzMin ≥ AzMax" in loaded.problems[1].message


def test_json_calibration_with_absurd_values(tmp_path):
    path = tmp_path / "calibration.json"
    save_modern(ModernCalibration(load_factory_calibration()), path)
    doc = json.loads(path.read_text())
    doc["imus"][2]["gyro_avg"][1] = 1e308
    doc["imus"][5]["accel"]["max"][0] = doc["imus"][5]["accel"]["min"][0]
    path.write_text(json.dumps(doc))
    loaded = load_modern(path)
    factory = load_factory_calibration()
    assert np.array_equal(loaded.table.values, factory.values)
    messages = [str(p) for p in loaded.problems]
    assert len(messages) == 2
    assert "id 2" in messages[0] and "GyAvg" in messages[0]
    assert "id 5" in messages[1] and "AxMax" in messages[1]
