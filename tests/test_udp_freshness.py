"""Issue 45.1 and 45.2 over real UDP sockets on 127.0.0.1: with a key no signed datagram is
accepted twice (a receiver that joined late, replays more than the reorder window old in
bursts, a replayed ZERO), and a takeover never locks the real sender out. The receiver's
clock is injected (:class:`Clock`), so the product's time rules (5 s of silence, the return)
are tested on a hand-made timeline, not on wall time.

Every frame is distinct (random counts), so which frames were delivered, and whose, is known
exactly: the expected values are the frames the test sent, never the receiver's own counts."""

from __future__ import annotations

import logging
import socket
import time

import numpy as np
import pytest

from bpms.commands.monitor import udp_status_line
from bpms.io.frames import encode_frames
from bpms.io.udp.auth import sign_datagram
from bpms.io.udp.codec import ZeroMessage, encode_raw_frame, encode_zero
from bpms.io.udp.receiver import UdpSource
from bpms.pipeline.sources import UdpFrameSource

pytestmark = pytest.mark.timeout(60)
KEY = b"lab key 45"
SESSION, SENDER, EPOCH = 0x4545, 77, 1_700_000_000_000_000
PERIOD = 0.02


class Clock:
    """The receiver's monotonic clock, set by the test."""

    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def distinct_frames(n: int, seed: int = 45) -> list[bytes]:
    raw = np.random.default_rng(seed).integers(-30000, 30000, (n, 18, 9)).astype(np.int16)
    data = encode_frames(raw)
    return [data[340 * k:340 * (k + 1)] for k in range(n)]


def raw_datagram(frame: bytes, seq: int, key: bytes | None = KEY, session: int = SESSION,
                 sender: int = SENDER, epoch: int = EPOCH) -> bytes:
    """One run's datagram as the sender made it (signed with ``key``)."""
    d = encode_raw_frame(frame, session=session, seq=seq, suit_time=seq * PERIOD,
                         send_time=1.7e9 + seq * PERIOD, sender=sender, epoch=epoch)
    return sign_datagram(d, key) if key else d


class Link:
    """A sending socket and a receiver: each datagram is sent at the clock time given and read
    before the next (so the receiver sees the timeline the test wrote)."""

    def __init__(self, src: UdpSource, clock: Clock) -> None:
        self.src, self.clock = src, clock
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.delivered: list[bytes] = []

    def send(self, datagrams: list[bytes], t0: float | None = None, dt: float = 0.0) -> None:
        for k, data in enumerate(datagrams):
            if t0 is not None:
                self.clock.t = t0 + k * dt
            before = self.src.stats.datagrams
            self.sock.sendto(data, self.src.address)
            deadline = time.monotonic() + 5.0
            while self.src.stats.datagrams == before:
                assert time.monotonic() < deadline, "a datagram never reached the receiver"
                got = self.src.read(0.005)
                if got is not None:
                    self.delivered.append(got.frame)

    def burst(self, datagrams: list[bytes]) -> None:
        """Send all at once (at the clock time now), then read until each has arrived."""
        before = self.src.stats.datagrams
        for data in datagrams:
            self.sock.sendto(data, self.src.address)
        deadline = time.monotonic() + 10.0
        while self.src.stats.datagrams < before + len(datagrams):
            assert time.monotonic() < deadline, "datagrams never reached the receiver"
            got = self.src.read(0.005)
            if got is not None:
                self.delivered.append(got.frame)

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def keyed():
    clock = Clock()
    src = UdpSource("127.0.0.1:0", key=KEY, clock=clock)
    link = Link(src, clock)
    yield link
    link.close()
    src.close()


def test_a_receiver_that_joined_late_never_takes_the_runs_earlier_datagrams(keyed):
    """682dd18: joined at 1,000, a replay of 0-999 was delivered (1,000 frames, "reordered")."""
    frames = distinct_frames(1100)
    run = [raw_datagram(f, k) for k, f in enumerate(frames)]
    keyed.send(run[1000:1050])  # the receiver joins at sequence 1,000
    keyed.burst(run[:1000])  # an eavesdropper replays what it recorded before
    keyed.send(run[1050:1100])
    s = keyed.src.stats
    assert keyed.delivered == frames[1000:1100]
    assert (s.replayed, s.delivered, s.lost) == (1000, 100, 0)


def test_replays_older_than_the_window_in_bursts_are_refused_and_shown(keyed, caplog):
    """682dd18: datagrams more than 32,768 numbers old, in bursts of 40 beside the live sender,
    were delivered (a "jump back" after 25 in a row), real frames lost, and the monitor said
    `replayed 0`."""
    caplog.set_level(logging.WARNING, logger="bpms.io.udp.receiver")
    old = distinct_frames(400, seed=1)
    live = distinct_frames(200, seed=2)
    base = 40_000
    keyed.send([raw_datagram(live[0], base)])
    for k in range(1, 200):
        keyed.send([raw_datagram(live[k], base + k)])
        if k % 20 == 0:  # a burst of 40 consecutive old datagrams of the same run
            b = (k // 20 - 1) * 40
            keyed.burst([raw_datagram(old[j], j) for j in range(b, b + 40)])
    s = keyed.src.stats
    assert keyed.delivered == live  # every real frame, nothing old
    assert (s.replayed, s.lost, s.restarts, s.implausible) == (9 * 40, 0, 0, 0)
    assert s.rejections() == {"replayed": 360}
    warned = [r.getMessage() for r in caplog.records if "replayed" in r.getMessage()]
    assert warned and caplog.records[0].levelname == "WARNING"
    source = UdpFrameSource.__new__(UdpFrameSource)  # the status of this very receiver
    source.udp, source._state = keyed.src, "streaming"
    status = source.status()
    line = udp_status_line(1.0, 50.0, len(keyed.delivered), status)
    assert "replayed 360" in line and "WARNING: datagrams refused (replayed from 127.0.0.1:" \
        in line


def test_numbers_wrap_without_a_replay_slipping_through(keyed):
    frames = distinct_frames(60)
    top = 2**32
    run = [raw_datagram(f, (top - 30 + k) % top) for k, f in enumerate(frames)]
    keyed.send(run[:40])  # across the wrap 2**32 - 1 -> 0
    keyed.send(run[:40])  # all again: refused or duplicate, never delivered
    keyed.send(run[40:])
    assert keyed.delivered == frames
    assert keyed.src.stats.lost == 0


@pytest.mark.parametrize("key", [KEY, None], ids=["shared key", "no key"])
def test_a_replayed_zero_is_never_applied_twice(key):
    """682dd18: an older ZERO of the same session, replayed, was taken again (yaw0 0.5
    instead of the -1.0 in force)."""
    R0 = np.broadcast_to(np.eye(3), (18, 3, 3)).copy()

    def zero(seq: int, yaw0: float) -> bytes:
        d = encode_zero(ZeroMessage(R0, yaw0, "manual"), session=SESSION, seq=seq,
                        suit_time=seq, send_time=1.7e9 + seq, sender=SENDER, epoch=EPOCH)
        return sign_datagram(d, key) if key else d

    clock = Clock()
    with UdpSource("127.0.0.1:0", key=key, clock=clock) as src:
        link = Link(src, clock)
        try:
            link.send([raw_datagram(f, k, key) for k, f in enumerate(distinct_frames(3))])
            link.send([zero(0, 0.5)])
            assert src.take_zero()[1].yaw0 == 0.5
            link.send([zero(1, -1.0)])
            assert src.take_zero()[1].yaw0 == -1.0
            link.send([zero(0, 0.5), zero(1, -1.0)])  # replayed
            assert src.take_zero() is None
            assert src.stats.replayed == 2
        finally:
            link.close()


@pytest.mark.parametrize("key", [KEY, None], ids=["shared key", "no key"])
def test_a_takeover_never_locks_the_real_sender_out(key, caplog):
    """The issue's timeline: the suit power-cycles for 7.5 s; after 5.6 s of silence a
    stranger sends 70 datagrams and takes over (logged, shown); then it stops and the real
    sender resumes with its old session. 682dd18 dropped all 391 of its frames as stale and
    showed only `silent`. Now the stream is back with it at its first datagram (the stranger
    has been quiet 0.5 s): all 391 delivered."""
    caplog.set_level(logging.WARNING, logger="bpms.io.udp.receiver")
    clock = Clock()
    real = distinct_frames(491, seed=3)
    stranger = distinct_frames(70, seed=4)
    other = dict(session=0x5A5A, sender=99, epoch=EPOCH + 5)
    source = UdpFrameSource.__new__(UdpFrameSource)
    with UdpSource("127.0.0.1:0", key=key, clock=clock) as src:
        source.udp, source._state = src, "streaming"
        link = Link(src, clock)
        try:
            t0 = clock.t
            link.send([raw_datagram(real[k], k, key) for k in range(100)], t0, PERIOD)
            silent_from = clock.t
            link.send([raw_datagram(stranger[k], k, key, **other) for k in range(70)],
                      silent_from + 5.6, PERIOD)
            assert src.stats.takeovers == 1 and "after 6.1 s of silence" in src.stats.takeover
            back = silent_from + 7.5
            during = udp_status_line(7.0, 0.0, len(link.delivered), source.status())
            link.send([raw_datagram(real[100 + k], 100 + k, key) for k in range(391)], back,
                      PERIOD)
            after = udp_status_line(16.0, 50.0, len(link.delivered), source.status())
        finally:
            link.close()
        s = src.stats
    delivered = link.delivered
    # the stranger's frames were followed after its 25th: the takeover was logged and shown
    assert delivered[:100] == real[:100] and delivered[-391:] == real[100:]
    assert len(delivered) == 100 + 46 + 391
    assert (s.takeovers, s.stale, s.lost) == (2, 0, 0)
    assert "switches 1" in during and "replaced 00004545 (after 6.1 s of silence)" in during
    assert "switches 2" in after and "came back" in after and "came back" in s.takeover
    assert sum("sender changed" in r.getMessage() for r in caplog.records) == 2


def test_the_real_sender_comes_back_even_while_the_stranger_keeps_sending():
    """Without a key: a newcomer that took over during a pause cannot keep the real sender out
    by sending on; nor can it then take back over while the real sender streams."""
    clock = Clock()
    real = distinct_frames(160, seed=5)
    stranger = distinct_frames(200, seed=6)
    other = dict(session=0x5A5A, sender=99, epoch=EPOCH + 5)
    source = UdpFrameSource.__new__(UdpFrameSource)
    with UdpSource("127.0.0.1:0", clock=clock) as src:
        source.udp, source._state = src, "streaming"
        link = Link(src, clock)
        try:
            link.send([raw_datagram(real[k], k, None) for k in range(50)], clock.t, PERIOD)
            t = clock.t + 6.0
            link.send([raw_datagram(stranger[k], k, None, **other) for k in range(30)], t,
                      PERIOD)
            assert src.followed.session == other["session"]
            t = clock.t + PERIOD
            for k in range(110):  # both send, interleaved
                link.send([raw_datagram(real[50 + k], 50 + k, None)], t + k * PERIOD)
                link.send([raw_datagram(stranger[30 + k], 30 + k, None, **other)],
                          t + k * PERIOD + 0.01)
            line = udp_status_line(9.0, 50.0, len(link.delivered), source.status())
        finally:
            link.close()
        s = src.stats
    assert src.followed.session == SESSION
    assert link.delivered[-101:] == real[59:160]  # its 10th datagram in a row took it back
    assert s.takeovers == 2 and s.stale == 9 + 101  # both sides' dropped datagrams, counted
    assert f"stale {s.stale}" in line and "switches 2" in line
    assert "WARNING:" in line and "datagrams of a replaced sender (127.0.0.1:" in line
