"""The numba filter bank against the scalar reference (SPEC §5), resets, gains, failed sensors."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.filter.bank import MahonyBank
from bpms.filter.calibration import SensorCalibration
from bpms.filter.rotations import dcm_to_euler
from bpms.firmware.sim.session import simulate
from tests.reference_mahony import ReferenceMahony, synthetic_motion

N_FRAMES = 2500  # 50 s of the simulated suit's script: arms, elbows, trunk, squats
GAIN_CHANGE_AT = 900  # kp_yaw 1.2 → 0.4, kp_rollpitch 0.02 → 0.05
RESET_AT = 1400  # all IMUs re-initialise here
RESET_ONE_AT, RESET_ONE_IMU = 2000, 6
TOL = 1e-9


@pytest.fixture(scope="module")
def data() -> tuple[np.ndarray, ...]:
    """Calibrated filter inputs of the simulated suit (mounting errors, noise, magnet)."""
    rec = simulate(duration_s=N_FRAMES * 0.02, seed=7, mag_disturbance=True)
    cal = SensorCalibration.from_table(rec.calibration)
    acc, mag, gyr = cal.calibrate(rec.raw)
    assert len(acc) == N_FRAMES
    return acc, mag, gyr, cal.gravity


@pytest.fixture(scope="module")
def synthetic() -> tuple[np.ndarray, ...]:
    """Fast random rotations of every IMU (other Gravity values), for a second check."""
    acc, mag, gyr, _ = synthetic_motion(N_FRAMES, seed=3)
    gravity = np.linspace(250.0, 270.0, 18)
    return acc * (gravity / 256.0)[None, :, None], mag, gyr, gravity


def _reference(acc, mag, gyr, gravity):
    """Reference outputs [N, 18, ...] for the scripted gain change and resets."""
    n = acc.shape[0]
    R = np.empty((n, 18, 3, 3))
    eul = np.empty((n, 18, 3))
    wi = np.empty((n, 18, 3))
    wp = np.empty((n, 18, 3))
    for i in range(18):
        f = ReferenceMahony(gravity[i])
        for k in range(n):
            if k == GAIN_CHANGE_AT:
                f.kp_yaw, f.kp_rp = 0.4, 0.05
            if k == RESET_AT or (k == RESET_ONE_AT and i == RESET_ONE_IMU):
                f.reset()
            f.update(acc[k, i].tolist(), mag[k, i].tolist(), gyr[k, i].tolist())
            R[k, i] = f.R
            eul[k, i] = (f.roll, f.pitch, f.yaw)
            wi[k, i] = f.w_i
            wp[k, i] = f.w_p
    return R, eul, wi, wp


@pytest.fixture(scope="module")
def reference(data):
    return _reference(*data)


def _params(n: int) -> np.ndarray:
    p = np.tile([0.02, 0.00002, 1.2, 0.00002, 0.02], (n, 1))
    p[GAIN_CHANGE_AT:, 2] = 0.4
    p[GAIN_CHANGE_AT:, 0] = 0.05
    return p


def _resets(n: int) -> np.ndarray:
    r = np.zeros((n, 18), bool)
    r[RESET_AT] = True
    r[RESET_ONE_AT, RESET_ONE_IMU] = True
    return r


def _assert_close(out, reference) -> None:
    for name, got, want in zip(("R", "euler", "w_i", "w_p"), out, reference, strict=True):
        err = np.max(np.abs(got - want))
        assert err < TOL, f"{name} differs from the reference by {err:g}"


def test_batch_matches_reference(data, reference):
    acc, mag, gyr, gravity = data
    bank = MahonyBank(gravity)
    out = bank.process(acc, mag, gyr, resets=_resets(N_FRAMES), params=_params(N_FRAMES),
                       store_terms=True)
    _assert_close((out.R, out.euler, out.w_i, out.w_p), reference)


def test_batch_matches_reference_on_fast_synthetic_rotations(synthetic):
    acc, mag, gyr, gravity = (v[:800] if v.ndim == 3 else v for v in synthetic)
    n = len(acc)
    out = MahonyBank(gravity).process(acc, mag, gyr, resets=_resets(N_FRAMES)[:n],
                                      params=_params(N_FRAMES)[:n], store_terms=True)
    _assert_close((out.R, out.euler, out.w_i, out.w_p), _reference(acc, mag, gyr, gravity))


def test_batch_in_chunks_matches_reference(data, reference):
    """The state carries over between calls; gains set on the bank apply from the next call."""
    acc, mag, gyr, gravity = data
    bank = MahonyBank(gravity)
    parts = []
    for lo, hi in ((0, 250), (250, GAIN_CHANGE_AT), (GAIN_CHANGE_AT, RESET_AT),
                   (RESET_AT, RESET_ONE_AT), (RESET_ONE_AT, N_FRAMES)):
        if lo == GAIN_CHANGE_AT:
            bank.set_gains(kp_yaw=0.4, kp_rollpitch=0.05)
        if lo == RESET_AT:
            bank.reset()
        if lo == RESET_ONE_AT:
            bank.reset(RESET_ONE_IMU)
        parts.append(bank.process(acc[lo:hi], mag[lo:hi], gyr[lo:hi], store_terms=True))
    out = [np.concatenate([getattr(p, name) for p in parts]) for name in ("R", "euler", "w_i",
                                                                           "w_p")]
    _assert_close(out, reference)


def test_frame_by_frame_matches_reference(data, reference):
    """A live frame is a batch of one: the same kernel, the same numbers as the reference."""
    acc, mag, gyr, gravity = data
    bank = MahonyBank(gravity)
    outs = []
    for k in range(N_FRAMES):
        if k == GAIN_CHANGE_AT:
            bank.set_gains(kp_yaw=0.4, kp_rollpitch=0.05)
        if k == RESET_AT:
            bank.reset()
        if k == RESET_ONE_AT:
            bank.reset(RESET_ONE_IMU)
        o = bank.process(acc[k:k + 1], mag[k:k + 1], gyr[k:k + 1], store_terms=True)
        outs.append((o.R[0], o.euler[0], o.w_i[0], o.w_p[0]))
    _assert_close([np.stack(x) for x in zip(*outs, strict=True)], reference)


def test_first_frame_and_reset_frame_only_initialise(data):
    acc, mag, gyr, gravity = data
    bank = MahonyBank(gravity)
    out = bank.process(acc[:3], mag[:3], gyr[:3], store_terms=True)
    assert np.all(out.w_i[0] == 0) and np.all(out.w_p[0] == 0)
    assert np.any(out.w_p[1] != 0)
    # Euler of the initialising frame: roll/pitch from the accelerometer alone
    a = acc[0]
    np.testing.assert_allclose(out.euler[0, :, 1],
                               -np.arctan2(a[:, 0], np.hypot(a[:, 1], a[:, 2])), atol=1e-12)
    np.testing.assert_allclose(dcm_to_euler(out.R[0]), out.euler[0], atol=1e-12)


def test_filter_converges_to_truth():
    """Self-consistency of the sign conventions: the filter tracks the true orientation."""
    acc, mag, gyr, R_true = synthetic_motion(1500, seed=5)
    out = MahonyBank(np.full(18, 256.0)).process(acc, mag, gyr)
    down_est = out.R[500:, :, 2, :]
    down_true = R_true[500:, :, 2, :]
    angle = np.degrees(np.arccos(np.clip(np.sum(down_est * down_true, -1), -1, 1)))
    assert np.sqrt(np.mean(angle**2)) < 2.0
    yaw_err = np.angle(np.exp(1j * (dcm_to_euler(out.R[500:])[..., 2]
                                    - dcm_to_euler(R_true[500:])[..., 2])))
    assert np.degrees(np.sqrt(np.mean(yaw_err**2))) < 5.0


def test_failed_sensor_holds_last_good_value(data):
    """A flagged sensor's value is replaced by its last good value; held steps are counted."""
    acc, mag, gyr, gravity = data
    n = 200
    errors = np.zeros((n, 18, 3), bool)
    errors[50:60, 4, 0] = True  # IMU 4 accel fails for 10 frames
    errors[80:85, 9, 2] = True  # IMU 9 gyro fails for 5 frames
    garbage_acc = acc[:n].copy()
    garbage_acc[50:60, 4] = 30000.0  # what a failed read might carry
    garbage_gyr = gyr[:n].copy()
    garbage_gyr[80:85, 9] = -99.0
    bank = MahonyBank(gravity)
    out = bank.process(garbage_acc, mag[:n], garbage_gyr, errors=errors)
    # equivalent input with the held values substituted by hand, no flags
    held_acc = acc[:n].copy()
    held_acc[50:60, 4] = acc[49, 4]
    held_gyr = gyr[:n].copy()
    held_gyr[80:85, 9] = gyr[79, 9]
    expected = MahonyBank(gravity).process(held_acc, mag[:n], held_gyr)
    np.testing.assert_allclose(out.R, expected.R, atol=1e-12)
    counts = bank.held_count
    assert counts[4, 0] == 10 and counts[9, 2] == 5 and counts.sum() == 15


def test_imu_without_good_value_stays_uninitialised(data):
    acc, mag, gyr, gravity = data
    errors = np.zeros((20, 18, 3), bool)
    errors[:10, 2, 1] = True  # IMU 2 magnetometer fails from the start for 10 frames
    out = MahonyBank(gravity).process(acc[:20], mag[:20], gyr[:20], errors=errors)
    assert np.isnan(out.euler[:10, 2]).all()
    assert np.isfinite(out.euler[10:, 2]).all()
    assert np.isfinite(out.euler[:, [0, 1, 3]]).all()
    # IMU 2 initialises at frame 10 exactly as a fresh filter started there
    fresh = MahonyBank(gravity).process(acc[10:20], mag[10:20], gyr[10:20])
    np.testing.assert_allclose(out.R[10:, 2], fresh.R[:, 2], atol=1e-12)


def test_reset_waits_for_a_valid_frame(data):
    acc, mag, gyr, gravity = data
    bank = MahonyBank(gravity)
    bank.process(acc[:100], mag[:100], gyr[:100])
    bank.reset(7)
    errors = np.zeros((10, 18, 3), bool)
    errors[:3, 7, 0] = True
    out = bank.process(acc[100:110], mag[100:110], gyr[100:110], errors=errors)
    assert np.isnan(out.R[:3, 7]).all()
    fresh = MahonyBank(gravity).process(acc[103:110], mag[103:110], gyr[103:110])
    np.testing.assert_allclose(out.R[3:, 7], fresh.R[:, 7], atol=1e-12)
    assert np.isfinite(out.R[:, 8]).all()
