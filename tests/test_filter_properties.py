"""Property tests: however a stream is cut into calls, with whatever resets, gain changes and
failed sensors, the batch path, the chunked batch path and the live path agree exactly."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bpms.filter.bank import MahonyBank
from bpms.filter.calibration import SensorCalibration
from bpms.firmware.sim.session import simulate

N = 240


@pytest.fixture(scope="module")
def inputs():
    rec = simulate(duration_s=N * 0.02, seed=9)
    cal = SensorCalibration.from_table(rec.calibration)
    return (*cal.calibrate(rec.raw), cal.gravity)


events = st.lists(
    st.tuples(st.integers(0, N - 1), st.sampled_from(["reset_all", "reset_one", "gain"]),
              st.integers(0, 17), st.floats(0.0, 2.0)),
    max_size=6)
failures = st.lists(st.tuples(st.integers(0, N - 1), st.integers(1, 20), st.integers(0, 17),
                              st.integers(0, 2)), max_size=5)
cuts = st.lists(st.integers(1, N - 1), max_size=6, unique=True)


@settings(deadline=None, max_examples=40)
@given(events=events, failures=failures, cuts=cuts)
def test_batch_chunks_and_live_agree(inputs, events, failures, cuts):
    acc, mag, gyr, gravity = inputs
    errors = np.zeros((N, 18, 3), bool)
    for start, length, imu, sensor in failures:
        errors[start:start + length, imu, sensor] = True
    resets = np.zeros((N, 18), bool)
    params = np.tile([0.02, 2e-5, 1.2, 2e-5, 0.02], (N, 1))
    by_frame: dict[int, list] = {}
    for k, kind, imu, value in sorted(events, key=lambda e: e[0]):  # stable: list order
        by_frame.setdefault(k, []).append((kind, imu, value))
        if kind == "reset_all":
            resets[k] = True
        elif kind == "reset_one":
            resets[k, imu] = True
        else:
            params[k:, 2] = value  # kp_yaw from frame k on
    whole = MahonyBank(gravity).process(acc, mag, gyr, errors, resets, params, store_terms=True)

    # chunked: events applied through the bank's controls at chunk starts or via arrays
    bank = MahonyBank(gravity)
    parts = []
    bounds = [0, *sorted(cuts), N]
    for lo, hi in itertools.pairwise(bounds):
        parts.append(bank.process(acc[lo:hi], mag[lo:hi], gyr[lo:hi], errors[lo:hi],
                                  resets[lo:hi], params[lo:hi], store_terms=True))
    for name in ("R", "euler", "w_i", "w_p"):
        np.testing.assert_array_equal(np.concatenate([getattr(p, name) for p in parts]),
                                      getattr(whole, name))

    live = MahonyBank(gravity)
    for k in range(N):
        for kind, imu, value in by_frame.get(k, []):
            if kind == "reset_all":
                live.reset()
            elif kind == "reset_one":
                live.reset(imu)
            else:
                live.set_gains(kp_yaw=value)
        out = live.process(acc[k:k + 1], mag[k:k + 1], gyr[k:k + 1], errors[k:k + 1],
                           store_terms=True)
        np.testing.assert_array_equal(out.R[0], whole.R[k])
        np.testing.assert_array_equal(out.w_i[0], whole.w_i[k])
    np.testing.assert_array_equal(live.held_count, bank.held_count)
