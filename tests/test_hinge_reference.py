"""The hinge-joint heading constraint's numba kernel against its slow, readable reference
(tests/reference_hinge.py, written from the documented steps) on the simulated suit walking
past a magnet (issue 46.3): flagged and clean magnetometers (σ growing and fading, the clean
offset held), a flag without a heading deviation, unknown attitudes (an IMU not yet
initialised, a lost one), joints too slow to teach the axis and fast enough to; turns and the
turned R and C to 1e-9, in one batch and frame by frame."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.filter.hinge import H_JD, H_JP, H_OFFSET, HINGES, HingeConstraint
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from tests.reference_hinge import ReferenceHinges

N = 600
TOL = 1e-9


@pytest.fixture(scope="module")
def inputs():
    rec = simulate(duration_s=N * 0.02, seed=4, mag_disturbance=True)
    proc = BodyPoseProcessor(rec.calibration)
    res = proc.process(rec.raw, rec.errors)
    _, _, gyr = proc.sensor_calibration.calibrate(rec.raw)
    R, C = np.array(res.R, float), np.array(res.C, float)
    flag = np.array(res.disturbance.mag, bool)
    heading = np.array(res.disturbance.mag_heading_deg, float)
    R[100:130, 5] = np.nan  # the right forearm's attitude lost for 0.6 s
    C[:40, 11] = np.nan  # the left forearm's segment unknown at first (its hinge waits)
    flag[200:320, 2] = True  # the right shank flagged for 2.4 s …
    heading[200:260, 2] = 35.0  # … with a 35° field deviation, then none known
    heading[260:320, 2] = np.nan
    flag[350:400, [0, 4]] = True  # a thigh and an upper arm flagged
    heading[350:400, [0, 4]] = [[12.0, -20.0]]
    flag[420:470, 14] = True  # the left shank flagged with no heading deviation known
    heading[420:470, 14] = np.nan
    # joint motion (the simulated script holds these joints still here): the right forearm
    # turning at 0.45 rad/s (between the teaching threshold and twice it), the left shank fast,
    # the right thigh while its shank is flagged (no teaching then)
    gyr = gyr.copy()
    gyr[150:190, 5] += [0.0, 0.45, 0.0]
    gyr[450:480, 14] += [0.0, 1.2, 0.0]
    gyr[210:240, 0] += [0.0, 0.9, 0.0]
    assert flag.any(axis=0)[[0, 2, 4]].all()
    return R, C, gyr, flag, heading


def _reference(R, C, gyr, flag, heading, ref=None):
    ref = ref or ReferenceHinges(HINGES.tolist(), 0.02)
    turns, Rs, Cs = [], [], []
    for t in range(len(R)):
        turn, R2, C2 = ref.step(R[t].tolist(), C[t].tolist(), gyr[t].tolist(),
                                flag[t].tolist(), heading[t].tolist())
        turns.append(turn)
        Rs.append(R2)
        Cs.append(C2)
    return np.array(turns), np.array(Rs), np.array(Cs)


def test_kernel_equals_the_reference(inputs):
    R, C, gyr, flag, heading = inputs
    ref = ReferenceHinges(HINGES.tolist(), 0.02)
    want_turn, want_R, want_C = _reference(R, C, gyr, flag, heading, ref)
    assert np.abs(want_turn).max() > 1e-3  # the constraint had something to do
    kernel = HingeConstraint(0.02)
    got_turn = kernel.turns(R, C, gyr, flag, heading)
    np.testing.assert_allclose(got_turn, want_turn, atol=TOL, rtol=0)
    # the state: each segment's σ and each hinge's learnt axis in both sensors' axes
    np.testing.assert_allclose(kernel.state.sigma, ref.sigma, atol=TOL, rtol=0)
    for h, state in enumerate(ref.state):
        np.testing.assert_allclose(kernel.state.hinges[h, H_JP:H_JP + 3], state.jp, atol=TOL)
        np.testing.assert_allclose(kernel.state.hinges[h, H_JD:H_JD + 3], state.jd, atol=TOL)
        assert kernel.state.hinges[h, H_OFFSET] == pytest.approx(state.offset, abs=TOL)
    got_R, got_C = HingeConstraint(0.02).apply(R, C, gyr, flag, heading)
    np.testing.assert_allclose(got_R, want_R, atol=TOL, rtol=0)
    np.testing.assert_allclose(got_C, want_C, atol=TOL, rtol=0)
    # frame by frame (the live path): the same
    live = HingeConstraint(0.02)
    one_by_one = np.concatenate([live.turns(R[t:t + 1], C[t:t + 1], gyr[t:t + 1],
                                            flag[t:t + 1], heading[t:t + 1])
                                 for t in range(len(R))])
    np.testing.assert_allclose(one_by_one, want_turn, atol=TOL, rtol=0)
