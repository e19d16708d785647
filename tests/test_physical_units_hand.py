"""SensorCalibration's display units (the one function behind the table, the plots, the
calibrated CSV and the LSL sensor stream) against SPEC §4 worked by hand from Table 2.2
(tests/hand_units.py, standard library only): every IMU and axis, sign and scale."""

from __future__ import annotations

import numpy as np
from hand_units import hand_raw, physical

from bpms.filter.calibration import SensorCalibration
from bpms.io.calib_file import load_factory_calibration


def test_physical_units_of_every_imu_and_axis():
    calibration = SensorCalibration.from_table(load_factory_calibration())
    raw = np.array([[hand_raw(i, f) for i in range(18)] for f in range(3)], np.int16)
    acc, mag, gyr = calibration.physical_units(raw)
    got = np.concatenate([acc, mag, gyr], axis=-1)
    expected = np.array([[physical(i, hand_raw(i, f)) for i in range(18)] for f in range(3)])
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)
    one = np.concatenate(calibration.physical_units(raw[0]), axis=-1)  # one frame [18, 9]
    np.testing.assert_allclose(one, expected[0], rtol=1e-12, atol=1e-12)


def test_the_filter_units_by_hand():
    """calibrate() (the filter's input, SPEC §4 before the pre-rotation): IMU 1 (R foot,
    identity pre-rotation) at its offsets reads zero; one count above the accelerometer's x
    offset is Gravity / (max − offset) counts of 1 g."""
    calibration = SensorCalibration.from_table(load_factory_calibration())
    raw = np.zeros((18, 9))
    # R foot: AxMin −268, AxMax 266 → offset −1, 267 counts per g; Gravity 266.6666667
    raw[1, 0] = -1 + 267  # exactly 1 g on x
    raw[1, 1:3] = [(-257 + 275) / 2, (-276 + 258) / 2]  # y, z at their offsets
    raw[1, 3:6] = [(-512 + 402) / 2, (-477 + 400) / 2, (-512 + 412) / 2]
    raw[1, 6:9] = [-5.53, 26.69666667, -10.75666667]
    acc, mag, gyr = (v[0] for v in calibration.calibrate(raw[None]))
    np.testing.assert_allclose(acc[1], [266.6666667, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(mag[1], [0.0, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(gyr[1], [0.0, 0.0, 0.0], atol=1e-9)


def test_the_inverse_by_hand_for_the_right_foot():
    """uncalibrate (raw counts of filter-unit vectors, the simulated suit's way to counts):
    IMU 1 (R foot, identity pre-rotation) reading 1 g down z, a field of +100 along x and y
    and no rotation gives AzMax, MxMax, MyMin (y negated) and the gyro averages, the other
    axes at their offsets (Table 2.2)."""
    calibration = SensorCalibration.from_table(load_factory_calibration())
    acc, mag, gyr = np.zeros((18, 3)), np.zeros((18, 3)), np.zeros((18, 3))
    acc[1] = [0.0, 0.0, 266.6666667]
    mag[1] = [100.0, 100.0, 0.0]
    raw = calibration.uncalibrate(acc, mag, gyr)[1]
    # AxMin −268 AxMax 266, AyMin −257 AyMax 275, AzMin −276 AzMax 258; MxMin −512 MxMax 402,
    # MyMin −477 MyMax 400, MzMin −512 MzMax 412; GxAvg −5.53, GyAvg 26.69666667, GzAvg
    # −10.75666667. 1 g on z is (AzMax − offset) counts above the offset −9: AzMax.
    expected = [-1.0, 9.0, 258.0, 402.0, -477.0, -50.0, -5.53, 26.69666667, -10.75666667]
    np.testing.assert_allclose(raw, expected, atol=1e-6)


def test_ellipsoids_added_one_imu_at_a_time_are_all_kept():
    from bpms.io.mag_ellipsoid import MagEllipsoid

    calibration = SensorCalibration.from_table(load_factory_calibration())
    first = MagEllipsoid(center=np.array([1.0, 2.0, 3.0]), matrix=np.eye(3) * 0.2)
    second = MagEllipsoid(center=np.array([-4.0, 5.0, 6.0]), matrix=np.eye(3) * 0.3)
    both = calibration.with_ellipsoids({0: first}).with_ellipsoids({1: second})
    np.testing.assert_array_equal(both.mag_center[0], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(both.mag_center[1], [-4.0, 5.0, 6.0])
    np.testing.assert_array_equal(both.mag_matrix[0], np.eye(3) * 0.2)
    # an IMU without an ellipsoid keeps its min/max offset and scale (Table 2.2, IMU 2)
    np.testing.assert_allclose(both.mag_center[2], [(-512 + 453) / 2, (-512 + 511) / 2,
                                                   (-456 + 511) / 2])
