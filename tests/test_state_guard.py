"""No silent NaN (issue 12.4): a filter state that stops being a rotation is caught in its
frame, that IMU re-initialised and counted; outputs never carry NaN for more than one frame."""

from __future__ import annotations

import numpy as np
import pytest
from pty_suit import suit_pty
from waiting import wait_until

from bpms.filter.guard import SO3_TOLERANCE, so3_error
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.arbiter import Arbiter, MotionSource
from bpms.io.filtered_file.reader import read_filtered
from bpms.io.options import SerialOptions
from bpms.pipeline.session import LiveSession
from bpms.pipeline.sources import SuitFrameSource

BURST = slice(150, 156)  # 6 frames (0.12 s) of absurd gyroscope readings
FULL_SCALE = 32767  # a gyroscope pinned at full scale: ≈ 40 rad/s, 0.8 rad per 20 ms step


@pytest.fixture(scope="module")
def clean():
    return MotionSource.simulated(seed=5, duration_s=12.0)


@pytest.fixture(scope="module")
def absurd(clean):
    raw = clean.raw.copy()
    raw[BURST, :, 6:9] = FULL_SCALE
    return MotionSource(raw, clean.errors)


def _longest_nan_run(finite: np.ndarray) -> int:
    """Longest run of non-finite frames per IMU after the IMU's first finite one."""
    longest = 0
    for i in range(finite.shape[1]):
        col = finite[:, i]
        run = 0
        for ok in col[int(np.argmax(col)):]:
            run = 0 if ok else run + 1
            longest = max(longest, run)
    return longest


def test_the_unguarded_state_really_leaves_so3():
    # Independent of the guard: one filter step with the pinned gyro through the kernel's own
    # renormalisation leaves a DCM that is no rotation (so the guard has something to catch).
    from bpms.filter.bank import MahonyBank
    from bpms.filter.calibration import GYRO_RAD_S_PER_COUNT

    bank = MahonyBank(np.full(1, 256.0))
    acc, mag = np.array([[0.0, 0.0, 256.0]]), np.array([[60.0, 0.0, 80.0]])
    bank.process(acc[None], mag[None], np.zeros((1, 1, 3)))
    w = np.full((1, 1, 3), FULL_SCALE * GYRO_RAD_S_PER_COUNT)
    out = bank.process(acc[None], mag[None], w)
    assert so3_error(out.R[0, 0]) > SO3_TOLERANCE


@pytest.mark.parametrize("dps", [300.0, 800.0, 1500.0, 2000.0])
def test_fast_real_turns_are_no_event(dps):
    # The DCM filter's first-order renormalisation leaves ‖RᵀR − I‖ above 1e-3 when it turns
    # fast (3.7e-3 at 500 °/s); a fast but real motion up to the gyroscope's full scale
    # (2000 °/s) must not count as a broken state.
    from bpms.filter.bank import MahonyBank
    from bpms.filter.guard import StateGuard, guarded_process

    n = 200
    acc = np.tile([0.0, 0.0, 256.0], (n, 1, 1))
    mag = np.tile([60.0, 0.0, 80.0], (n, 1, 1))
    gyr = np.tile(np.radians(dps) * np.array([0.6, 0.0, 0.8]), (n, 1, 1))
    gyr[:20] = 0.0
    plain = MahonyBank(np.full(1, 256.0)).process(acc, mag, gyr)
    assert so3_error(plain.R).max() > SO3_TOLERANCE or dps < 500
    guard = StateGuard(1)
    out, flags = guarded_process(MahonyBank(np.full(1, 256.0)), guard, acc, mag, gyr)
    assert not flags.any() and guard.count.sum() == 0
    np.testing.assert_array_equal(out.R, plain.R)


def test_live_session_recovers_within_one_second_and_counts(absurd, clean, tmp_path):
    arbiter = Arbiter(absurd, realtime=False)
    with suit_pty(arbiter) as (_server, pty_path):
        session = LiveSession(SuitFrameSource(pty_path, SerialOptions()),
                              recording_dir=tmp_path)
        sub = session.subscribe(maxlen=100_000)
        session.source.connect()
        recording = session.start_logging(raw=False, filtered=True, name="guard")
        session.start()
        try:
            assert wait_until(lambda: session.status().processed >= 400, 60)
        finally:
            session.stop()
        # after the stop: the status counts exactly the frames the subscriber got (read while
        # streaming, it could count a later pass of the looping motion's burst)
        status = session.status()
    delivered = sub.drain()
    samples = delivered[:400]
    euler = np.array([s.euler for s in samples])
    flags = np.array([s.reinitialised for s in samples])
    finite = np.isfinite(euler).all(axis=2)
    # every flagged frame lies inside the burst (plus the frame after it at most)
    flagged = np.flatnonzero(flags.any(axis=1))
    assert len(flagged) and flagged.min() >= BURST.start and flagged.max() <= BURST.stop
    # counted per IMU, in the status and as an event
    assert status.reinit_count == np.array([s.reinitialised for s in delivered]).sum() > 0
    assert any("re-initialised" in e for e in status.events)
    # outputs never carry NaN for more than one frame, and NaN only at flagged frames
    assert _longest_nan_run(finite) <= 1
    start = int(np.argmax(finite.all(axis=1)))
    assert not (~finite[start:] & ~flags[start:]).any()
    # within 1 s (50 frames) after sane input every IMU gives finite angles that agree with
    # the run that never saw the burst (the re-initialisation aligned it from acc and mag)
    after = BURST.stop + 50
    assert finite[after:].all()
    reference = BodyPoseProcessor().process(clean.raw[:400], clean.errors[:400]).euler
    diff = np.angle(np.exp(1j * (euler[after:] - reference[after:])))
    assert np.degrees(np.abs(diff)).max() < 5.0
    # the filtered file: no NaN row beyond the frames of the events
    written = read_filtered(recording.filtered_path).euler[:400]
    nan_rows = np.flatnonzero(~np.isfinite(written).all(axis=(1, 2)))
    assert set(nan_rows) <= set(flagged) | set(range(start))


def test_batch_and_frame_by_frame_agree_through_the_events(absurd):
    raw, errors = absurd.raw[:300], absurd.errors[:300]
    batch = BodyPoseProcessor().process(raw, errors)
    live = BodyPoseProcessor()
    steps = [live.step(raw[k], errors[k]) for k in range(len(raw))]
    np.testing.assert_array_equal(np.concatenate([s.euler for s in steps]), batch.euler)
    np.testing.assert_array_equal(np.concatenate([s.reinitialised for s in steps]),
                                  batch.reinitialised)
    np.testing.assert_array_equal(live.reinit_count, batch.reinit_count)
    assert batch.reinitialised.shape == (300, 18)
    assert batch.reinit_count.sum() == batch.reinitialised.sum() > 0


@pytest.mark.parametrize("live", [False, True])
def test_non_finite_input_is_held_and_a_poisoned_state_is_caught(clean, live):
    raw = clean.raw[:200].astype(np.float64)
    raw[80:83, 4, 0:3] = np.nan  # non-finite accelerometer through the API
    proc = BodyPoseProcessor()

    def run(block):
        if not live:
            return proc.process(block)
        parts = [proc.step(f) for f in block]
        return parts, np.concatenate([p.euler for p in parts]), np.concatenate(
            [p.reinitialised for p in parts])

    first = run(raw[:120])
    euler = first[1] if live else first.euler
    # the NaN never reaches the state: the last good accelerometer value is held, counted
    assert np.isfinite(euler[1:]).all()
    assert proc.bank.held_count[4, 0] == 3 and proc.reinit_count.sum() == 0
    proc.bank.state.R[9] = np.nan  # poison a filter state directly
    second = run(raw[120:])
    euler, flags = (second[1], second[2]) if live else (second.euler, second.reinitialised)
    assert flags[0, 9] and flags.sum() == 1  # caught in the same frame, counted once
    assert not np.isfinite(euler[0, 9]).all() and np.isfinite(euler[0, :9]).all()
    assert np.isfinite(euler[1:]).all()  # one frame of NaN, never more
    assert proc.reinit_count[9] == 1


def test_factory_run_has_no_events(clean):
    result = BodyPoseProcessor().process(clean.raw, clean.errors)
    assert not result.reinitialised.any() and result.reinit_count.sum() == 0


@pytest.mark.parametrize("algorithm", ["mahony", "observer", "adaptive", "vqf"])
def test_every_filter_rewinds_exactly_and_is_guarded(clean, algorithm):
    from dataclasses import replace

    from bpms.filter.algorithms import make_bank
    from bpms.io.options import FilterOptions

    proc = BodyPoseProcessor()
    acc, mag, gyr = proc.calibrate(clean.raw[:300])
    bank = make_bank(proc.sensor_calibration.gravity, replace(FilterOptions(),
                                                               algorithm=algorithm))
    bank.process(acc[:100], mag[:100], gyr[:100])
    snap = bank.snapshot()
    first = bank.process(acc[100:], mag[100:], gyr[100:]).R
    bank.restore(snap)
    np.testing.assert_array_equal(bank.process(acc[100:], mag[100:], gyr[100:]).R, first)
    # and a poisoned state in the middle of a batch is caught in its frame
    proc.select_filter(algorithm)
    proc.process(clean.raw[:100], clean.errors[:100])
    if algorithm == "mahony":
        proc.bank.state.R[5] *= 3.0
    elif algorithm in ("observer", "adaptive"):
        proc.bank.state.q[5] = np.nan
    else:
        state = proc.bank.vqf.filters[5].state
        state["gyrQuat"] = np.full(4, np.nan)
        proc.bank.vqf.filters[5].state = state
    result = proc.process(clean.raw[100:300], clean.errors[100:300])
    assert result.reinitialised[:2, 5].any() and result.reinit_count[5] == 1
    assert np.isfinite(result.euler[2:]).all()
