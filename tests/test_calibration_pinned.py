"""The calibration formula pinned to numbers worked out by hand from the dissertation's Table 2.2
(calib/Calib.cfg, ``../shared/calibration-table-2.2.csv``), not by the code under test.

docs/units.md: per axis ``offset = (min + max) / 2``; accelerometer ``scale = Gravity / (max −
offset)``, magnetometer ``scale = 100 / (max − offset)``, gyroscope ``(raw − avg) · 0.06957 ·
π/180`` rad/s; axis signs accel (+, +, +), mag (+, −, −), gyro (−, −, −); then the IMU's
pre-rotation (pitch 90°: filter x = board z, y = board y, z = −board x; roll 90°: x = board x,
y = −board z, z = board y; identity).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bpms.filter.calibration import SensorCalibration
from bpms.io.calib_file import load_factory_calibration

GYRO = 0.06957 * math.pi / 180.0  # rad/s per count (ITG-3200, 14.375 LSB per °/s)


def _calibrated(imu: int, counts: list[float]) -> tuple[np.ndarray, ...]:
    raw = np.zeros((1, 18, 9), dtype=np.int16)
    raw[0, imu] = counts
    acc, mag, gyr = SensorCalibration.from_table(load_factory_calibration()).calibrate(raw)
    return acc[0, imu], mag[0, imu], gyr[0, imu]


def test_right_thigh_pitch_90():
    # Table 2.2, IMU 0 (R leg): Gravity 262.3333333; Ax −271…261, Ay −273…252, Az −266…251;
    # Mx −422…470, My −392…382, Mz −463…511; gyro averages −45.88, 49.25333333, 7.136666667.
    g = 262.3333333
    # accel offsets −5, −10.5, −7.5; (max − offset) 266, 262.5, 258.5
    # mag offsets 24, −5, 24; (max − offset) 446, 387, 487
    acc, mag, gyr = _calibrated(0, [261, -10, 251, 470, 382, -463, -45, 49, 7])
    board_acc = [(261 + 5) * g / 266, (-10 + 10.5) * g / 262.5, (251 + 7.5) * g / 258.5]
    board_mag = [(470 - 24) * 100 / 446, -(382 + 5) * 100 / 387, -(-463 - 24) * 100 / 487]
    board_gyr = [-(-45 + 45.88) * GYRO, -(49 - 49.25333333) * GYRO, -(7 - 7.136666667) * GYRO]
    # pitch 90°: (board z, board y, −board x)
    np.testing.assert_allclose(acc, [board_acc[2], board_acc[1], -board_acc[0]], rtol=1e-12)
    np.testing.assert_allclose(mag, [board_mag[2], board_mag[1], -board_mag[0]], rtol=1e-12)
    np.testing.assert_allclose(gyr, [board_gyr[2], board_gyr[1], -board_gyr[0]], rtol=1e-9)
    # at an axis maximum the accelerometer reads Gravity counts, the magnetometer 100
    np.testing.assert_allclose([board_acc[0], board_mag[0]], [g, 100.0], rtol=1e-12)


def test_right_foot_identity():
    # IMU 1 (R foot): Gravity 266.6666667; Ax −268…266 (offset −1, max − offset 267);
    # Mx −512…402 (offset −55, 457), Mz −512…412 (offset −50, 462); gyro z average −10.75666667
    g = 266.6666667
    acc, mag, gyr = _calibrated(1, [-268, 9, 0, -512, -38, 412, -5, 27, -11])
    assert math.isclose(acc[0], (-268 + 1) * g / 267, rel_tol=1e-12)  # −1 g on board x
    assert math.isclose(mag[0], (-512 + 55) * 100 / 457, rel_tol=1e-12)  # −100
    assert math.isclose(mag[2], -(412 + 50) * 100 / 462, rel_tol=1e-12)  # sign −: −100
    assert math.isclose(gyr[2], -(-11 + 10.75666667) * GYRO, rel_tol=1e-9)


def test_right_shoulder_roll_90():
    # IMU 15 (R shoulder), roll 90°: filter (board x, −board z, board y). Its Table 2.2 row:
    row = np.loadtxt(_table(), delimiter=",", skiprows=1, usecols=range(2, 18))[15]
    g, (_, ax1, ay0, ay1, _, az1) = row[0], row[1:7]
    counts = [ax1, ay0, az1, 0, 0, 0, 0, 0, 0]  # +1 g on x, −1 g on y, +1 g on z
    acc, _, _ = _calibrated(15, counts)
    # (max − offset) = (max − min) / 2 for each axis
    board = [g, (ay0 - (ay0 + ay1) / 2) * g / ((ay1 - ay0) / 2), g]
    np.testing.assert_allclose(acc, [board[0], -board[2], board[1]], rtol=1e-12)
    np.testing.assert_allclose(acc, [g, -g, -g], rtol=1e-12)


def _table():
    path = Path(__file__).resolve().parents[2] / "shared" / "calibration-table-2.2.csv"
    if not path.is_file():
        pytest.skip(f"Table 2.2 not found at {path} (../shared beside the repository)")
    return path
