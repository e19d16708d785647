"""Gyro-bias and body-acceleration estimates on the processor's Result (issue 19.4)."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.filter.calibration import GYRO_RAD_S_PER_COUNT
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.motion import Move, Still
from bpms.firmware.sim.session import simulate
from bpms.io.frames import N_IMUS
from bpms.io.options import Options

IMU = 12
BIAS_COUNTS = 10


@pytest.fixture(scope="module")
def rec():
    script = [Still("still (start)", 8.0),
              Move("right arm forward raise", 2.0, {"sh_r_flex": 60}, hold=0.5),
              Move("right arm down", 2.0, hold=0.5)]
    rec = simulate(seed=5, script=script)
    rec.raw = rec.raw.copy()
    rec.raw[:, IMU, 8] += BIAS_COUNTS
    return rec


def _result(rec, algorithm):
    options = Options()
    options.filter.algorithm = algorithm
    proc = BodyPoseProcessor(rec.calibration, options)
    res = proc.process(rec.raw, rec.errors)
    _, _, gyr_biased = proc.calibrate(rec.raw)
    raw = rec.raw.copy()
    raw[:, IMU, 8] -= BIAS_COUNTS
    _, _, gyr = proc.calibrate(raw)
    # the injected bias in the filter frame: what the calibrated gyro reads too much
    return res, (gyr_biased - gyr)[0, IMU]


def test_adaptive_learns_the_injected_bias_at_rest(rec):
    res, injected = _result(rec, "adaptive")
    assert np.linalg.norm(injected) == pytest.approx(BIAS_COUNTS * GYRO_RAD_S_PER_COUNT)
    assert res.gyro_bias.shape == res.body_acc.shape == (len(res), N_IMUS, 3)
    k = np.searchsorted(res.t, 7.5)  # after 7.5 s of rest
    np.testing.assert_allclose(res.gyro_bias[k, IMU], injected, atol=np.radians(0.1))
    others = np.delete(res.gyro_bias[k], IMU, axis=0)
    assert np.abs(others).max() < np.radians(0.1)
    # at rest the body acceleration estimate is ≈ 0 (m/s², NED)
    assert np.abs(res.body_acc[k]).max() < 0.2


@pytest.mark.parametrize("algorithm", ["observer", "mahony"])
def test_bias_estimates_point_the_right_way(rec, algorithm):
    """The observer's integral and the original's −ωI move towards the injected bias."""
    res, injected = _result(rec, algorithm)
    assert res.gyro_bias.shape == (len(res), N_IMUS, 3)
    est = res.gyro_bias[-1, IMU]
    assert est @ injected > 0.0
    if algorithm == "observer":
        assert res.body_acc.shape == (len(res), N_IMUS, 3)
    else:
        assert res.body_acc is None


def test_vqf_reports_its_bias_estimate(rec):
    pytest.importorskip("vqf")
    res, injected = _result(rec, "vqf")
    assert res.body_acc is None and res.gyro_bias.shape == (len(res), N_IMUS, 3)
    assert res.gyro_bias[-1, IMU] @ injected > 0.0
    # live frame by frame gives the same estimates
    options = Options()
    options.filter.algorithm = "vqf"
    live = BodyPoseProcessor(rec.calibration, options)
    steps = np.array([live.step(rec.raw[k], rec.errors[k]).gyro_bias[0]
                      for k in range(0, 200)])
    np.testing.assert_allclose(steps, res.gyro_bias[:200], atol=1e-9)


def test_concatenated_parts_equal_one_pass(rec):
    from bpms.filter.processor import Result

    options = Options()
    options.filter.algorithm = "adaptive"
    whole = BodyPoseProcessor(rec.calibration, options).process(rec.raw, rec.errors)
    proc = BodyPoseProcessor(rec.calibration, options)
    parts = [proc.process(rec.raw[a:a + 100], rec.errors[a:a + 100])
             for a in range(0, len(rec.raw), 100)]
    joined = Result.concat(parts)
    for name in ("t", "R", "gyro_bias", "body_acc"):
        np.testing.assert_array_equal(getattr(joined, name), getattr(whole, name))
    np.testing.assert_array_equal(joined.disturbance.mag, whole.disturbance.mag)
    np.testing.assert_array_equal(joined.disturbance.mag_norm_ratio,
                                  whole.disturbance.mag_norm_ratio)
