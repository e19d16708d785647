"""UDP forwarding (SPEC §9, docs/udp.md): datagram codec, forwarder, client source.

Real UDP sockets on 127.0.0.1 only. Sending and receiving happen in one thread, in batches
that fit the receive buffer, so the kernel never drops and every run is deterministic.
"""

from __future__ import annotations

import math
import random
import socket
import struct
import threading
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from udp_docs_reader import docs_reader
from waiting import inside, wait_until

from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.filter.rotations import euler_to_dcm
from bpms.io.frames import FRAME_SIZE, encode_frame
from bpms.io.udp.addresses import UdpConfigError, parse_address
from bpms.io.udp.auth import sign_datagram
from bpms.io.udp.codec import (
    HEADER_SIZE,
    HEADER_V3_SIZE,
    MAX_DATAGRAM,
    SEQ_MOD,
    DatagramError,
    MessageType,
    ZeroMessage,
    decode_datagram,
    encode_header,
    encode_pose,
    encode_pose_extensions,
    encode_raw_frame,
    encode_zero,
)
from bpms.io.udp.receiver import UdpSource
from bpms.io.udp.sender import UdpForwarder
from bpms.io.udp.sequence import SequenceTracker, Verdict

RNG_SEED = 20121


def make_frames(n: int, seed: int = 1) -> list[bytes]:
    rng = np.random.default_rng(seed)
    raw = rng.integers(-32768, 32768, size=(n, 18, 9), dtype=np.int16)
    errors = rng.random((n, 18, 3)) < 0.01
    return [encode_frame(raw[i], errors[i]) for i in range(n)]


def unit_quats(n: int = 18, seed: int = 2) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def drain(src: UdpSource, until: int, timeout: float = 10.0) -> list:
    """Read from ``src`` until it has counted ``until`` datagrams (or the timeout)."""
    out = []
    deadline = time.monotonic() + timeout
    while src.stats.datagrams < until and time.monotonic() < deadline:
        frame = src.read(timeout=0.002)
        if frame is not None:
            out.append(frame)
    while (frame := src.read(timeout=0.0)) is not None:
        out.append(frame)
    assert src.stats.datagrams == until, f"kernel dropped datagrams: {src.stats}"
    return out


def batch_size(*socks) -> int:
    """Datagrams that fit every receive buffer at once (a small one costs ~2-4 KiB of it)."""
    return max(8, min(250, *(b // 8192 for b in (
        s.rcvbuf if isinstance(s, UdpSource) else s.getsockopt(socket.SOL_SOCKET,
                                                               socket.SO_RCVBUF)
        for s in socks))))


@pytest.fixture
def source():
    src = UdpSource("127.0.0.1:0")
    yield src
    src.close()


# --------------------------------------------------------------------------- codec


def test_header_layout_is_the_documented_one():
    frame = make_frames(1)[0]
    dg = encode_raw_frame(frame, session=0x01020304, seq=0x0A0B0C0D, suit_time=1.5,
                          send_time=2.25, sender=0x1122334455667788, epoch=1_700_000_000_123_456)
    assert len(dg) == HEADER_V3_SIZE + FRAME_SIZE == 48 + 340 == 388
    assert dg[0:4] == b"BPMS"
    assert dg[4] == 4 and dg[5] == 1 and dg[6:8] == b"\0\0"
    assert dg[8:12] == b"\x01\x02\x03\x04"
    assert dg[12:16] == b"\x0a\x0b\x0c\x0d"
    assert struct.unpack(">d", dg[16:24])[0] == 1.5
    assert struct.unpack(">d", dg[24:32])[0] == 2.25
    assert dg[32:40] == bytes.fromhex("1122334455667788")
    assert struct.unpack(">Q", dg[40:48])[0] == 1_700_000_000_123_456
    assert dg[48:] == frame
    decoded = decode_datagram(dg)
    assert (decoded.version, decoded.sender, decoded.epoch) == (4, 0x1122334455667788,
                                                                1_700_000_000_123_456)

    q = unit_quats()
    angles = np.linspace(-1, 1, len(JOINT_ANGLE_NAMES))
    pose = encode_pose(q, angles, session=7, seq=3, suit_time=0.0, send_time=0.0)
    assert pose[4] == 4 and pose[5] == 2
    assert len(pose) == 48 + 4 + 18 * 16 + 28 * 4 == 452
    assert struct.unpack(">HH", pose[48:52]) == (18, 28)
    w, x, y, z = struct.unpack(">4f", pose[52:68])
    assert np.allclose([w, x, y, z], q[0], atol=1e-6)
    assert np.isclose(struct.unpack(">f", pose[52 + 18 * 16 : 56 + 18 * 16])[0], -1.0)


def test_version_1_datagrams_are_still_read():
    """A sender of the previous versions (32-byte header, no sender id or epoch)."""
    frame = make_frames(1)[0]
    dg = encode_raw_frame(frame, session=9, seq=4, suit_time=0.08, send_time=3.0, version=1)
    assert len(dg) == HEADER_SIZE + FRAME_SIZE == 372 and dg[4] == 1
    decoded = decode_datagram(dg)
    assert (decoded.frame, decoded.seq, decoded.version, decoded.sender, decoded.epoch) == (
        frame, 4, 1, 0, 0)
    pose = encode_pose(unit_quats(), np.zeros(28), session=9, seq=1, suit_time=0.0,
                       send_time=0.0, version=1)
    assert len(pose) == 436 and decode_datagram(pose).pose.quaternions.shape == (18, 4)


@settings(deadline=None, max_examples=60)
@given(raw=arrays(np.int16, (18, 9)), errors=arrays(bool, (18, 3)),
       session=st.integers(0, 2**32 - 1), seq=st.integers(0, 2**32 - 1),
       suit_time=st.floats(allow_nan=False, allow_infinity=False),
       send_time=st.floats(0, 4e9), flags=st.integers(0, 0xFFFF))
def test_raw_frame_round_trip(raw, errors, session, seq, suit_time, send_time, flags):
    frame = encode_frame(raw, errors)
    dg = decode_datagram(encode_raw_frame(frame, session=session, seq=seq, suit_time=suit_time,
                                          send_time=send_time, flags=flags))
    assert dg.type == MessageType.RAW_FRAME and dg.frame == frame and dg.pose is None
    assert (dg.session, dg.seq, dg.suit_time, dg.send_time, dg.flags) == (
        session, seq, suit_time, send_time, flags)


@settings(deadline=None, max_examples=60)
@given(q=arrays(np.float64, (18, 4), elements=st.floats(-1, 1)).filter(
           lambda q: (np.linalg.norm(q, axis=1) > 0.1).all()),
       angles=arrays(np.float64, 28, elements=st.floats(-math.pi, math.pi)),
       seq=st.integers(0, 2**32 - 1), suit_time=st.floats(0, 1e6))
def test_pose_round_trip(q, angles, seq, suit_time):
    dg = decode_datagram(encode_pose(q, angles, session=9, seq=seq, suit_time=suit_time,
                                     send_time=1.0))
    assert dg.type == MessageType.POSE and dg.seq == seq and dg.suit_time == suit_time
    expected = q / np.linalg.norm(q, axis=1, keepdims=True)
    assert dg.pose.quaternions.shape == (18, 4) and dg.pose.angles.shape == (28,)
    assert np.allclose(dg.pose.quaternions, expected, atol=1e-6)
    assert np.allclose(dg.pose.angles, angles, atol=1e-6)


def _bad_datagrams() -> dict[str, bytes]:
    frame = make_frames(1)[0]
    good = encode_raw_frame(frame, session=1, seq=1, suit_time=0.0, send_time=0.0)
    pose = encode_pose(unit_quats(), np.zeros(28), session=1, seq=1, suit_time=0.0,
                       send_time=0.0)
    head_pose = pose[:HEADER_V3_SIZE]
    pose_v1 = encode_pose(unit_quats(), np.zeros(28), session=1, seq=1, suit_time=0.0,
                          send_time=0.0, version=1)
    q = unit_quats().astype(">f4")
    nan_q = q.copy()
    nan_q[3, 1] = np.nan
    body = struct.pack(">HH", 18, 28)
    return {
        "empty": b"",
        "short": good[:10],
        "header only": good[:HEADER_V3_SIZE],
        "v3 header cut": good[:40],
        "magic": b"XPMS" + good[4:],
        "version": good[:4] + b"\x09" + good[5:],  # unknown (2 = POSE with extensions)
        "type": good[:5] + b"\x07" + good[6:],
        "long frame": good + b"\0",
        "short frame": good[:-1],
        "markers": good[:HEADER_V3_SIZE] + b"$$" + frame[2:],
        "nan time": good[:16] + struct.pack(">d", math.nan) + good[24:],
        "inf time": good[:24] + struct.pack(">d", math.inf) + good[32:],
        "pose short": pose[:-4],
        "pose long (version 1)": pose_v1 + b"\0\0\0\0",
        "pose block cut": pose + b"\0\0\0",
        "pose block runs past the end": pose + struct.pack(">HH", 9, 10) + b"\0" * 4,
        "pose no counts": head_pose + b"\0",
        "pose counts lie": pose[:HEADER_V3_SIZE] + struct.pack(">HH", 19, 28)
        + pose[HEADER_V3_SIZE + 4:-4],
        "pose nan": head_pose + body + nan_q.tobytes() + np.zeros(28, ">f4").tobytes(),
        "pose not unit": head_pose + body + (q * 1.1).astype(">f4").tobytes()
        + np.zeros(28, ">f4").tobytes(),
        "pose zero": head_pose + body + np.zeros((18, 4), ">f4").tobytes()
        + np.zeros(28, ">f4").tobytes(),
        "pose nan angle": head_pose + body + q.tobytes()
        + np.full(28, np.nan, ">f4").tobytes(),
    }


@pytest.mark.parametrize("name", list(_bad_datagrams()))
def test_decode_rejects_malformed_with_one_exception_type(name):
    with pytest.raises(DatagramError) as info:
        decode_datagram(_bad_datagrams()[name])
    assert "\n" not in str(info.value) and str(info.value)


def random_bad_datagrams(n: int, seed: int = RNG_SEED) -> list[bytes]:
    """Random bytes (lengths 0..65,000), truncated real datagrams, real headers with bad
    payload lengths: none is a valid datagram."""
    rng = random.Random(seed)
    frames = make_frames(8, seed=seed)
    # version 1 (32-byte header, no POSE extension blocks: every extra byte is an error)
    reals = [encode_raw_frame(f, session=5, seq=i, suit_time=i * 0.02, send_time=1e9,
                              version=1) for i, f in enumerate(frames)]
    reals.append(encode_pose(unit_quats(), np.zeros(28), session=5, seq=0, suit_time=0.0,
                             send_time=1e9, version=1))
    out = [b"", bytes(65000), rng.randbytes(65000), rng.randbytes(MAX_DATAGRAM)]
    while len(out) < n:
        kind = rng.randrange(4)
        if kind == 0:
            length = rng.choice([rng.randrange(0, 64), rng.randrange(0, 2000),
                                 rng.randrange(0, 65001) if rng.random() < 0.01 else 372])
            out.append(rng.randbytes(length))
        elif kind == 1:
            real = rng.choice(reals)
            out.append(real[: rng.randrange(0, len(real))])
        elif kind == 2:
            real = rng.choice(reals)
            extra = rng.randrange(1, 600)
            payload = real[HEADER_SIZE:]
            if rng.random() < 0.5:
                out.append(real[:HEADER_SIZE] + payload + rng.randbytes(extra))
            else:
                out.append(real[:HEADER_SIZE] + payload[: max(0, len(payload) - extra)])
        else:  # a real header with random bytes after it
            real = rng.choice(reals)
            out.append(real[:HEADER_SIZE] + rng.randbytes(rng.randrange(0, 800)))
    return out


def test_decode_fuzz_raises_only_datagram_error():
    for data in random_bad_datagrams(10_000, seed=7):
        with pytest.raises(DatagramError):
            decode_datagram(data)


# --------------------------------------------------------------------------- sockets


def test_10000_frames_in_order(source):
    frames = make_frames(10_000)
    with UdpForwarder([f"127.0.0.1:{source.address[1]}"]) as fw:
        received = []
        n = batch_size(source)
        for start in range(0, len(frames), n):
            for frame in frames[start : start + n]:
                assert fw.send_frame(frame) == 1
            received += drain(source, min(start + n, len(frames)))
        assert fw.stats.sent == 10_000 and fw.stats.errors == 0 and fw.stats.frames == 10_000
        session = fw.session
    assert [r.seq for r in received] == list(range(10_000))
    assert [r.frame for r in received] == frames
    assert all(r.session == session and not r.reordered for r in received)
    assert received[123].suit_time == pytest.approx(123 * 0.02)
    s = source.stats
    assert (s.datagrams, s.received, s.delivered) == (10_000, 10_000, 10_000)
    assert (s.lost, s.duplicated, s.reordered, s.malformed, s.restarts) == (0, 0, 0, 0, 0)


class Relay:
    """A UDP proxy on 127.0.0.1 that drops, duplicates and delays datagrams with a seeded RNG
    and records exactly what it sent."""

    def __init__(self, target: tuple[str, int], seed: int, p_drop=0.05, p_dup=0.05,
                 p_hold=0.03) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(5.0)
        self.address = self.sock.getsockname()
        self.target = target
        self.rng = random.Random(seed)
        self.p = (p_drop, p_dup, p_hold)
        self.held: list[list] = []  # [datagrams still to let pass, datagram]
        self.sent_seqs: list[int] = []
        self.dropped = self.duplicated_copies = 0

    def _emit(self, data: bytes) -> None:
        self.sock.sendto(data, self.target)
        self.sent_seqs.append(struct.unpack_from(">I", data, 12)[0])

    def _forward(self, data: bytes) -> None:
        self._emit(data)
        for entry in self.held:
            entry[0] -= 1
        for entry in [e for e in self.held if e[0] <= 0]:
            self.held.remove(entry)
            self._emit(entry[1])

    def pump(self, n: int) -> None:
        """Receive ``n`` datagrams and act on each."""
        p_drop, p_dup, p_hold = self.p
        for _ in range(n):
            data = self.sock.recv(70_000)
            r = self.rng.random()
            if r < p_drop:
                self.dropped += 1
            elif r < p_drop + p_dup:
                self._forward(data)
                self._forward(data)
                self.duplicated_copies += 1
            elif r < p_drop + p_dup + p_hold:
                self.held.append([self.rng.randint(1, 4), data])
            else:
                self._forward(data)

    def flush(self) -> None:
        for _, data in self.held:
            self._emit(data)
        self.held.clear()

    def truth(self) -> dict[str, int]:
        """Counters computed from what the relay actually sent."""
        seen: set[int] = set()
        top = -1
        dup = reordered = 0
        for s in self.sent_seqs:
            if s in seen:
                dup += 1
            else:
                reordered += s < top
                seen.add(s)
            top = max(top, s)
        span = max(seen) - min(seen) + 1
        return {"received": len(self.sent_seqs), "delivered": len(seen), "duplicated": dup,
                "reordered": reordered, "lost": span - len(seen)}

    def close(self) -> None:
        self.sock.close()


@pytest.mark.parametrize("seed", [1, 2])
def test_lossy_relay_counters_are_exact(source, seed):
    relay = Relay(source.address, seed)
    frames = make_frames(3000, seed=seed)
    got = []
    try:
        with UdpForwarder([f"127.0.0.1:{relay.address[1]}"]) as fw:
            n = batch_size(source, relay.sock) // 2  # duplicates double a batch
            for start in range(0, len(frames), n):
                batch = frames[start : start + n]
                for frame in batch:
                    fw.send_frame(frame)
                relay.pump(len(batch))
                got += drain(source, len(relay.sent_seqs))
            relay.flush()
            got += drain(source, len(relay.sent_seqs))
    finally:
        relay.close()
    truth = relay.truth()
    s = source.stats
    assert relay.dropped > 100 and truth["duplicated"] > 100 and truth["reordered"] > 50
    assert {k: getattr(s, k) for k in truth} == truth
    assert (s.malformed, s.restarts, s.stale) == (0, 0, 0)
    assert s.datagrams == s.received + s.malformed + s.ignored + s.stale
    assert s.received == s.delivered + s.duplicated
    # Delivered in arrival order, each sequence number once, with the right bytes.
    first_sends = list(dict.fromkeys(relay.sent_seqs))
    assert [r.seq for r in got] == first_sends
    assert all(r.frame == frames[r.seq] for r in got)
    assert sum(r.reordered for r in got) == truth["reordered"]


def test_random_datagrams_are_all_counted_malformed(source):
    bad = random_bad_datagrams(10_000)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sent = 0
        batch_bytes = 0
        for data in bad:
            sock.sendto(data, source.address)
            sent += 1
            batch_bytes += len(data) + 2048
            if batch_bytes > source.rcvbuf // 4:
                assert drain(source, sent) == []
                batch_bytes = 0
        assert drain(source, sent) == []
        # A valid frame after all that garbage still comes through.
        frame = make_frames(1)[0]
        sock.sendto(encode_raw_frame(frame, session=3, seq=0, suit_time=0, send_time=0),
                    source.address)
        assert [r.frame for r in drain(source, sent + 1)] == [frame]
    finally:
        sock.close()
    s = source.stats
    assert s.malformed == 10_000 and s.datagrams == 10_001 and s.delivered == 1
    assert s.last_malformed


def test_pose_datagrams_are_counted_ignored_by_the_frame_source(source):
    with UdpForwarder([f"127.0.0.1:{source.address[1]}"]) as fw:
        fw.send_pose(unit_quats(), np.zeros(28), suit_time=0.5)
        fw.send_frame(make_frames(1)[0])
        assert fw.next_seq(MessageType.POSE) == 1 and fw.next_seq(MessageType.RAW_FRAME) == 1
    got = drain(source, 2)
    assert [g.seq for g in got] == [0]
    assert source.stats.ignored == 1 and source.stats.malformed == 0


def _send_raw(sock, address, frame, session, seqs):
    for s in seqs:
        sock.sendto(encode_raw_frame(frame, session=session, seq=s, suit_time=0, send_time=0),
                    address)


def test_wrap_restart_and_stale_over_sockets():
    frame = make_frames(1)[0]
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    # A new session takes over at its first datagram here (by default only after 5 s of
    # silence of the followed one and 25 datagrams in a row: tests/test_udp_takeover.py).
    source = UdpSource("127.0.0.1:0", takeover_after_s=0.0, takeover_datagrams=1)
    try:
        # Wrap: 2**32-3 .. 2**32-1, then 0, 2 (1 lost): no restart.
        _send_raw(sock, source.address, frame, 11, [SEQ_MOD - 3, SEQ_MOD - 2, SEQ_MOD - 1, 0, 2])
        got = drain(source, 5)
        assert [g.seq for g in got] == [SEQ_MOD - 3, SEQ_MOD - 2, SEQ_MOD - 1, 0, 2]
        assert (source.stats.lost, source.stats.restarts) == (1, 0)
        # Sender restart: a new session id starting at 0; the old gap becomes final.
        _send_raw(sock, source.address, frame, 12, [0, 1])
        # A late datagram of the old session is stale: dropped, not a second restart.
        _send_raw(sock, source.address, frame, 11, [1])
        got = drain(source, 8)
        assert [(g.session, g.seq) for g in got] == [(12, 0), (12, 1)]
    finally:
        sock.close()
        source.close()
    s = source.stats
    assert (s.restarts, s.stale, s.lost, s.delivered, s.duplicated) == (1, 1, 1, 7, 0)


def test_tracker_semantics():
    t = SequenceTracker(window=100)
    verdicts = [t.observe(1, s) for s in [10, 11, 14, 13, 11, 9, 15, 12]]
    V = Verdict
    assert verdicts == [V.NEW, V.NEW, V.NEW, V.REORDERED, V.DUPLICATE, V.REORDERED, V.NEW,
                        V.REORDERED]
    assert (t.lost, t.reordered, t.duplicated, t.unique) == (0, 3, 1, 7)
    t.observe(1, 20)  # 16..19 open
    assert (t.lost, t.pending) == (4, 4)
    t.observe(1, 200)  # 16..19 leave the window: final; 21..199 partly pending
    assert t.lost == 4 + 179 and t.pending == 100
    # far behind with the same id: held (not a restart) until 25 consecutive numbers follow
    assert [t.observe(1, 17 + k) for k in range(24)] == [V.IMPLAUSIBLE] * 24
    assert (t.implausible, t.restarts, t.lost) == (24, 0, 183)
    assert t.observe(1, 17 + 24) == V.RESYNC and t.restarts == 1  # a sender that restarted
    assert t.lost == 183 and t.pending == 0
    assert t.observe(1, 40) == V.REORDERED  # extends the new session backwards
    # a huge forward jump is held, never counted lost; a plausible datagram forgets it
    assert t.observe(1, 41 + 2**31 - 1) == V.IMPLAUSIBLE
    assert t.observe(1, 42) == V.NEW
    assert t.lost == 183 and t.implausible == 25 and t.jumps == 0
    assert t.observe(1, 42 + 3000) == V.NEW  # a minute of losses at 50 Hz is plausible
    assert t.lost == 183 + 2999


def test_tracker_counts_datagrams_that_contradict_the_session():
    """A second sender on the same session: the same number with another frame, or a frame
    far behind the stream."""
    t = SequenceTracker()
    V = Verdict
    assert [t.observe(1, k, digest=k) for k in range(5)] == [V.NEW] * 5
    assert t.observe(1, 3, digest=3) == V.DUPLICATE and t.conflicts == 0  # a true duplicate
    assert t.observe(1, 3, digest=99) == V.CONFLICT and t.conflicts == 1
    assert t.observe(1, 1000, digest=1000) == V.NEW  # a forged jump ahead: a plausible gap
    assert t.observe(1, 5, digest=5) == V.REORDERED and t.conflicts == 2  # 995 late
    assert (t.duplicated, t.unique) == (2, 7)


def test_forwarder_counts_errors_and_never_raises():
    closed = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    closed.bind(("127.0.0.1", 0))
    dead_port = closed.getsockname()[1]
    closed.close()
    frame = make_frames(1)[0]
    with UdpSource("127.0.0.1:0") as src, UdpForwarder(
            [f"127.0.0.1:{dead_port}", f"127.0.0.1:{src.address[1]}"]) as fw:
        for _ in range(20):
            fw.send_frame(frame)
            time.sleep(0.001)
        s = fw.stats
        assert s.frames == 20 and s.sent + s.refused == 40
        assert s.refused >= 1 and s.errors == 0  # nobody listening is not an error here
        assert len(drain(src, 20)) == 20  # the live target got everything
    with pytest.raises(ValueError):
        UdpForwarder(["127.0.0.1:9"]).send_frame(frame[:-1])


def test_close_unblocks_a_blocked_reader():
    src = UdpSource("127.0.0.1:0")
    result = []
    reader = threading.Thread(target=lambda: result.append(src.read(timeout=60)))
    reader.start()
    assert wait_until(lambda: inside(reader, "read"), 10)  # the reader is in its read
    src.close()
    reader.join(timeout=5)
    assert not reader.is_alive() and result == [None]
    assert list(src) == []  # iterating a closed source ends at once
    assert src.read(timeout=1) is None


def test_iteration_yields_frames_until_closed():
    frames = make_frames(5)
    with UdpSource("127.0.0.1:0", poll_s=0.05) as src, UdpForwarder(
            [f"127.0.0.1:{src.address[1]}"]) as fw:
        for f in frames:
            fw.send_frame(f)
        got = []
        guard = threading.Timer(10.0, src.close)  # never hang, even if frames went missing
        guard.start()
        try:
            for r in src:
                got.append(r.frame)
                if len(got) == len(frames):
                    src.close()
        finally:
            guard.cancel()
        assert got == frames


@pytest.mark.parametrize("text", ["127.0.0.1", "127.0.0.1:port", "127.0.0.1:70000",
                                  "no-such-host.invalid:5005"])
def test_bad_addresses_are_config_errors(text):
    with pytest.raises(UdpConfigError):
        UdpForwarder([text])


def test_parse_address_and_bad_group():
    assert parse_address("127.0.0.1:5005") == ("127.0.0.1", 5005)
    assert parse_address(":6000") == ("0.0.0.0", 6000)
    with pytest.raises(UdpConfigError, match="multicast"):
        UdpSource("127.0.0.1:0", multicast_group="10.0.0.1")
    with pytest.raises(UdpConfigError):
        UdpForwarder([])


def test_multicast_on_loopback():
    group = "239.255.71.17"
    try:
        src = UdpSource("0.0.0.0:0", multicast_group=group, multicast_interface="127.0.0.1")
    except UdpConfigError as exc:
        pytest.skip(f"the kernel refuses to join {group} on the loopback interface: {exc}")
    frames = make_frames(50)
    try:
        with UdpForwarder([f"{group}:{src.address[1]}"], multicast_ttl=1,
                          multicast_interface="127.0.0.1") as fw:
            for f in frames:
                fw.send_frame(f)
            if fw.stats.errors:
                pytest.skip(f"the kernel refuses multicast sends on loopback: "
                            f"{fw.stats.last_error}")
            first = src.read(timeout=2.0)
            if first is None:
                pytest.skip("multicast on the loopback interface is not delivered here")
            got = [first, *drain(src, 50)]
    finally:
        src.close()
    assert [g.frame for g in got] == frames and src.stats.lost == 0


def test_header_helper_wraps_sequence_numbers():
    head = encode_header(MessageType.RAW_FRAME, 1, SEQ_MOD + 5, 0.0, 0.0)
    assert struct.unpack_from(">I", head, 12)[0] == 5



def test_docs_third_party_reader_agrees_with_the_codec():
    parse = docs_reader()
    raw = np.arange(162, dtype=np.int16).reshape(18, 9) - 81
    errors = np.zeros((18, 3), bool)
    errors[16, 2] = True
    frame = encode_frame(raw, errors)
    msg = parse(encode_raw_frame(frame, session=4, seq=77, suit_time=1.54, send_time=9.0))
    assert (msg["type"], msg["session"], msg["seq"], msg["suit_time"]) == (1, 4, 77, 1.54)
    assert np.array_equal(np.array(msg["imus"]), raw)
    assert msg["error_words"][5] == 1 << (3 * 1 + 2)  # IMU 16 = cluster 5 slot 1, gyro
    q = unit_quats()
    angles = np.linspace(-1.5, 1.5, 28)
    msg = parse(encode_pose(q, angles, session=4, seq=3, suit_time=0.5, send_time=9.0))
    assert np.allclose(msg["quaternions"], q, atol=1e-6)
    assert np.allclose(msg["angles"], angles, atol=1e-6)
    assert JOINT_ANGLE_NAMES[2] == "knee_r.flexion"  # the example prints angles[2] as knee_r
    # every version it claims: version 1, a signed version 4 (the tag skipped), and a POSE
    # with extension blocks after its angles
    msg = parse(encode_raw_frame(frame, session=4, seq=78, suit_time=1.56, send_time=9.0,
                                 version=1))
    assert msg["version"] == 1 and np.array_equal(np.array(msg["imus"]), raw)
    msg = parse(sign_datagram(encode_raw_frame(frame, session=4, seq=79, suit_time=1.58,
                                               send_time=9.0, sender=5, epoch=6), b"k"))
    assert (msg["version"], msg["sender"], msg["epoch"]) == (4, 5, 6)
    assert np.array_equal(np.array(msg["imus"]), raw)
    msg = parse(encode_raw_frame(frame, session=4, seq=80, suit_time=1.6, send_time=9.0,
                                 version=3, sender=5, epoch=6))
    assert msg["version"] == 3 and np.array_equal(np.array(msg["imus"]), raw)
    # the sender's Reset Zero (ZERO, version 4)
    R0 = np.array([euler_to_dcm(0.1 * i, -0.05 * i, 0.2 + 0.01 * i) for i in range(18)])
    R0[3] = np.nan  # an IMU without a zero
    zero = ZeroMessage(R0, 0.7, "manual", "hip", 25)
    msg = parse(encode_zero(zero, session=4, seq=0, suit_time=9.48, send_time=9.0))
    assert (msg["type"], msg["suit_time"], msg["source"], msg["window"]) == (3, 9.48, 0, 25)
    assert msg["yaw0"] == 0.7 and msg["R0"][3] is None
    np.testing.assert_array_equal(np.array([r for i, r in enumerate(msg["R0"]) if i != 3]),
                                  np.delete(R0, 3, axis=0).reshape(17, 9))
    again = decode_datagram(encode_zero(zero, session=4, seq=0, suit_time=9.48, send_time=9.0))
    np.testing.assert_array_equal(again.zero.R0, R0)
    blocks = encode_pose_extensions(np.zeros((21, 3)), "isb")
    msg = parse(encode_pose(q, angles, session=4, seq=4, suit_time=0.52, send_time=9.0)
                + blocks)
    assert np.allclose(msg["angles"], angles, atol=1e-6)
    for bad in random_bad_datagrams(300, seed=3):
        assert parse(bad) is None or bad[5] == 2  # its POSE checks are lighter than ours
