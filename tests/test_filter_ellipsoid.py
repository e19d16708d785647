"""The processor uses a magnetometer ellipsoid fit from the modern companion file."""

from __future__ import annotations

import numpy as np

from bpms.filter.calibration import MagEllipsoid, SensorCalibration
from bpms.filter.processor import BodyPoseProcessor
from bpms.io.calib_file import load_factory_calibration, save_legacy
from bpms.io.calib_modern import ModernCalibration, modern_path, save_modern


def test_ellipsoid_beside_the_legacy_file_reaches_the_filter_inputs(tmp_path):
    table = load_factory_calibration()
    legacy = tmp_path / "Calib.cfg"
    save_legacy(table, legacy)
    mm = table.mag_min_max[3]
    center = mm.mean(axis=-1) + np.array([5.0, -3.0, 2.0])
    matrix = np.diag(100.0 / (mm[:, 1] - mm[:, 0]) * 2) @ np.array(
        [[1.0, 0.05, 0.0], [0.05, 0.97, 0.02], [0.0, 0.02, 1.03]])
    ellipsoid = MagEllipsoid(center, matrix)
    save_modern(ModernCalibration(table, {3: ellipsoid}), modern_path(legacy))

    plain = BodyPoseProcessor(load_factory_calibration())
    fitted = BodyPoseProcessor(legacy)
    assert plain.sensor_calibration.mag_correction() is None
    assert fitted.sensor_calibration.mag_correction() is not None
    raw = np.random.default_rng(2).integers(-400, 400, (50, 18, 9)).astype(np.int16)
    expected = SensorCalibration.from_table(table, ellipsoids={3: ellipsoid}).calibrate(raw)
    got = fitted.calibrate(raw)
    for a, b in zip(got, expected, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-9)
    # Only IMU 3's magnetometer changes.
    base = plain.calibrate(raw)
    changed = np.abs(got[1] - base[1]).max(axis=(0, 2)) > 1e-6
    assert changed.tolist() == [i == 3 for i in range(18)]
    np.testing.assert_array_equal(got[0], base[0])
