"""The arbiter emulator's protocol state machine (transport-independent), on a manual clock."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.firmware.sim.arbiter import Arbiter, Faults, MotionSource
from bpms.io.frames import FRAME_SIZE, decode_frames, encode_frame
from bpms.io.parser import FrameParser


class Clock:
    """A clock the test moves by hand."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture(scope="module")
def source() -> MotionSource:
    rng = np.random.default_rng(0)
    return MotionSource(rng.integers(-500, 500, size=(40, 18, 9)).astype(np.int16))


def make(source, **kw) -> tuple[Arbiter, Clock]:
    clock = Clock()
    return Arbiter(source, clock=clock, **kw), clock


def run_for(arb: Arbiter, clock: Clock, seconds: float, step: float = 0.005) -> bytes:
    out = bytearray()
    end = clock.now + seconds
    while clock.now < end - 1e-9:
        clock.now = min(clock.now + step, end)
        out += b"".join(arb.poll())
    return bytes(out)


def test_identify_and_battery(source):
    arb, clock = make(source, battery_v=3.35, battery_drain_v_per_h=0.2)
    arb.receive(b"\x02\x01")
    assert b"".join(arb.poll()) == b"BPMS" + b"V3.35\n"
    clock.now += 1800
    arb.receive(b"\x01")
    assert b"".join(arb.poll()) == b"V3.25\n"
    clock.now += 100 * 3600
    arb.receive(b"\x01")
    assert b"".join(arb.poll()) == b"V2.60\n"  # regulator cut-off: never below
    arb.receive(b"\x07\xff")
    assert arb.poll() == [] and arb.stats.ignored_bytes == 2


def test_stream_stale_first_frame_and_numbering(source):
    arb, clock = make(source)
    arb.receive(b"\x00")
    data = run_for(arb, clock, 0.21)  # frames due at 0, 20, ..., 200 ms
    frames = FrameParser().feed(data + b"$")
    assert len(frames) == 11
    zero = decode_frames(frames[0])
    assert not zero.raw.any() and not zero.errors.any()  # power-up: an all-zero reading
    for j, frame in enumerate(frames[1:]):
        assert frame == source.frame(j)
    # Any byte stops; the next start's stale frame repeats the last reading sent.
    arb.receive(b"\x02")
    assert b"".join(arb.poll()) == b"BPMS"
    assert run_for(arb, clock, 0.1) == b""
    arb.receive(b"\x00")
    frames = FrameParser().feed(run_for(arb, clock, 0.05) + b"$")
    assert frames[0] == source.frame(9) and frames[1] == source.frame(10)
    st = arb.stats
    assert (st.starts, st.stops, st.stale_frames) == (2, 1, 2)
    assert st.frames_sent == 11 + 3 and arb.motion_index == 12


def test_start_while_streaming_restarts_with_a_stale_frame(source):
    arb, clock = make(source)
    arb.receive(b"\x00")
    run_for(arb, clock, 0.05)
    arb.receive(b"\x00")
    frames = FrameParser().feed(b"".join(arb.poll()) + b"$")
    assert frames[0] == source.frame(arb.motion_index - 1)  # stale repeat, at once
    assert arb.stats.stale_frames == 2 and arb.streaming


def test_motion_source_loops(source):
    arb, _ = make(source, realtime=False)
    arb.receive(b"\x00")
    frames = []
    while len(frames) < 1 + 2 * len(source) + 1:
        frames += FrameParser().feed(b"".join(arb.poll(max_frames=7)) + b"$")
    assert frames[1 + len(source)] == source.frame(0) == frames[1]


def test_absolute_deadlines_do_not_drift(source):
    arb, clock = make(source)
    arb.receive(b"\x00")
    rng = np.random.default_rng(1)
    total = 0
    for _ in range(300):  # irregular, sometimes late, polling over ≈ 10 s
        clock.now += float(rng.uniform(0.0, 0.067))
        total += len(b"".join(arb.poll()))
    elapsed = clock.now - 1000.0
    assert total == FRAME_SIZE * (int(elapsed / 0.02 + 1e-9) + 1)


def test_fast_mode_respects_the_cap(source):
    arb, _ = make(source, realtime=False)
    arb.receive(b"\x00")
    assert len(arb.poll(max_frames=5)) == 5
    assert arb.poll(max_frames=0) == []
    assert len(arb.poll(max_frames=3)) == 3


def test_error_bits_injected_and_counted(source):
    arb, _ = make(source, realtime=False, faults=Faults(error_rate=0.02), seed=4)
    arb.receive(b"\x00")
    data = b"".join(b"".join(arb.poll(max_frames=50)) for _ in range(20))
    frames = FrameParser().feed(data + b"$")
    dec = decode_frames(b"".join(frames[1:]))
    assert dec.errors.sum() == arb.stats.error_flags > 0
    assert (dec.raw.reshape(-1, 18, 3, 3)[dec.errors] == 0).all()


def test_dropped_and_corrupted_bytes_are_seen_by_the_parser(source):
    faults = Faults(drop_rate=0.1, corrupt_rate=0.05)
    arb, _ = make(source, realtime=False, faults=faults, seed=2)
    arb.receive(b"\x00")
    parser = FrameParser()
    frames = []
    for _ in range(40):
        frames += parser.feed(b"".join(arb.poll(max_frames=25)))
    frames += parser.flush()
    st = arb.stats
    assert st.frames_with_dropped_bytes > 50 and st.corrupted_frames > 20
    # Every frame that lost bytes is lost; corrupted ones survive unless a marker was hit.
    assert len(frames) <= st.frames_sent - st.frames_with_dropped_bytes
    assert len(frames) >= st.frames_sent - st.frames_with_dropped_bytes - st.corrupted_frames
    assert parser.stats.resyncs >= 0.8 * st.frames_with_dropped_bytes


def test_bursty_delivery_keeps_order_and_bounds_delay(source):
    arb, clock = make(source, faults=Faults(bursty=True, burst_prob=0.1), seed=3)
    arb.receive(b"\x00")
    t_start = clock.now
    arrivals = []
    parser = FrameParser()
    while clock.now < t_start + 20.0:
        clock.now += 0.001
        for chunk in arb.poll():
            for frame in parser.feed(chunk):
                arrivals.append((clock.now, frame))
    frames = [f for _, f in arrivals]
    for j, frame in enumerate(frames[1:50]):
        assert frame == source.frame(j)  # order kept
    delays = [t - (t_start + k * 0.02) for k, (t, _) in enumerate(arrivals)]
    assert max(delays) <= 0.3 + 0.002 and min(delays) >= 0.0
    gaps = np.diff([t for t, _ in arrivals])
    assert (gaps < 0.0015).mean() > 0.2  # bursts: many frames arrive back to back
    assert gaps.max() > 0.05  # and there are holds


def test_silence_loses_frames_and_ignores_the_host(source):
    arb, clock = make(source, faults=Faults(silence_at_s=0.5, silence_s=1.0))
    arb.receive(b"\x00")
    before = run_for(arb, clock, 0.5)
    assert len(before) == FRAME_SIZE * 25
    during = run_for(arb, clock, 0.3)
    arb.receive(b"\x02")  # ignored: the link is down
    during += run_for(arb, clock, 0.7)
    assert during == b"" and arb.stats.silenced_bytes_in == 1
    after = FrameParser().feed(run_for(arb, clock, 0.2) + b"$")
    assert len(after) == 10 and after[0] == source.frame(24)  # numbering: emitted frames only
    assert arb.stats.silenced_frames == 50


def test_host_disconnect_stops_the_stream(source):
    arb, clock = make(source)
    arb.receive(b"\x00")
    run_for(arb, clock, 0.1)
    arb.host_disconnected()
    assert not arb.streaming and run_for(arb, clock, 0.1) == b""


def test_motion_source_frames_match_encoder():
    rng = np.random.default_rng(2)
    raw = rng.integers(-3000, 3000, size=(5, 18, 9)).astype(np.int16)
    err = rng.random((5, 18, 3)) < 0.1
    src = MotionSource(raw, err)
    assert src.frame(7) == encode_frame(raw[2], err[2])
    sim = MotionSource.simulated(duration_s=1.0)
    assert len(sim) == 50 and sim.frame(3) == encode_frame(*sim.reading(3))
