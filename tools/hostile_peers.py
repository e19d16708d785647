"""Peers that end badly, for tests/test_link_disconnect.py and bench/hostile_input.py.

- :class:`ClosingTcpSuit`: a suit on 127.0.0.1 that answers like the arbiter (0x02 ``BPMS``,
  0x01 battery, 0x00 start with a stale first frame), streams numbered frames at 50 Hz and
  closes the connection right after the last one, sent together with the few before it;
- :func:`closing_pty_run`: the same over a real pseudo-terminal whose suit end closes as soon
  as the host has read the last frame;
- :func:`read_until_gone`: the host side, :class:`bpms.pipeline.sources.SuitFrameSource`
  read until the link is *gone*.

Frames carry their number (uint32 little-endian at offset 2); the stale frame carries
:data:`STALE`. So the frames a correct host delivers are known exactly: 0, 1, …, n − 1.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import struct
import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from bpms.io.link import SerialTransport  # noqa: E402
from bpms.io.link_states import LinkState  # noqa: E402
from bpms.io.options import SerialOptions  # noqa: E402
from bpms.pipeline.sources import SuitFrameSource  # noqa: E402

STALE = 0xFFFFFFFF
SERIAL = SerialOptions(link_lost_after_s=1.0, discovery_timeout_s=0.5, read_timeout_s=0.05)


def frame(k: int) -> bytes:
    """A 340-byte frame carrying the number ``k``."""
    return b"$#" + struct.pack("<I", k) + bytes(332) + b"#$"


def sample(frame_bytes: bytes) -> int:
    return struct.unpack_from("<I", frame_bytes, 2)[0]


def _answer(byte: int) -> bytes:
    return {0x02: b"BPMS", 0x01: b"V3.30\n"}.get(byte, b"")


class ClosingTcpSuit:
    """Streams ``frames`` numbered frames after the start command (the last ``burst`` in one
    write) and closes the connection right after them. Further connections are refused."""

    def __init__(self, frames: int, burst: int = 3) -> None:
        self.frames = frames
        self.burst = burst
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.listener.bind(("127.0.0.1", 0))
        self.listener.listen(1)
        self.url = f"socket://127.0.0.1:{self.listener.getsockname()[1]}"
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        try:
            conn, _ = self.listener.accept()
        except OSError:
            return
        self.listener.close()
        with conn:
            while True:
                ready, _, _ = select.select([conn], [], [], 10.0)
                data = conn.recv(64) if ready else b""
                if not data:
                    return
                for byte in data:
                    conn.sendall(_answer(byte))
                    if byte == 0x00:
                        self._stream(conn)
                        return

    def _stream(self, conn: socket.socket) -> None:
        conn.sendall(frame(STALE))
        for k in range(self.frames - self.burst):
            time.sleep(0.02)
            conn.sendall(frame(k))
        time.sleep(0.02)
        conn.sendall(b"".join(frame(k) for k in range(self.frames - self.burst, self.frames)))
        conn.shutdown(socket.SHUT_WR)  # right after the frame: the FIN follows the data
        self.done.set()

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.listener.close()
        self.thread.join(5)


def read_until_gone(source: SuitFrameSource, timeout: float = 10.0) -> list[int]:
    """The frame numbers ``source`` delivers until its link is gone (or ``timeout`` s)."""
    got: list[int] = []
    deadline = time.monotonic() + timeout
    while source.state is not LinkState.GONE and time.monotonic() < deadline:
        got.extend(sample(e.frame) for e in source.read(0.05))
    return got


def closing_tcp_run(frames: int = 8, burst: int = 3) -> tuple[list[int], LinkState]:
    """One connection to a :class:`ClosingTcpSuit`: (frame numbers delivered, final state)."""
    suit = ClosingTcpSuit(frames, burst)
    source = SuitFrameSource(suit.url, SERIAL, retry_s=60.0)
    try:
        source.connect()
        got = read_until_gone(source)
        return got, source.state
    finally:
        source.close()
        suit.close()


class CountingTransport:
    """pyserial's transport, counting the bytes the host has read (so that the suit's end can
    close exactly when everything it wrote has been read)."""

    def __init__(self, port: str, baud: int) -> None:
        self.inner = SerialTransport(port, baud)
        self.read_bytes = 0

    def read(self, wait_s: float) -> bytes:
        data = self.inner.read(wait_s)
        self.read_bytes += len(data)
        return data

    def write(self, data: bytes) -> None:
        self.inner.write(data)

    def close(self, goodbye: bytes = b"") -> None:
        self.inner.close(goodbye)


def closing_pty_run(frames: int) -> tuple[list[int], LinkState]:
    """A real pseudo-terminal whose suit end streams ``frames`` frames and closes as soon as
    the host has read the last one (the kernel drops what is unread when a pty closes, as a
    radio loses what is in flight): (frame numbers delivered, final state). Unix only."""
    import tty

    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    opened: list[CountingTransport] = []

    def opener(port: str, baud: int) -> CountingTransport:
        opened.append(CountingTransport(port, baud))
        return opened[-1]

    def serve() -> None:
        written = 0
        while True:
            ready, _, _ = select.select([master], [], [], 10.0)
            if not ready:
                return
            for byte in os.read(master, 64):
                reply = _answer(byte)
                written += os.write(master, reply) if reply else 0
                if byte == 0x00:
                    written += os.write(master, frame(STALE))
                    for k in range(frames):
                        time.sleep(0.02)
                        written += os.write(master, frame(k))
                    deadline = time.monotonic() + 5.0
                    while opened[-1].read_bytes < written and time.monotonic() < deadline:
                        time.sleep(0.002)
                    os.close(master)  # right after the host read the last frame
                    return

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    source = SuitFrameSource(os.ttyname(slave), SERIAL, retry_s=60.0, opener=opener)
    try:
        source.connect()
        return read_until_gone(source), source.state
    finally:
        source.close()
        thread.join(5)
        os.close(slave)


# --------------------------------------------------------------------------- UDP attackers


class AttackResult:
    """One UDP attack: forged datagrams sent and the forged frames the receiver delivered,
    beside the real sender's frames sent and delivered; ``detected``: what the receiver
    counted (its stats)."""

    def __init__(self, name: str, forged: int, accepted: int, real_sent: int,
                 real_delivered: int, detected: str) -> None:
        self.name = name
        self.forged = forged
        self.accepted = accepted
        self.real_sent = real_sent
        self.real_delivered = real_delivered
        self.detected = detected


def _motion_frames(n: int) -> list[bytes]:
    from bpms.firmware.sim.arbiter import MotionSource

    motion = MotionSource.simulated(duration_s=n * 0.02 + 1.0, seed=26)
    return [motion.frame(j) for j in range(n)]


def _signed_earlier_run(frames: list[bytes], key: bytes) -> list[bytes]:
    from bpms.io.udp.sender import UdpForwarder

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as cap:
        cap.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        cap.bind(("127.0.0.1", 0))
        cap.settimeout(5.0)
        with UdpForwarder([f"127.0.0.1:{cap.getsockname()[1]}"], key=key) as earlier:
            for k, f in enumerate(frames):
                earlier.send_frame(f, k * 0.02)
        return [cap.recv(2048) for _ in frames]


def _receive(src, until: int, out: list[bytes], timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while src.stats.datagrams < until and time.monotonic() < deadline:
        got = src.read(0.01)
        if got is not None:
            out.append(got.frame)
    while (got := src.read(0.0)) is not None:
        out.append(got.frame)


def _paced(fw, frames: list[bytes], first: int = 0, burst: bool = False) -> None:
    t0 = time.monotonic()
    for k, f in enumerate(frames):
        if not burst:
            time.sleep(max(0.0, t0 + k * 0.02 - time.monotonic()))
        fw.send_frame(f, (first + k) * 0.02)


def udp_attacks(key: bytes = b"lab key") -> list[AttackResult]:
    """The attacks of issue 26 on a real receiver (:class:`bpms.io.udp.receiver.UdpSource`,
    default takeover rule) over 127.0.0.1, each beside a real sender. Takes ~15 s (the
    pauses are real)."""
    from bpms.io.udp.codec import MessageType, encode_raw_frame
    from bpms.io.udp.sender import UdpForwarder

    frames = _motion_frames(1600)
    real_frames, fake_frames = frames[:300], frames[300:1200]
    resumed = frames[1200:1591]  # the real sender's frames after its power-cycle
    fake_set = set(fake_frames)
    results = []
    # recorded before any real sender of the runs below starts: an earlier run
    recorded_one = _signed_earlier_run(fake_frames[:1], key)[0]
    recorded_run = _signed_earlier_run(fake_frames[:200], key)

    def run(name: str, keyed: bool, attack) -> None:
        from bpms.commands.monitor import udp_status_line
        from bpms.pipeline.sources import UdpFrameSource

        k = key if keyed else None
        source = UdpFrameSource("127.0.0.1:0", key=k or b"")  # b"": none, not the environment's
        src = source.udp
        with source.udp, UdpForwarder([f"127.0.0.1:{src.address[1]}"], key=k) as real, \
                socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as attacker:
            got: list[bytes] = []
            forged, real_sent = attack(src, real, attacker, got)
            _receive(src, src.stats.datagrams, got, 1.0)
            s = src.stats
            source._state = "streaming"
            shown = udp_status_line(0.0, 0.0, len(got), source.status())
        accepted = sum(f in fake_set for f in got)
        detected = (f"foreign {s.foreign}, replayed {s.replayed}, unauthenticated "
                    f"{s.unauthenticated}, malformed {s.malformed}, conflicts {s.conflicts}, "
                    f"implausible {s.implausible}, stale {s.stale}, lost {s.lost}, "
                    f"switches {s.takeovers}; monitor: "
                    + (shown.split("  streaming")[-1].strip() or "no warning"))
        results.append(AttackResult(name, forged, accepted, real_sent,
                                    sum(f in real_set for f in got), detected))

    def pause_and_one(keyed: bool):
        def attack(src, real, attacker, got):
            forged = (recorded_one if keyed else
                      encode_raw_frame(fake_frames[0], session=0x5EED, seq=0, suit_time=0.0,
                                       send_time=time.time()))
            _paced(real, real_frames[:150])
            _receive(src, 150, got)
            time.sleep(1.5)  # the suit's 3 s pause, the datagram in its middle
            attacker.sendto(forged, src.address)
            time.sleep(1.5)
            _paced(real, real_frames[150:300], 150)
            _receive(src, 301, got)
            return 1, 300
        return attack

    def replayed_run(src, real, attacker, got):
        recorded = recorded_run
        _paced(real, real_frames[:100], burst=True)
        _receive(src, 100, got)
        time.sleep(6.0)  # silent longer than the 5 s takeover time
        for data in recorded:
            attacker.sendto(data, src.address)
        _receive(src, 300, got)
        _paced(real, real_frames[100:200], 100, burst=True)
        _receive(src, 400, got)
        return 200, 200

    def same_session(src, real, attacker, got):
        n = 150
        for j in range(n):
            real.send_frame(real_frames[j], j * 0.02)
            seq = real.next_seq(MessageType.RAW_FRAME) + 3
            data = encode_raw_frame(fake_frames[j], session=real.session, seq=seq,
                                    suit_time=seq * 0.02, send_time=time.time(),
                                    sender=real.sender, epoch=real.epoch)
            attacker.sendto(data, src.address)
            if j % 20 == 19:
                _receive(src, 2 * (j + 1), got)
        for j, jump in enumerate((2**31 - 1, 2**30)):
            seq = real.next_seq(MessageType.RAW_FRAME) + jump
            attacker.sendto(encode_raw_frame(fake_frames[n + j], session=real.session, seq=seq,
                                             suit_time=0.0, send_time=time.time(),
                                             sender=real.sender, epoch=real.epoch), src.address)
        _receive(src, 2 * n + 2, got)
        return n + 2, n

    def foreign_flood(src, real, attacker, got):
        sent = 0
        for j in range(300):
            real.send_frame(real_frames[j], j * 0.02)
            for s in range(5):
                attacker.sendto(encode_raw_frame(fake_frames[(5 * j + s) % 800],
                                                 session=0xF00 + s, seq=j, suit_time=0.0,
                                                 send_time=time.time()), src.address)
                sent += 1
            if j % 10 == 9:
                _receive(src, 6 * (j + 1), got)
        _receive(src, 1800, got)
        return sent, 300

    def fuzz(src, real, attacker, got):
        import random

        rng = random.Random(26)
        sent = 0
        for j in range(300):
            real.send_frame(real_frames[j], j * 0.02)
            good = encode_raw_frame(fake_frames[j], session=real.session, seq=j + 1,
                                    suit_time=0.0, send_time=time.time(), sender=real.sender,
                                    epoch=real.epoch)
            for data in (rng.randbytes(rng.randrange(0, 500)),
                         good[:rng.randrange(0, len(good))],
                         good + rng.randbytes(32),  # a tag flag that is not set: unsigned
                         bytes(b ^ (rng.random() < 0.01) for b in good)):
                attacker.sendto(data, src.address)
                sent += 1
            if j % 10 == 9:
                _receive(src, 5 * (j + 1), got)
        _receive(src, 1500, got)
        return sent, 300

    def signed(frames_, first: int, k, session=0x4545, sender=77, epoch=None):
        """One run's datagrams numbered from ``first``, as its sender made them."""
        from bpms.io.udp.auth import sign_datagram

        epoch = epoch or time.time_ns() // 1000
        out = []
        for j, f in enumerate(frames_):
            d = encode_raw_frame(f, session=session, seq=first + j, suit_time=(first + j) * 0.02,
                                 send_time=time.time(), sender=sender, epoch=epoch)
            out.append(sign_datagram(d, k) if k else d)
        return out

    def late_join_replay(src, real, attacker, got):
        """Issue 45.1: the receiver joins the run at 1,000; its numbers 200-999 replayed."""
        epoch = time.time_ns() // 1000
        live = signed(real_frames[:100], 1000, key, epoch=epoch)
        old = signed(fake_frames[:800], 200, key, epoch=epoch)
        for data in live[:50]:
            attacker.sendto(data, src.address)
        _receive(src, 50, got)
        for data in old:
            attacker.sendto(data, src.address)
        _receive(src, 850, got)
        for data in live[50:]:
            attacker.sendto(data, src.address)
        _receive(src, 900, got)
        return 800, 100

    def old_bursts(src, real, attacker, got):
        """Issue 45.1: numbers more than 32,768 old, in bursts of 40 beside the live sender."""
        epoch = time.time_ns() // 1000
        live = signed(real_frames[:200], 40_000, key, epoch=epoch)
        old = signed(fake_frames[:400], 0, key, epoch=epoch)
        n = 0
        for j, data in enumerate(live):
            attacker.sendto(data, src.address)
            n += 1
            if j % 20 == 19:
                b = (j // 20) * 40
                for old_data in old[b:b + 40]:
                    attacker.sendto(old_data, src.address)
                n += 40
                _receive(src, n, got)
        _receive(src, n, got)
        return 400, 200

    def takeover_return(stranger_key):
        """Issue 45.2: the suit power-cycles 7.5 s; after 5.6 s a stranger sends 70
        datagrams; then the real sender resumes its session with 391 frames."""
        def attack(src, real, attacker, got):
            _paced(real, real_frames[:100])
            _receive(src, 100, got)
            time.sleep(5.6)
            other = signed(fake_frames[:70], 0, stranger_key, session=0x5A5A, sender=99)
            t0 = time.monotonic()
            for j, data in enumerate(other):
                time.sleep(max(0.0, t0 + j * 0.02 - time.monotonic()))
                attacker.sendto(data, src.address)
            _receive(src, 170, got, 2.0)
            time.sleep(max(0.0, 7.5 - 5.6 - 70 * 0.02))
            _paced(real, resumed, 100)
            _receive(src, 561, got)
            return 70, 100 + 391
        return attack

    real_set = set(real_frames) | set(resumed)
    run("one datagram during a 3 s pause (no key)", False, pause_and_one(False))
    run("one replayed signed datagram during a 3 s pause (key)", True, pause_and_one(True))
    run("a recorded signed run replayed after 6 s of silence (key)", True, replayed_run)
    run("a spoofer on the real session, 3 ahead, 2 huge jumps (no key)", False, same_session)
    run("the same spoofer, unsigned (key)", True, same_session)
    run("5 other sessions flooding while the real one streams (no key)", False, foreign_flood)
    run("random, cut and bit-flipped datagrams (key)", True, fuzz)
    run("the run's own numbers 200-999 replayed to a receiver that joined at 1,000 (key)",
        True, late_join_replay)
    run("numbers > 32,768 old in bursts of 40 beside the live sender (key)", True, old_bursts)
    run("a takeover during a 7.5 s power-cycle, the real sender resumes (no key)", False,
        takeover_return(None))
    run("the same with a stranger that holds the key too (second keyholder)", True,
        takeover_return(key))
    run("the same with an unsigned stranger (key)", True, takeover_return(None))
    return results
