"""Calibration procedures against the simulated suit with a deliberately changed truth."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.calibration.ellipsoid import fit_ellipsoid, sphere_residual
from bpms.calibration.procedures import POSE_ORDER, AccelProcedure, GyroProcedure, MagProcedure
from bpms.calibration.result import collect, format_summary, summary
from bpms.filter.calibration import MagEllipsoid
from bpms.firmware.sim.calibration_poses import CHANGED_IMUS, CalibrationSuit, changed_table
from bpms.io.calib_file import load_factory_calibration

IMUS = list(CHANGED_IMUS)


@pytest.fixture(scope="module")
def truth():
    return changed_table()


@pytest.fixture(scope="module")
def run(truth):
    """Gyro, accel (6 poses each) and a 2-minute sweep of the changed IMUs, merged into the
    factory table."""
    suit = CalibrationSuit(truth, seed=5)
    gyro = GyroProcedure(IMUS, samples=500)
    gyro.feed_many(suit.still(520))
    accel = AccelProcedure(IMUS, auto=True)
    while not accel.done:
        accel.feed_many(suit.accel_pose(*accel.current, 250))
    mag = MagProcedure(IMUS, duration_s=120.0, ellipsoid=True)
    mag.feed_many(suit.sweep(6000))
    old = load_factory_calibration()
    update = collect(gyro, accel, mag, old)
    return gyro, accel, mag, update, old, update.merge(old)


def test_truth_differs_from_factory(truth):
    diff = np.abs(truth.values - load_factory_calibration().values)
    assert (diff[IMUS].max(axis=1) > 10).all()
    assert (diff[[i for i in range(18) if i not in IMUS]] == 0).all()


def test_recovered_values_match_the_truth(run, truth):
    gyro, accel, mag, _update, old, new = run
    assert gyro.state == "done" and accel.done and mag.state == "done"
    for imu in IMUS:
        t, n = truth.values[imu], new.values[imu]
        gravity = t[0]
        assert abs(n[0] - gravity) <= 0.01 * gravity  # gravity within 1 %
        t_off = t[1:7].reshape(3, 2).mean(axis=1)
        n_off = n[1:7].reshape(3, 2).mean(axis=1)
        assert np.abs(n_off - t_off).max() <= 0.01 * gravity  # accel offsets within 1 %
        assert np.abs(n[1:7] - t[1:7]).max() <= 0.01 * gravity  # and the extremes
        assert np.abs(n[13:16] - t[13:16]).max() <= 2.0  # gyro averages within 2 counts
        t_mag, n_mag = t[7:13].reshape(3, 2), n[7:13].reshape(3, 2)
        mag_range = t_mag[:, 1] - t_mag[:, 0]
        assert (np.abs(n_mag.mean(axis=1) - t_mag.mean(axis=1)) <= 0.03 * mag_range).all()
    # nothing else changed
    others = [i for i in range(18) if i not in IMUS]
    assert (new.values[others] == old.values[others]).all()


def test_quality_figures_and_summary(run):
    *_, update, old, new = run
    q = update.quality
    assert set(q.gravity_spread_pct) == set(IMUS)
    assert all(v < 1.0 for v in q.gravity_spread_pct.values())
    assert all(0.0 < v < 2.0 for v in q.mag_residual.values())
    assert all(q.mag_residual_ellipsoid[i] <= q.mag_residual[i] for i in IMUS)
    assert all(v > 0.95 for v in q.mag_coverage.values())
    rows = summary(old, new, IMUS)
    assert {r.imu for r in rows} == set(IMUS)
    assert "GxAvg" in format_summary(rows)
    assert len(q.lines()) == 2 * len(IMUS)


def test_moving_during_the_gyro_step_is_refused():
    suit = CalibrationSuit(seed=1)
    proc = GyroProcedure([0, 4], samples=300)
    proc.feed_many(suit.still(100))
    assert proc.state == "collecting" and 0 < proc.progress < 1
    proc.feed_many(suit.moving(60))
    assert proc.state == "rejected" and "moved" in proc.message
    assert proc.averages == {}
    proc.restart()
    proc.feed_many(suit.still(320))
    assert proc.state == "done" and proc.attempts == 2
    assert set(proc.averages) == {0, 4}


def test_gyro_ignores_failed_readings():
    suit = CalibrationSuit(seed=2)
    raw = suit.still(200)
    errors = np.zeros((200, 18, 3), bool)
    errors[::3, 0, 2] = True
    raw[::3, 0, 6:9] = 30000  # garbage behind the error bit
    proc = GyroProcedure([0], samples=200)
    proc.feed_many(raw, errors)
    assert proc.state == "done"
    assert np.abs(proc.averages[0] - suit.table.gyro_avg[0]).max() < 2.0


def test_accel_guided_order_skip_redo_and_wrong_pose():
    suit = CalibrationSuit(seed=3)
    proc = AccelProcedure([5], samples=100)
    assert [s[1:] for s in proc.steps] == list(POSE_ORDER)
    # wrong pose: +x asked... first step is +z; hold -z instead → capture refused
    proc.feed_many(suit.accel_pose(5, 2, -1, 30))
    assert not proc.at_extreme and not proc.capture()
    proc.feed_many(suit.accel_pose(5, 2, 1, 30))
    assert proc.at_extreme and proc.still and proc.capture()
    proc.feed_many(suit.accel_pose(5, 2, 1, 50))
    assert proc.capturing and 0.4 < proc.progress < 0.6
    proc.feed_many(suit.accel_pose(5, 2, 1, 60))
    assert (5, 2, 1) in proc.captures and proc.current == (5, 2, -1)
    proc.skip()
    assert proc.current == (5, 0, 1) and (5, 2, -1) in proc.skipped
    proc.redo((5, 2, -1))
    assert proc.current == (5, 2, -1)
    proc.feed_many(suit.accel_pose(5, 2, -1, 30))
    assert proc.capture()
    proc.feed_many(suit.accel_pose(5, 2, -1, 110))
    assert (5, 2, -1) in proc.captures and proc.current == (5, 0, 1)  # back where it was
    ext = proc.extremes()[5]
    assert np.isnan(ext[0]).all() and not np.isnan(ext[2]).any()
    # moving during a capture restarts it
    proc.feed_many(suit.accel_pose(5, 0, 1, 30))
    assert proc.capture()
    proc.feed_many(suit.moving(20))
    assert proc.progress < 0.1 and "moved" in proc.message


def test_merge_keeps_skipped_poses_and_recomputes_gravity():
    suit = CalibrationSuit(changed_table((3,)), seed=4)
    proc = AccelProcedure([3], samples=100, auto=True)
    while not proc.done:
        if proc.current[1] == 1:  # skip both y poses
            proc.skip()
            continue
        proc.feed_many(suit.accel_pose(*proc.current, 150))
    old = load_factory_calibration()
    new = collect(accel=proc, old=old).merge(old)
    assert new.values[3, 3] == old.values[3, 3] and new.values[3, 4] == old.values[3, 4]
    acc = new.values[3, 1:7].reshape(3, 2)
    assert new.values[3, 0] == pytest.approx(np.mean((acc[:, 1] - acc[:, 0]) / 2))


def test_mag_warnings_saturation_too_small_and_coverage():
    table = load_factory_calibration()
    table.values[1, 7:9] -= 60  # IMU 1's x range now goes beyond the chip's -512
    suit = CalibrationSuit(table, seed=6, mag_clip=512)
    proc = MagProcedure([1, 3], duration_s=30.0)
    proc.feed_many(suit.sweep(1500))
    assert proc.state == "done" and proc.progress == 1.0
    text = "\n".join(proc.warnings())
    assert "IMU 1 mx" in text and "saturated" in text and "IMU 3" not in text
    short = MagProcedure([3], duration_s=2.0)
    short.feed_many(suit.sweep(100, rate_dps=30.0))
    assert any("sphere seen" in w for w in short.warnings())  # 2 s cannot cover it
    small = MagProcedure([3], duration_s=1.0)
    small.feed_many(suit.still(50))
    assert any("too small" in w for w in small.warnings())


def test_ellipsoid_fit_recovers_soft_iron():
    rng = np.random.default_rng(0)
    A = np.array([[0.25, 0.03, 0.0], [0.03, 0.2, -0.02], [0.0, -0.02, 0.22]])
    truth = MagEllipsoid(center=np.array([40.0, -25.0, 10.0]), matrix=A)
    u = rng.normal(size=(2000, 3))
    u = 100 * u / np.linalg.norm(u, axis=1, keepdims=True)
    pts = np.linalg.solve(A, u.T).T + truth.center + rng.normal(0, 1.0, (2000, 3))
    fit = fit_ellipsoid(pts)
    assert fit is not None
    assert np.abs(fit.ellipsoid.center - truth.center).max() < 1.5
    assert np.abs(fit.ellipsoid.matrix - A).max() < 0.005
    assert fit.residual < 1.0 and sphere_residual(pts, truth) < 1.0
    assert fit_ellipsoid(pts[:10]) is None  # too few points
    flat = pts.copy()
    flat[:, 2] = 0.0
    assert fit_ellipsoid(flat) is None  # a plane is no ellipsoid
