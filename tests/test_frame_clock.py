"""The de-jittered frame clock on synthetic Bluetooth-like arrival times (truth: the sampling
times the synthetic suit used)."""

from __future__ import annotations

import numpy as np

from bpms.pipeline.frame_clock import FrameClock

T = 0.02


def bluetooth_arrivals(n, rng, t0=1000.0, drift_ppm=0.0, burst_every=50, burst_len=12):
    """True sampling times and arrival times: exponential delays (≤ 300 ms) plus bursts where
    the link holds frames back and releases them at once."""
    true = t0 + np.arange(n) * T * (1 + drift_ppm * 1e-6)
    delay = np.minimum(rng.exponential(0.02, n), 0.3)
    arrival = true + delay
    for start in range(burst_every, n - burst_len, burst_every):
        release = arrival[start + burst_len - 1] + 0.05
        arrival[start:start + burst_len] = release  # all delivered together, ≤ 300 ms late
    arrival = np.maximum.accumulate(arrival)  # a serial link keeps order
    assert (arrival - true).max() <= 0.4
    return true, arrival


def run(clock, arrivals, indices=None, discontinuities=()):
    indices = np.arange(len(arrivals)) if indices is None else indices
    return np.array([clock.stamp(int(i), float(a), k in discontinuities)
                     for k, (i, a) in enumerate(zip(indices, arrivals, strict=True))])


def test_jittered_arrivals_give_stamps_on_the_sampling_grid():
    rng = np.random.default_rng(1)
    true, arrival = bluetooth_arrivals(3000, rng)
    stamps = run(FrameClock(T), arrival)
    assert np.all(np.diff(stamps) > 0)
    raw_err = np.abs(arrival - true)[100:]
    err = np.abs(stamps - true)[100:]
    assert raw_err.max() > 0.1  # the receive times really jitter
    assert err.max() < 0.003  # the clock is within 3 ms of the sampling times
    # regular: after settling every step is the period
    np.testing.assert_allclose(np.diff(stamps)[200:], T, atol=0.002)


def test_link_delay_is_subtracted():
    rng = np.random.default_rng(2)
    true, arrival = bluetooth_arrivals(1000, rng)
    delay = 0.075
    stamps = run(FrameClock(T, link_delay=delay), arrival + delay)
    assert np.abs(stamps - true)[100:].max() < 0.003


def test_crystal_drift_is_followed_both_ways():
    for ppm in (-200.0, 200.0):
        rng = np.random.default_rng(3)
        true, arrival = bluetooth_arrivals(15000, rng, drift_ppm=ppm)  # 5 minutes
        stamps = run(FrameClock(T), arrival)
        assert np.all(np.diff(stamps) > 0)
        assert np.abs(stamps - true)[100:].max() < 0.006, ppm


def test_lost_frames_and_reconnection_reanchor():
    rng = np.random.default_rng(4)
    true, arrival = bluetooth_arrivals(2000, rng)
    # frames 800..849 never arrive; the live index counts accepted frames only
    keep = np.r_[0:800, 850:2000]
    clock = FrameClock(T)
    stamps = run(clock, arrival[keep], np.arange(len(keep)))
    after = np.flatnonzero(keep >= 850)
    err = np.abs(stamps - true[keep])
    assert np.all(np.diff(stamps) > 0)
    assert err[after[200:]].max() < 0.003  # back on the grid within a few blocks
    # a reconnection: the source restarts its count, flagged as a discontinuity
    clock2 = FrameClock(T)
    s1 = run(clock2, arrival[:500])
    s2 = run(clock2, arrival[600:1500], np.arange(900), discontinuities={0})
    assert s2[0] > s1[-1] and clock2.reanchors == 1
    assert np.abs(s2 - true[600:1500])[100:].max() < 0.003


def test_a_silent_link_with_a_continuing_count_is_caught_within_a_few_frames():
    """The live index counts accepted frames: after 3 s of silence the count goes on while
    the sampling time jumped. Stamps must follow within ``late_frames`` frames, not wait for a
    block."""
    rng = np.random.default_rng(5)
    true, arrival = bluetooth_arrivals(1500, rng)
    keep = np.r_[0:500, 650:1500]  # 150 frames (3 s) never arrive
    stamps = run(FrameClock(T), arrival[keep], np.arange(len(keep)))
    err = np.abs(stamps - true[keep])
    first_after = 500
    assert np.all(np.diff(stamps) > 0)
    assert err[first_after + 5:first_after + 100].max() < 0.35  # within Bluetooth jitter
    assert err[first_after + 150:].max() < 0.003
