"""The modern calibration file, merging into existing files, and the filter's use of an
ellipsoid correction."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bpms.calibration.output import load_existing, save_pair
from bpms.calibration.procedures import AccelProcedure, GyroProcedure, MagProcedure
from bpms.calibration.result import collect
from bpms.filter.bank import MahonyBank
from bpms.filter.calibration import MagEllipsoid, SensorCalibration
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.calibration_poses import CalibrationSuit, changed_table
from bpms.firmware.sim.session import simulate
from bpms.io.calib_file import load_calibration, load_factory_calibration, save_legacy
from bpms.io.calib_modern import (
    ModernCalibration,
    load_modern,
    modern_path,
    save_modern,
)

ELL = MagEllipsoid(center=np.array([30.0, -20.0, 5.0]),
                   matrix=np.array([[0.24, 0.02, 0.0], [0.02, 0.2, 0.01], [0.0, 0.01, 0.22]]))


def test_modern_round_trip(tmp_path):
    table = changed_table((4,))
    path = tmp_path / "Calib.json"
    save_modern(ModernCalibration(table, {4: ELL}, {4: {"method": "test"}}), path)
    back = load_modern(path)
    assert back.problems == []
    assert np.array_equal(back.table.values, table.values)
    assert np.array_equal(back.ellipsoids[4].matrix, ELL.matrix)
    assert back.provenance == {4: {"method": "test"}}
    doc = json.loads(path.read_text())
    assert doc["imus"][4]["accel"]["min"][0] == table.values[4, 1]


def test_modern_bad_content_falls_back_per_imu(tmp_path):
    path = tmp_path / "Calib.json"
    save_modern(ModernCalibration(changed_table((2, 3))), path)
    doc = json.loads(path.read_text())
    doc["imus"][2]["accel"]["min"][1] = "abc"
    doc["imus"][3]["mag"]["max"] = [-900, -900, -900]  # below the min
    del doc["imus"][5]
    path.write_text(json.dumps(doc))
    back = load_modern(path)
    factory = load_factory_calibration()
    wheres = [p.where for p in back.problems]
    assert len(wheres) == 3 and "IMU 5" in wheres
    assert np.array_equal(back.table.values[[2, 3, 5]], factory.values[[2, 3, 5]])
    path.write_text("{not json")
    broken = load_modern(path)
    assert len(broken.problems) == 1 and "cannot be read" in broken.problems[0].message
    assert np.array_equal(broken.table.values, factory.values)


def test_replacing_one_imu_recalibrates_only_that_imu(tmp_path):
    legacy = tmp_path / "Calib.cfg"
    existing_table = changed_table((1, 9), seed=7)
    save_legacy(existing_table, legacy)
    save_modern(ModernCalibration(existing_table, {9: ELL}), modern_path(legacy))
    existing = load_existing(legacy)
    assert 9 in existing.ellipsoids
    # IMU 1 replaced: a new sweep of that IMU only
    suit = CalibrationSuit(changed_table((1,), seed=8), seed=1)
    mag = MagProcedure([1], duration_s=60.0, ellipsoid=True)
    mag.feed_many(suit.sweep(3000))
    update = collect(mag=mag, old=existing.table)
    save_pair(existing, update, legacy, ["mag"])
    new = load_calibration(legacy)
    assert new.problems == []
    others = [i for i in range(18) if i != 1]
    assert np.array_equal(new.values[others], existing_table.values[others])
    assert np.array_equal(new.values[1, :7], existing_table.values[1, :7])  # accel kept
    assert not np.array_equal(new.values[1, 7:13], existing_table.values[1, 7:13])
    modern = load_existing(legacy)
    assert set(modern.ellipsoids) == {1, 9}
    assert "mag" in modern.provenance[1] and "quality" in modern.provenance[1]


def test_stale_modern_companion_contributes_nothing(tmp_path):
    legacy = tmp_path / "Calib.cfg"
    save_modern(ModernCalibration(load_factory_calibration(), {3: ELL}), modern_path(legacy))
    save_legacy(changed_table((3,)), legacy)  # edited by another tool afterwards
    assert load_existing(legacy).ellipsoids == {}


def test_default_path_unchanged_and_ellipsoid_correction_exact():
    table = changed_table()
    rec = simulate(4.0, seed=3, calibration=table)
    plain = SensorCalibration.from_table(table)
    assert plain.mag_matrix is None and plain.mag_correction() is None
    diag = plain.with_ellipsoids({})  # the min/max values as diagonal matrices
    for a, b in zip(plain.calibrate(rec.raw), diag.calibrate(rec.raw), strict=True):
        np.testing.assert_allclose(a, b, atol=1e-9)
    ell = plain.with_ellipsoids({2: ELL})
    proc = BodyPoseProcessor(table)
    _, mag_default, _ = proc.calibrate(rec.raw)
    _, mag_ell, _ = ell.calibrate(rec.raw)
    # the ellipsoid formula written out (docs/calibration.md): R* · signs · A (raw − b)
    board = np.einsum("ij,nj->ni", ELL.matrix, rec.raw[:, 2, 3:6] - ELL.center) * ell.mag_signs
    np.testing.assert_allclose(mag_ell[:, 2], board @ ell.pre_rotations[2].T, atol=1e-9)
    assert not np.allclose(mag_ell[:, 2], mag_default[:, 2])
    np.testing.assert_allclose(mag_ell[:, 3], mag_default[:, 3], atol=1e-12)
    # uncalibrate inverts the ellipsoid path (the simulated suit's soft-iron truth)
    acc, mag, gyr = ell.calibrate(rec.raw)
    np.testing.assert_allclose(ell.uncalibrate(acc, mag, gyr), rec.raw, atol=1e-6)


def _heading_error(R: np.ndarray, truth: np.ndarray, imus: list[int]) -> np.ndarray:
    """rms heading error, degrees, over the last 3/4 of the run, per IMU."""
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    yaw_t = np.arctan2(truth[..., 1, 0], truth[..., 0, 0])
    d = np.degrees(np.angle(np.exp(1j * (yaw - yaw_t))))[len(R) // 4:, imus]
    return np.sqrt(np.mean(d**2, axis=0))


@pytest.fixture(scope="module")
def soft_iron_run():
    """Truth: IMU 2 and 7 changed, IMU 7 with a soft-iron distortion."""
    truth = changed_table((2, 7))
    base = SensorCalibration.from_table(truth)
    half = np.diag(np.sqrt(base.mag_scale[7]))  # symmetric soft iron, as the fit assumes
    A = half @ np.array([[1.0, 0.12, 0.0], [0.12, 0.9, 0.05], [0.0, 0.05, 1.1]]) @ half
    true_ell = {7: MagEllipsoid(center=base.mag_offset[7] + [10.0, -5.0, 0.0], matrix=A)}
    suit = CalibrationSuit(truth, true_ell, seed=9)
    gyro = GyroProcedure([2, 7], samples=500)
    gyro.feed_many(suit.still(520))
    accel = AccelProcedure([2, 7], auto=True)
    while not accel.done:
        accel.feed_many(suit.accel_pose(*accel.current, 250))
    mag = MagProcedure([2, 7], duration_s=120.0, ellipsoid=True)
    mag.feed_many(suit.sweep(6000))
    update = collect(gyro, accel, mag, old=load_factory_calibration())
    return truth, true_ell, update


def test_filter_heading_with_the_new_calibration(soft_iron_run, tmp_path):
    truth, _true_ell, update = soft_iron_run
    legacy, _ = save_pair(load_existing(None), update, tmp_path / "Calib.cfg",
                          ["gyro", "accel", "mag"])
    new = load_calibration(legacy)  # the new file, as the filter reads it
    rec = simulate(30.0, seed=2, calibration=truth)
    imus = [2]

    def heading(table):
        return _heading_error(BodyPoseProcessor(table, auto_zero=False)
                              .process(rec.raw, rec.errors).R, rec.truth.R, imus)

    with_truth, with_new = heading(truth), heading(new)
    assert (with_new <= with_truth + 1.0).all()
    assert (heading(load_factory_calibration()) > with_truth + 1.0).all()  # the check bites


def test_filter_heading_with_the_ellipsoid(soft_iron_run):
    truth, true_ell, update = soft_iron_run
    assert 7 in update.ellipsoids
    assert update.quality.mag_residual_ellipsoid[7] < update.quality.mag_residual[7]
    # a recording made through the soft-iron truth
    suit_cal = SensorCalibration.from_table(truth, ellipsoids=true_ell)
    rec = simulate(30.0, seed=4, calibration=truth)
    raw = np.clip(np.rint(suit_cal.uncalibrate(*SensorCalibration.from_table(truth)
                                               .calibrate(rec.raw))), -32768, 32767)

    def heading(cal: SensorCalibration) -> float:
        acc, mag, gyr = cal.calibrate(raw)
        out = MahonyBank(cal.gravity).process(acc, mag, gyr)
        return float(_heading_error(out.R, rec.truth.R, [7])[0])

    new = update.merge(load_factory_calibration())
    with_truth = heading(suit_cal)
    with_ellipsoid = heading(SensorCalibration.from_table(new, ellipsoids=update.ellipsoids))
    assert with_ellipsoid <= with_truth + 1.0
