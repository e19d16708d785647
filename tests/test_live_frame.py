"""The single-call live frame (bpms.filter.live_frame) gives the general path's numbers bit for
bit, through the events that make a frame take the general path, and really is the path most
live frames take (issue 18.4: the recorder's CPU)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bpms.filter import live_frame
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from tests.test_kernels import _same

FULL_SCALE = 32767
FIELDS = ("t", "R", "euler", "C", "gyro_bias", "estimates", "reinitialised", "reinit_count",
          "corrected", "held_count", "euler_segment", "euler_output", "joint_angles",
          "joint_positions", "quaternions", "segment_quaternions")


@pytest.fixture(scope="module")
def hard_live():
    """30 s of the scripted motion with a magnet passing, 1 % failed readings and a gyroscope
    pinned at full scale for 4 frames (the state guard re-initialises filters)."""
    rec = simulate(30.0, seed=5, mag_disturbance=True, error_rate=0.01)
    raw = rec.raw.copy()
    raw[700:704, :, 6:9] = FULL_SCALE
    return raw, rec.errors


def _live(raw, errors, fast: bool, monkeypatch) -> tuple[list, BodyPoseProcessor, int]:
    """Every frame through ``step`` with a Reset Zero, a gain change, a manual reset and a
    frame without error flags; the fast path on or off. (results, processor, fast frames)"""
    taken = []
    original = live_frame.LiveFrame.step

    def counted(self, *args):
        taken.append(1)
        return original(self, *args)

    with monkeypatch.context() as m:
        m.setattr(live_frame.LiveFrame, "step", counted)
        if not fast:
            m.setattr(live_frame.LiveFrame, "usable", lambda self, *args: False)
        proc = BodyPoseProcessor()
        results = []
        for k in range(len(raw)):
            if k == 400:
                proc.reset_zero()
            if k == 900:
                proc.set_gains(kp_rollpitch=0.05, kp_yaw=2.0)
            if k == 1000:
                proc.reset_filter(3)
            results.append(proc.step(raw[k], None if k == 1100 else errors[k]))
    return results, proc, len(taken)


def test_the_live_frame_gives_the_general_numbers_bit_for_bit(hard_live, monkeypatch):
    raw, errors = hard_live
    fast, proc_f, taken = _live(raw, errors, True, monkeypatch)
    general, proc_g, none = _live(raw, errors, False, monkeypatch)
    assert none == 0
    # every frame takes the single call but the stream's first (it only initialises, and the
    # provisional Reset Zero captures there), the automatic capture (frame 49) and the
    # requested one (frame 400); the guard's re-initialisations stay on the single call
    assert len(raw) - taken == 3
    # the hard parts happened, so the comparison covers them
    assert proc_g.guard.count.sum() > 0
    assert any(r.disturbance.mag.any() for r in general)
    assert len(proc_g.pose.captures) >= 3
    for k, (a, b) in enumerate(zip(fast, general, strict=True)):
        for name in FIELDS:
            assert _same(np.asarray(getattr(a, name)), np.asarray(getattr(b, name))), (k, name)
        for f in dataclasses.fields(a.disturbance):
            assert _same(getattr(a.disturbance, f.name), getattr(b.disturbance, f.name)), \
                (k, f.name)
        assert [z.frame for z in a.zeros] == [z.frame for z in b.zeros]
        for za, zb in zip(a.zeros, b.zeros, strict=True):
            assert _same(za.R0, zb.R0) and za.yaw0 == zb.yaw0
    for x, y in zip(proc_f.bank.state.arrays(), proc_g.bank.state.arrays(), strict=True):
        assert _same(x, y)
    assert _same(proc_f.disturbance.state, proc_g.disturbance.state)
    assert _same(proc_f.disturbance.mag_count, proc_g.disturbance.mag_count)
    assert _same(proc_f.guard.expected, proc_g.guard.expected)
    assert _same(proc_f.pose._buffer, proc_g.pose._buffer)


def test_a_live_stream_equals_the_same_frames_filtered_as_a_batch(hard_live, monkeypatch):
    # One source of numbers: the live frames (mostly the single call) and one batch of the
    # same frames give the same outputs bit for bit, Reset Zero and re-initialisations included.
    raw, errors = hard_live
    n = 1200
    live, _, taken = _live(raw[:n], errors[:n], True, monkeypatch)
    assert taken > 0.9 * n
    proc = BodyPoseProcessor()
    batch_errors = errors[:n].copy()
    batch_errors[1100] = False
    first = proc.process(raw[:400], batch_errors[:400])
    second = proc.process(raw[400:900], batch_errors[400:900], zero_at=[0])
    proc.set_gains(kp_rollpitch=0.05, kp_yaw=2.0)
    third = proc.process(raw[900:1000], batch_errors[900:1000])
    proc.reset_filter(3)
    fourth = proc.process(raw[1000:n], batch_errors[1000:n])
    batch = [first, second, third, fourth]
    for name in ("R", "euler", "C", "euler_output", "joint_angles", "joint_positions",
                 "reinitialised", "corrected"):
        one = np.concatenate([getattr(r, name) for r in live])
        whole = np.concatenate([getattr(r, name) for r in batch])
        assert _same(one, whole), name


def test_wire_frames_decode_and_filter_as_the_general_path(hard_live, monkeypatch):
    from bpms.io.frames import FrameError, decode_frames, encode_frame

    raw, errors = hard_live
    n = 400
    raw = raw[:n].copy()
    errors = errors[:n].copy()
    rng = np.random.default_rng(3)
    raw[200:210] = rng.integers(-32768, 32768, size=(10, 18, 9))  # every bit pattern
    raw[210, :, 0] = -32768
    raw[211, :, 0] = 32767
    errors[220:230] = rng.random((10, 18, 3)) < 0.5
    wire = [encode_frame(raw[k], errors[k]) for k in range(n)]
    outputs = {}
    for fast in (True, False):
        with monkeypatch.context() as m:
            if not fast:
                m.setattr(live_frame.LiveFrame, "usable", lambda self, *args: False)
            proc = BodyPoseProcessor()
            outputs[fast] = [proc.step_wire(frame) for frame in wire]
    for k, ((a, raw_a, err_a), (b, raw_b, err_b)) in enumerate(zip(outputs[True],
                                                                  outputs[False], strict=True)):
        expected = decode_frames(wire[k])
        assert raw_a.dtype == np.int16 and np.array_equal(raw_a, expected.raw), k
        assert np.array_equal(err_a, expected.errors) and np.array_equal(raw_b, expected.raw)
        assert np.array_equal(err_b, expected.errors)
        assert np.array_equal(raw_a[0], raw[k]) and np.array_equal(err_a[0], errors[k])
        for name in FIELDS:
            assert _same(np.asarray(getattr(a, name)), np.asarray(getattr(b, name))), (k, name)
    # a frame without its end marker: the parser's error, nothing filtered
    proc = BodyPoseProcessor()
    proc.step_wire(wire[0])
    frames = proc.frames
    with pytest.raises(FrameError, match="markers"):
        proc.step_wire(wire[1][:-2] + b"xx")
    assert proc.frames == frames
