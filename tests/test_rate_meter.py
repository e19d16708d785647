"""The reception-rate meter (bpms.pipeline.rate.RateMeter) under the suit's real delivery.

The suit makes one frame every 20 ms (SPEC §1: 50 Hz); Bluetooth delays each by a few ms up to
300 ms and hands them to the host in bursts. The session marks each burst with its frame count
(``mark(len(events))``). The health panel turns amber below 45 Hz (bpms.gui.health.DEGRADED_HZ),
so the meter must read the steady 50 Hz through the bursts. Every clock here is injected: no
wall time is read, so the test means the same on a loaded machine.

The expected values are worked out here from the delivery model, not from the meter."""

from __future__ import annotations

import random

import pytest

from bpms.pipeline.rate import RateMeter

PERIOD_S = 0.02  # SPEC §1: one frame every 20 ms


def bursty_arrivals(seconds: float, seed: int, max_delay_s: float = 0.3,
                    read_every_s: float = 0.1) -> list[tuple[float, int]]:
    """(host time, frames in this read) for a 50 Hz suit over ``seconds``: frame i is made at
    i * 20 ms and reaches the host after a random delay of up to ``max_delay_s`` without
    overtaking the one before (a serial stream keeps order); the host reads every
    ``read_every_s`` and gets every frame arrived since the last read."""
    rng = random.Random(seed)
    arrivals = []
    last = 0.0
    for i in range(int(seconds / PERIOD_S)):
        last = max(last, i * PERIOD_S + rng.uniform(0.0, max_delay_s))
        arrivals.append(last)
    reads: list[tuple[float, int]] = []
    t = read_every_s
    k = 0
    while k < len(arrivals):
        n = 0
        while k < len(arrivals) and arrivals[k] <= t:
            n += 1
            k += 1
        if n:
            reads.append((t, n))
        t += read_every_s
    return reads


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_steady_50_hz_through_bluetooth_bursts(seed):
    """After the first full window the meter reads 50 Hz within 10 % at every read and between
    reads, never below the health panel's 45 Hz alarm: bursts do not raise a false alarm."""
    meter = RateMeter(window_s=5.0)
    reads = bursty_arrivals(30.0, seed)
    assert sum(n for _, n in reads) == 1500  # the model itself: 30 s at 50 Hz
    assert max(n for _, n in reads) >= 10, "the model must deliver real bursts"
    readings = []
    for t, n in reads:
        meter.mark(n, now=t)
        if t >= 6.0:
            readings.append(meter.rate_hz(now=t))
            readings.append(meter.rate_hz(now=t + 0.05))  # halfway to the next read
    assert readings
    assert min(readings) >= 45.0, min(readings)
    assert max(readings) <= 55.0, max(readings)
    assert sum(readings) / len(readings) == pytest.approx(50.0, rel=0.02)


def test_long_bursts_average_out():
    """One burst of 25 frames every 500 ms (a congested link): still 50 Hz within 10 %."""
    meter = RateMeter(window_s=5.0)
    readings = []
    for k in range(1, 41):
        t = 0.5 * k
        meter.mark(25, now=t)
        if t > 6.0:
            readings.append(meter.rate_hz(now=t))
    # by hand: at a burst the window [t-5, t] holds 11 bursts = 275 frames over 5 s:
    # (275 - 1) / 5 = 54.8 Hz
    assert readings[-1] == pytest.approx(274 / 5.0)
    assert all(45.0 <= r <= 55.0 for r in readings)


def test_counts_every_frame_of_a_burst():
    """mark(count) counts count frames: 3 reads of 10 frames 0.2 s apart are 29 intervals over
    0.4 s of span = 72.5 Hz (the rate of the frames seen, with no alarm smoothing)."""
    meter = RateMeter(window_s=5.0)
    for t in (0.0, 0.2, 0.4):
        meter.mark(10, now=t)
    assert meter.rate_hz(now=0.4) == pytest.approx(29 / 0.4)


def test_a_slow_link_reads_slow():
    """A suit reaching the host at 25 Hz (half the frames lost) reads 25 Hz, under the alarm."""
    meter = RateMeter(window_s=5.0)
    for i in range(1, 501):
        meter.mark(1, now=i * 0.04)
    assert meter.rate_hz(now=20.0) == pytest.approx(25.0, rel=0.01)


def test_silence_brings_the_rate_down_and_then_to_zero():
    """When frames stop, the rate falls (the span grows to now) and reads 0 once the last
    frame is older than the window."""
    meter = RateMeter(window_s=5.0)
    for i in range(1, 501):
        meter.mark(1, now=i * PERIOD_S)  # 10 s at 50 Hz
    assert meter.rate_hz(now=10.0) == pytest.approx(50.0, rel=0.01)
    # 2 s later: window [7, 12] holds the frames of (7, 10]: 150 frames -> 149 / 5 s
    assert meter.rate_hz(now=12.0) == pytest.approx(149 / 5.0, rel=0.02)
    assert meter.rate_hz(now=15.5) == 0.0
    assert meter.rate_hz(now=100.0) == 0.0


def test_too_few_frames_read_zero():
    meter = RateMeter(window_s=5.0)
    assert meter.rate_hz(now=0.0) == 0.0
    meter.mark(1, now=1.0)
    assert meter.rate_hz(now=1.0) == 0.0
    meter.mark(1, now=1.02)
    assert meter.rate_hz(now=1.02) == pytest.approx(50.0)


def test_the_window_length_is_honoured():
    """A 1 s window forgets a burst 1.5 s old: 50 Hz for the last second only."""
    meter = RateMeter(window_s=1.0)
    meter.mark(100, now=0.0)  # a stale burst
    for i in range(1, 101):
        meter.mark(1, now=1.0 + i * PERIOD_S)
    assert meter.rate_hz(now=3.0) == pytest.approx(50.0, rel=0.03)


def test_the_defaults_a_5_s_window_and_one_frame_a_mark():
    """The session's meter is RateMeter() and marks each read: a burst 5.5 s old is out of
    its window; mark() counts one frame."""
    meter = RateMeter()
    meter.mark(100, now=0.0)  # a stale burst, 5.5 s before the reading
    for i in range(1, 256):
        meter.mark(now=0.5 + i * PERIOD_S)  # 50 Hz from 0.52 s to 5.6 s
    # by hand: the window [0.6, 5.6] holds frames 5..255 (251 frames) over 5 s → 50 Hz
    assert meter.rate_hz(now=5.6) == pytest.approx(250 / 5.0, rel=1e-9)


def test_one_burst_alone_is_no_rate_yet():
    """Frames that all arrived at one instant, read at that instant: no span, 0 Hz (not a
    division by zero, not a made-up rate)."""
    meter = RateMeter()
    meter.mark(12, now=3.0)
    assert meter.rate_hz(now=3.0) == 0.0


def test_the_span_runs_from_the_oldest_frame_to_now():
    """Two frames 1 s apart read 2 s after the second: 1 interval over 3 s."""
    meter = RateMeter()
    meter.mark(now=10.0)
    meter.mark(now=11.0)
    assert meter.rate_hz(now=13.0) == pytest.approx(1 / 3.0, rel=1e-12)


def test_the_host_clock_by_default():
    """Without ``now`` the meter reads the host's monotonic clock (as the session calls it)."""
    import time

    meter = RateMeter()
    start = time.monotonic()
    meter.mark(now=start - 1.0)
    meter.mark()
    rate = meter.rate_hz()
    elapsed = time.monotonic() - start
    assert 1 / (1.0 + elapsed) <= rate <= 1.0 + 1e-9
