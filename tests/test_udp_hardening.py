"""The UDP receiver against hostile or confused peers, over real sockets on 127.0.0.1:
absurd header times, huge sequence jumps, a second sender, a shared key."""

from __future__ import annotations

import socket
import struct
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from waiting import wait_until

from bpms.firmware.sim.arbiter import MotionSource
from bpms.io.udp.auth import sign_datagram
from bpms.io.udp.codec import encode_raw_frame
from bpms.io.udp.receiver import UdpSource
from bpms.io.udp.sender import UdpForwarder
from bpms.io.udp.sequence import MAX_PLAUSIBLE_GAP, REORDER_WINDOW, SequenceTracker, Verdict
from bpms.pipeline.sources import UdpFrameSource

pytestmark = pytest.mark.timeout(60)
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def frames():
    motion = MotionSource.simulated(duration_s=10.0, seed=4)
    return [motion.frame(j) for j in range(400)]


@pytest.fixture
def sender():
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    yield sock
    sock.close()


def collect(read, count_done, timeout=10.0) -> list:
    out = []

    def step() -> bool:
        got = read()
        if got:
            out.extend(got if isinstance(got, list) else [got])
        return count_done()

    assert wait_until(step, timeout)
    return out


def test_overflowing_and_absurd_times_are_malformed_never_an_exception(frames, sender):
    source = UdpFrameSource("127.0.0.1:0")
    try:
        addr = source.udp.address
        bad = [(1.7e308, 0.0), (-1.0, 0.0), (0.0, 1.7e308), (0.0, -5.0), (5e8, 1e9)]
        for k, (suit_time, send_time) in enumerate(bad):
            sender.sendto(encode_raw_frame(frames[k], session=9, seq=k, suit_time=suit_time,
                                           send_time=send_time), addr)
        nan = bytearray(encode_raw_frame(frames[9], session=9, seq=9, suit_time=0, send_time=0))
        nan[16:24] = struct.pack("!d", float("nan"))
        sender.sendto(bytes(nan), addr)
        sender.sendto(encode_raw_frame(frames[10], session=9, seq=10, suit_time=0.2,
                                       send_time=1.7e9), addr)
        got = collect(lambda: source.read(0.05), lambda: source.udp.stats.datagrams == 7)
    finally:
        source.close()
    assert [e.frame for e in got] == [frames[10]] and got[0].index == 10
    s = source.udp.stats
    assert s.malformed == 6 and s.delivered == 1
    assert "out of range" in s.last_malformed or "finite" in s.last_malformed


def test_a_big_gap_costs_no_more_than_a_small_one():
    t = SequenceTracker()
    seq = 0
    t.observe(1, seq)
    for _ in range(200):  # 200 gaps of a minute each (the largest plausible): 600,000 lost
        seq += MAX_PLAUSIBLE_GAP
        assert t.observe(1, seq) == Verdict.NEW
        # gaps are ranges: the bookkeeping holds a few entries, not thousands of numbers
        assert len(t._starts) <= 12
    assert t.lost == 200 * (MAX_PLAUSIBLE_GAP - 1)
    received = sum(1 for k in range(seq - REORDER_WINDOW, seq) if k % MAX_PLAUSIBLE_GAP == 0)
    assert t.pending == REORDER_WINDOW - received  # the window below the highest stays open
    assert t.observe(1, seq - 5) == Verdict.REORDERED  # a late one still fills its gap
    assert t.observe(1, seq - 5) == Verdict.DUPLICATE
    assert t.lost == 200 * (MAX_PLAUSIBLE_GAP - 1) - 1


def test_implausible_jumps_cost_nothing_and_are_not_lost():
    """Two spoofed jumps pushed lost to 8.6 billion (issue 26): now they are held."""
    t = SequenceTracker()
    for k in range(10):
        t.observe(1, k)
    for seq in (2**31 - 1, 2**31 + 40_000, 40_000, 3_000_000):
        assert t.observe(1, seq) == Verdict.IMPLAUSIBLE
    assert t.observe(1, 10) == Verdict.NEW
    assert (t.lost, t.implausible, t.jumps, t.unique) == (0, 4, 0, 11)


def test_jumps_over_sockets_keep_exact_counts(frames, sender):
    with UdpSource("127.0.0.1:0") as source:
        # plausible gaps, one late datagram, then a jump far ahead and one far behind
        seqs = [0, 2000, 4000, 3999, 6000, 6000 + 40_000, (6000 - 40_000) % 2**32]
        for k, s in enumerate(seqs):
            sender.sendto(encode_raw_frame(frames[k], session=3, seq=s, suit_time=k * 0.02,
                                           send_time=1.7e9), source.address)
        got = collect(lambda: source.read(0.05), lambda: source.stats.datagrams == len(seqs))
        s = source.stats
    assert [g.seq for g in got] == seqs[:5]
    assert (s.reordered, s.duplicated, s.malformed, s.implausible) == (1, 0, 0, 2)
    assert s.lost == 3 * 1999 - 1 and s.received == s.delivered + s.implausible


def stream(fw: UdpForwarder, frames: list[bytes], stop: threading.Event, period: float = 0.005):
    k = 0
    while not stop.wait(period):
        fw.send_frame(frames[k % len(frames)], (k % len(frames)) * 0.02)
        k += 1


def test_a_foreign_session_does_not_take_over_an_active_stream(frames):
    # 3 s of silence: a margin for a loaded machine (A never pauses that long), shorter
    # than the 5 s default to keep the test short
    source = UdpFrameSource("127.0.0.1:0", takeover_after_s=3.0)
    target = f"127.0.0.1:{source.udp.address[1]}"
    stop_a = threading.Event()
    with UdpForwarder([target], session=0xA) as a, UdpForwarder([target], session=0xB) as b:
        thread = threading.Thread(target=stream, args=(a, frames, stop_a), daemon=True)
        thread.start()
        events = collect(lambda: source.read(0.05), lambda: source.udp.stats.delivered >= 20)
        for k in range(50):  # a second sender (say a second `bpms replay`) joins
            b.send_frame(frames[k], k * 0.02)
        more = collect(lambda: source.read(0.05),
                       lambda: source.udp.stats.foreign == 50 and
                       source.udp.stats.delivered >= 120)
        st = source.status()
        assert st.state == "streaming" and "another sender" in st.warning
        assert st.counters["foreign"] == 50 and st.counters["restarts"] == 0
        # the active stream went on, whole: A's session, nothing lost or repeated
        assert source.udp.followed.session == 0xA and not any(e.discontinuity for e in more)
        assert source.udp.stats.lost == 0 and source.udp.stats.duplicated == 0
        # A stops; once it has been silent for the takeover time, B takes over
        stop_a.set()
        thread.join(2)
        stop_b = threading.Event()
        thread_b = threading.Thread(target=stream, args=(b, frames, stop_b), daemon=True)
        thread_b.start()
        try:
            late = collect(lambda: source.read(0.05),
                           lambda: source.udp.stats.restarts == 1, timeout=15)
            assert source.udp.followed.session == 0xB and any(e.discontinuity for e in late)
            assert "replaced" in source.status().warning  # the takeover is shown
        finally:
            stop_b.set()
            thread_b.join(2)
        source.close()
    assert all(e.frame in frames for e in events + more + late)
    assert source.udp.stats.stale == 0


def test_a_shared_key_refuses_unauthenticated_and_wrong_key_datagrams(frames, sender):
    with UdpSource("127.0.0.1:0", key=b"lab key 1") as source:
        plain = encode_raw_frame(frames[0], session=5, seq=0, suit_time=0, send_time=1.7e9)
        wrong = sign_datagram(encode_raw_frame(frames[1], session=5, seq=1, suit_time=0.02,
                                               send_time=1.7e9), b"lab key 2")
        tampered = bytearray(sign_datagram(encode_raw_frame(
            frames[2], session=5, seq=2, suit_time=0.04, send_time=1.7e9), b"lab key 1"))
        tampered[100] ^= 1
        # signed with the right key, but version 1: no freshness, refused with a key
        old_version = sign_datagram(encode_raw_frame(frames[5], session=5, seq=3,
                                                     suit_time=0.06, send_time=1.7e9,
                                                     version=1), b"lab key 1")
        for data in (plain, wrong, bytes(tampered), old_version):
            sender.sendto(data, source.address)
        with UdpForwarder([f"127.0.0.1:{source.address[1]}"], key=b"lab key 1") as fw:
            fw.send_frame(frames[3], 0.06)
        got = collect(lambda: source.read(0.05), lambda: source.stats.datagrams == 5)
        s = source.stats
    assert [g.frame for g in got] == [frames[3]]
    assert s.unauthenticated == 4 and s.malformed == 0 and s.delivered == 1
    # a receiver without a key reads signed datagrams (the tag is stripped, not checked)
    with UdpSource("127.0.0.1:0") as open_source, UdpForwarder(
            [f"127.0.0.1:{open_source.address[1]}"], key=b"lab key 1") as fw:
        fw.send_frame(frames[4], 0.08)
        got = collect(lambda: open_source.read(0.05), lambda: open_source.stats.datagrams == 1)
    assert [g.frame for g in got] == [frames[4]]


def test_monitor_listen_shows_the_address_and_another_sender(frames):
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    mon = subprocess.Popen([sys.executable, "-m", "bpms", "monitor", "--listen",
                            f"127.0.0.1:{port}", "--seconds", "4"], cwd=ROOT,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first = mon.stdout.readline()
    assert first.strip() == f"listening for UDP on 127.0.0.1:{port} (this computer only)"
    stop = threading.Event()
    lines: list[str] = []
    with UdpForwarder([f"127.0.0.1:{port}"], session=1) as a, UdpForwarder(
            [f"127.0.0.1:{port}"], session=2) as b:
        thread = threading.Thread(target=stream, args=(a, frames, stop, 0.02), daemon=True)
        thread.start()
        try:
            while not any(" streaming" in line for line in lines):  # A is the active sender
                line = mon.stdout.readline()
                assert line, mon.stderr.read()
                lines.append(line.rstrip())
            for k in range(20):
                b.send_frame(frames[k], k * 0.02)
            out, err = mon.communicate(timeout=30)
        finally:
            stop.set()
            thread.join(2)
    assert mon.returncode == 0, err
    lines += out.splitlines()
    assert any("WARNING: another sender (127.0.0.1:" in line for line in lines), out
    assert any(" streaming" in line and "foreign 20" in line for line in lines), out


def test_the_key_comes_from_the_options_key_file(tmp_path, monkeypatch):
    """udp.key_file: its text is the key (the environment variable wins); an unreadable or
    empty key file is a one-line error, not a silent 'no key'."""
    from bpms.io.udp.auth import KEY_ENV, UdpKeyError, shared_key

    monkeypatch.delenv(KEY_ENV, raising=False)
    key_file = tmp_path / "udp.key"
    key_file.write_text("  lab secret \n")
    assert shared_key("") is None
    assert shared_key(str(key_file)) == b"lab secret"
    monkeypatch.setenv(KEY_ENV, "from env")
    assert shared_key(str(key_file)) == b"from env"
    monkeypatch.delenv(KEY_ENV)
    with pytest.raises(UdpKeyError, match="cannot be read"):
        shared_key(str(tmp_path / "missing.key"))
    (tmp_path / "empty.key").write_text("\n")
    with pytest.raises(UdpKeyError, match="is empty"):
        shared_key(str(tmp_path / "empty.key"))


def test_a_session_signs_with_the_key_file_and_a_keyed_receiver_accepts_it(tmp_path,
                                                                          monkeypatch):
    from bpms.firmware.sim.session import simulate
    from bpms.io.options import Options
    from bpms.io.rawfile import read_raw
    from bpms.io.replay import ReplaySource
    from bpms.io.udp.auth import KEY_ENV
    from bpms.io.udp.receiver import UdpSource
    from bpms.pipeline.session import LiveSession

    monkeypatch.delenv(KEY_ENV, raising=False)
    key_file = tmp_path / "udp.key"
    key_file.write_text("lab secret")
    good = UdpSource("127.0.0.1:0", key=b"lab secret")
    wrong = UdpSource("127.0.0.1:0", key=b"another")
    try:
        options = Options()
        options.udp.key_file = str(key_file)
        raw = simulate(duration_s=1.0, seed=4).save_raw(tmp_path / "Raw_key_1.bpmsraw")
        session = LiveSession(ReplaySource(read_raw(raw), speed=None), options)
        session.start_forwarding([f"127.0.0.1:{good.address[1]}",
                                  f"127.0.0.1:{wrong.address[1]}"])
        session.start()
        got_good = []

        def received() -> int:
            frame = good.read(0.05)
            if frame is not None:
                got_good.append(frame)
            return len(got_good)

        assert wait_until(lambda: received() >= 40, 20)
        assert wait_until(lambda: wrong.read(0.05) is None
                          and wrong.stats.unauthenticated > 0, 10)
        session.stop()
        assert wrong.stats.delivered == 0
    finally:
        good.close()
        wrong.close()
