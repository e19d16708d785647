"""A live frame is a batch of one through the same orchestration: frame by frame and as one
batch, a recording gives the same numbers bit for bit — through a magnet (disturbance flags,
the heading trust, the hinge constraint), failed readings and a gyroscope pinned at full scale
(state-guard re-initialisations), for every filter."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from bpms.io.options import Options


@pytest.fixture(scope="module")
def hard():
    rec = simulate(12.0, seed=2, mag_disturbance=True)
    raw, errors = rec.raw.copy(), rec.errors.copy()
    raw[300:306, 7, 6:9] = 32767  # a pinned gyroscope: the guard re-initialises IMU 7
    errors[400:420, 4, 1] = True  # a failed magnetometer: its last good value is held
    return raw, errors


@pytest.mark.parametrize("algorithm", ["mahony", "observer", "adaptive", "vqf"])
def test_frame_by_frame_equals_one_batch(hard, algorithm):
    raw, errors = hard
    options = Options()
    options.filter.algorithm = algorithm
    batch = BodyPoseProcessor(options=options).process(raw, errors)
    live = BodyPoseProcessor(options=options)
    frames = [live.step(raw[k], errors[k]) for k in range(len(raw))]
    if algorithm == "mahony":
        assert batch.reinit_count.sum() >= 1  # the guard had something to do
    assert batch.disturbance.mag.any()  # and the detector
    for name in ("R", "euler", "C", "euler_output", "joint_angles", "joint_positions",
                 "reinitialised", "corrected", "estimates"):
        one_by_one = np.concatenate([getattr(r, name) for r in frames])
        np.testing.assert_array_equal(one_by_one, getattr(batch, name), err_msg=name)
    for name in ("mag", "acc", "mag_dev", "mag_heading_deg"):
        one_by_one = np.concatenate([getattr(r.disturbance, name) for r in frames])
        np.testing.assert_array_equal(one_by_one, getattr(batch.disturbance, name),
                                      err_msg=name)
