"""Physical consistency of the simulated suit (bpms.firmware.sim.session.simulate)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from bpms.filter.body_model import POINT_INDEX, joint_positions
from bpms.filter.calibration import SensorCalibration
from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.filter.rotations import dcm_to_euler
from bpms.firmware.sim.motion import DT
from bpms.firmware.sim.sensors import SensorModel
from bpms.firmware.sim.session import simulate
from bpms.io.calib_file import load_factory_calibration
from bpms.io.frames import FRAME_SIZE, decode_frames


@pytest.fixture(scope="module")
def rec():
    return simulate(seed=3)


@pytest.fixture(scope="module")
def clean():
    return simulate(seed=3, noise=False)


def calibrated(r):
    cal = SensorCalibration.from_table(r.calibration)
    acc, mag, gyr = cal.calibrate(r.raw)
    return cal, acc, mag, gyr


def still_mask(r, margin_s=0.1):
    mask = np.zeros(len(r.t), dtype=bool)
    for t0, t1 in r.still_windows:
        mask |= (r.t >= t0 + margin_s) & (r.t <= t1 - margin_s)
    return mask


def test_shapes_and_frames(rec):
    n = len(rec.t)
    assert 60.0 <= rec.t[-1] <= 90.0
    np.testing.assert_allclose(rec.t, np.arange(n) * 0.02)
    assert rec.raw.shape == (n, 18, 9) and rec.raw.dtype == np.int16
    assert rec.errors.shape == (n, 18, 3) and not rec.errors.any()
    assert len(rec.frames) == n * FRAME_SIZE
    decoded = decode_frames(rec.frames)
    np.testing.assert_array_equal(decoded.raw, rec.raw)
    assert rec.truth.R.shape == rec.truth.C.shape == (n, 18, 3, 3)
    assert rec.truth.joint_angles.shape == (n, len(JOINT_ANGLE_NAMES))
    assert rec.truth.pelvis_position.shape == (n, 3)
    names = [p[2] for p in rec.phases]
    assert names[0].startswith("still") and names[-1].startswith("still")
    assert "walk" in names and any("squat" in s for s in names)


def test_still_windows_at_start_and_end(rec):
    (a0, a1), (b0, b1) = rec.still_windows[0], rec.still_windows[-1]
    assert a0 == 0.0 and 2.0 <= a1 - a0 <= 4.0
    assert b1 == pytest.approx(rec.t[-1]) and b1 - b0 >= 2.9


def test_seeded_and_duration(rec):
    again = simulate(duration_s=10.0, seed=3)
    assert len(again.t) == 500
    np.testing.assert_array_equal(again.raw, rec.raw[:500])
    other = simulate(duration_s=10.0, seed=4)
    assert not np.array_equal(other.raw, again.raw)


def test_accel_magnitude_is_gravity_when_still(rec):
    cal, acc, _, _ = calibrated(rec)
    still = still_mask(rec)
    ratio = np.linalg.norm(acc[still], axis=-1) / cal.gravity
    assert abs(ratio.mean() - 1.0) < 0.002
    assert np.abs(ratio - 1.0).max() < 0.03
    # ... and it points along the true "down" in each IMU's filter frame.
    for t0, t1 in rec.still_windows:
        win = (rec.t >= t0) & (rec.t <= t1)
        mean = acc[win].mean(axis=0)
        down = rec.truth.R[win][0, :, 2, :]
        cos = (mean * down).sum(-1) / np.linalg.norm(mean, axis=-1)
        assert np.degrees(np.arccos(np.minimum(cos, 1.0))).max() < 0.3


def _skew(w: np.ndarray) -> np.ndarray:
    K = np.zeros((*w.shape[:-1], 3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
    return K


def _exp(w: np.ndarray) -> np.ndarray:
    """Rodrigues: rotation vectors [..., 3] → matrices."""
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    K = _skew(w)
    safe = np.maximum(th, 1e-12)
    return np.eye(3) + np.sin(th) / safe * K + (1 - np.cos(th)) / safe**2 * K @ K


def _integrate(gyr: np.ndarray, R0: np.ndarray, truth: np.ndarray, exact: bool) -> float:
    """Worst angle (°) between the propagated and the true DCMs, sampled every 0.5 s."""
    R = R0.copy()
    worst = 0.0
    for k in range(1, len(gyr)):
        if exact:
            R = R @ _exp(gyr[k] * DT)
        else:  # the filter's update and renormalisation (SPEC §5 steps 2-3)
            R = R + R @ _skew(gyr[k] * DT)
            x, y = R[:, 0], R[:, 1]
            e = (x * y).sum(-1, keepdims=True)
            xo, yo = x - e / 2 * y, y - e / 2 * x
            zo = np.cross(xo, yo)
            R = np.stack([r * (0.5 * (3 - (r * r).sum(-1, keepdims=True)))
                          for r in (xo, yo, zo)], axis=1)
        if k % 25 == 0:
            rel = np.swapaxes(R, -1, -2) @ truth[k]
            cos = np.clip((np.trace(rel, axis1=1, axis2=2) - 1) / 2, -1, 1)
            worst = max(worst, float(np.degrees(np.arccos(cos)).max()))
    return worst


def test_gyro_integrates_to_true_orientation():
    """The simulated gyro (through raw counts and the calibration) integrates to the true DCM.

    Noise-free with whole-count gyro averages: rounding a fractional zero-rate average would
    otherwise leave a constant bias of up to 0.5 count (0.035 °/s), as in a real sensor.
    Exact integration follows the truth to rounding; the filter's first-order update adds its
    own discretisation error (≈ 0.6° per fast compound move, ≈ 1.2° worst over the script)."""
    table = load_factory_calibration()
    table.values[:, 13:16] = np.round(table.values[:, 13:16])
    clean = simulate(seed=3, noise=False, calibration=table)
    _, _, _, gyr = calibrated(clean)
    assert _integrate(gyr, clean.truth.R[0], clean.truth.R, exact=True) < 0.2
    assert _integrate(gyr, clean.truth.R[0], clean.truth.R, exact=False) < 2.0


def test_mag_heading_matches_true_yaw(clean):
    """Tilt-compensated heading (SPEC §5 step 1) with the true roll/pitch = the true yaw."""
    _, _, mag, _ = calibrated(clean)
    eul = dcm_to_euler(clean.truth.R)
    roll, pitch, yaw = eul[..., 0], eul[..., 1], eul[..., 2]
    m0, m1, m2 = mag[..., 0], mag[..., 1], mag[..., 2]
    mx = m0 * np.cos(pitch) + m1 * np.sin(roll) * np.sin(pitch) + m2 * np.cos(roll) * np.sin(pitch)
    my = m1 * np.cos(roll) - m2 * np.sin(roll)
    heading = np.arctan2(-my, mx)
    ok = np.abs(pitch) < np.radians(75)
    err = np.degrees(np.angle(np.exp(1j * (heading - yaw))))[ok]
    assert np.abs(err).max() < 1.0
    # Level in the calibration pose: the plain heading is the subject's 30° heading ± mounting.
    still = still_mask(clean)
    level = np.degrees(np.arctan2(-mag[still][..., 1], mag[still][..., 0]))
    assert np.abs(level - 30.0).max() < 12.0


def test_mag_magnitude_and_dip(clean):
    _, acc, mag, _ = calibrated(clean)
    still = still_mask(clean)
    norm = np.linalg.norm(mag[still], axis=-1)
    assert np.abs(norm - 100.0).max() < 1.5
    cos = (acc[still] * mag[still]).sum(-1) / (np.linalg.norm(acc[still], axis=-1) * norm)
    assert np.degrees(np.arcsin(cos)).mean() == pytest.approx(60.0, abs=0.5)


def test_joint_angles_zero_in_calibration_pose(rec):
    still = still_mask(rec, margin_s=0.0)
    assert still.sum() > 200
    assert np.abs(rec.truth.joint_angles[still]).max() < 1e-9
    # ... and they do move during the script (elbows, knees, shoulders, head).
    span = np.degrees(np.ptp(rec.truth.joint_angles, axis=0))
    for name in ("elbow_r.flexion", "knee_l.flexion", "shoulder_r.flexion", "head.rotation"):
        assert span[JOINT_ANGLE_NAMES.index(name)] > 30.0


def test_truth_r_is_segment_times_mounting(rec):
    np.testing.assert_allclose(rec.truth.R, rec.truth.C @ rec.truth.E, atol=1e-12)
    tilt = np.degrees(np.arccos(np.clip((np.trace(rec.truth.E, axis1=1, axis2=2) - 1) / 2,
                                        -1, 1)))
    assert 0.1 < tilt.max() < 15.0
    exact = simulate(duration_s=1.0, mounting_errors=False)
    np.testing.assert_allclose(exact.truth.E, np.broadcast_to(np.eye(3), (18, 3, 3)))


def test_linear_acceleration_is_second_difference(rec):
    pos = rec.truth.imu_position
    acc2 = (pos[2:] - 2 * pos[1:-1] + pos[:-2]) / DT**2
    diff = rec.truth.imu_acceleration[1:-1] - acc2
    diff[:, [1, 13], 2] = 0.0  # heel-strike impacts are added to the feet's vertical only
    assert np.abs(diff).max() < 1e-6
    # Human-like: below 1 g everywhere except the swinging feet and shanks.
    g = np.linalg.norm(acc2, axis=-1) / 9.81
    others = np.delete(g, [1, 2, 13, 14], axis=1)
    assert others.max() < 1.0


def test_heel_strikes_and_step_length():
    # ±16 g: the 2.5 g impacts are not clipped (the firmware's ±2 g clips them, see below).
    clean = simulate(seed=3, noise=False, model=SensorModel(accel_range_g=16.0))
    cal, acc, _, _ = calibrated(clean)
    mag_g = np.linalg.norm(acc, axis=-1) / cal.gravity
    strikes = clean.truth.heel_strikes
    assert len(strikes) >= 8
    sides = [s for _, s in strikes]
    assert all(a != b for a, b in itertools.pairwise(sides))
    near = np.zeros(len(clean.t), dtype=bool)
    for t, side in strikes:
        k = round(t / DT)
        foot = 1 if side == "right" else 13
        assert mag_g[k, foot] == pytest.approx(2.5, abs=0.05)
        near[k - 3:k + 4] = True
    assert mag_g[~near][:, [1, 13]].max() < 1.9  # no false heel strike above 2.0 g
    # Pelvis advance between strikes = distance between the ankles at the strike (mid-walk).
    pts = joint_positions(clean.truth.C, on_ground=False)
    times = [t for t, _ in strikes]
    for t_a, t_b in itertools.pairwise(times[3:7]):
        ka, kb = round(t_a / DT), round(t_b / DT)
        advance = np.linalg.norm(clean.truth.pelvis_position[kb, :2]
                                 - clean.truth.pelvis_position[ka, :2])
        step = np.linalg.norm(pts[kb, POINT_INDEX["ankle_r"], :2]
                              - pts[kb, POINT_INDEX["ankle_l"], :2]
                              - (pts[kb, POINT_INDEX["hip_r"], :2]
                                 - pts[kb, POINT_INDEX["hip_l"], :2]))
        assert advance == pytest.approx(step, rel=0.05)


def test_accelerometer_saturates_at_its_configured_range():
    """At ±2 g (older firmware) counts end at -512..511 (full resolution, 256 counts per g), so
    a 2.5 g heel strike is clipped; the firmware's ±16 g (the default) passes it."""
    assert SensorModel().accel_range_g == 16.0
    assert SensorModel(accel_range_g=2.0).accel_limits() == (-512, 511)
    assert SensorModel().accel_limits() == (-4096, 4095)
    with pytest.raises(ValueError):
        SensorModel(accel_range_g=3.0)
    narrow = simulate(seed=3, noise=False, model=SensorModel(accel_range_g=2.0))
    acc = narrow.raw[..., 0:3].astype(int)
    assert acc.min() >= -512 and acc.max() <= 511
    k = round(narrow.truth.heel_strikes[2][0] / DT)
    foot = 1 if narrow.truth.heel_strikes[2][1] == "right" else 13
    assert np.isin(acc[k, foot], [-512, 511]).any()  # the strike hits the rail
    wide = simulate(seed=3, noise=False, duration_s=k * DT + 1.0,
                    model=SensorModel(accel_range_g=16.0))
    assert np.abs(wide.raw[k, foot, 0:3].astype(int)).max() > 600


def test_true_calibration_table_differs_from_host(clean):
    true = load_factory_calibration()
    true.values[4, 1:3] += 40.0  # IMU 4 accel x min/max shifted: offset +40 counts
    true.values[9, 7:9] *= 1.2  # IMU 9 mag x range 20 % wider
    other = simulate(seed=3, noise=False, calibration=true)
    diff = other.raw.astype(int) - clean.raw.astype(int)
    changed = np.unique(np.nonzero(diff)[1])
    assert set(changed) <= {4, 9} and {4, 9} <= set(changed)
    # Decoded with the true table, the physics is the same.
    _, acc, mag, _ = calibrated(other)
    _, acc0, mag0, _ = calibrated(clean)
    assert np.abs(acc - acc0).max() < 1.5 and np.abs(mag - mag0).max() < 1.0


def test_injected_errors():
    r = simulate(duration_s=20.0, error_rate=0.01, seed=5)
    rate = r.errors.mean()
    assert 0.007 < rate < 0.013
    np.testing.assert_array_equal(decode_frames(r.frames).errors, r.errors)
    failed = r.raw.reshape(len(r.t), 18, 3, 3)[r.errors]
    assert (failed == 0).all(axis=-1).mean() == pytest.approx(0.5, abs=0.1)


def test_mag_disturbance_is_local_in_time_and_space():
    base = simulate(noise=False, duration_s=35.0)
    dist = simulate(noise=False, duration_s=35.0, mag_disturbance=True)
    (d,) = dist.disturbances
    delta = np.abs(dist.raw.astype(int) - base.raw.astype(int))[..., 3:6].max(axis=-1)
    inside = (dist.t > d.t0 + d.ramp_s) & (dist.t < d.t1 - d.ramp_s)
    outside = (dist.t < d.t0) | (dist.t > d.t1)
    assert delta[inside, 5].max() > 50  # the right forearm sees the magnet
    assert delta[outside].max() == 0
    assert delta[inside, 13].max() < delta[inside, 5].max() / 10  # the left foot hardly
