"""A scripted fake suit on a fake clock: deterministic link-state tests without real time.

:class:`ScriptedSuit` plays the arbiter protocol (0x00 start with a stale first frame, 0x01
battery, 0x02 ``BPMS``, any byte stops a stream) and a script of faults at given times:

- ``("silence", t, s)``: the radio carries nothing either way for ``s`` seconds; the suit
  keeps streaming, the frames due meanwhile are lost (never sent);
- ``("power_cycle", t, s)``: the suit is off for ``s`` seconds, then on, idle;
- ``("gone", t, s)``: the port fails (reads and writes raise OSError, opening fails) for
  ``s`` seconds; afterwards the device is back, idle (a reopened port, a new TCP client);
- ``("tcp_drop", t, s)``: like ``gone`` with TCP's errors (reset, then refused);
- ``("bytes", t, b)``: the suit sends these bytes.

Frames carry their motion-sample number (uint32 LE at offset 2); the stale frame sent after
a start carries :data:`STALE`. :attr:`ScriptedSuit.sent` lists the sample numbers sent.
"""

from __future__ import annotations

import errno
import struct

from bpms.io.link import LinkClosedError

STALE = 0xFFFFFFFF
PERIOD = 0.02


def frame(k: int) -> bytes:
    return b"$#" + struct.pack("<I", k) + bytes(332) + b"#$"


def sample(frame_bytes: bytes) -> int:
    return struct.unpack_from("<I", frame_bytes, 2)[0]


class FakeClock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += max(seconds, 0.0)


class ScriptedSuit:
    def __init__(self, clock: FakeClock, script: list[tuple] = ()) -> None:
        self.clock = clock
        self.script = sorted(script, key=lambda e: e[1])
        self.streaming = False
        self.k = 0
        self.next_frame = 0.0
        self.silent_until = -1.0
        self.off_until = -1.0
        self.gone_until = -1.0
        self.gone_kind = "gone"
        self.generation = 0  # a port opened before a failure stays failed
        self.out = bytearray()
        self.sent: list[int] = []
        self.stale_sent = 0
        self.host_bytes: list[tuple[float, bytes]] = []  # (time, bytes) heard by the suit
        self.opens = 0

    # -- the suit's life ------------------------------------------------------------------
    def reachable(self, t: float) -> bool:
        return t >= self.silent_until and t >= self.off_until and t >= self.gone_until

    def advance(self) -> None:
        now = self.clock()
        while True:
            te = self.script[0][1] if self.script else float("inf")
            tf = self.next_frame if self.streaming else float("inf")
            t = min(te, tf)
            if t > now:
                return
            if te <= tf:
                self._apply(self.script.pop(0))
                continue
            if self.reachable(t):
                self.out += frame(self.k)
                self.sent.append(self.k)
            self.k += 1
            self.next_frame += PERIOD

    def _apply(self, event: tuple) -> None:
        kind, t, arg = event
        if kind == "silence":
            self.silent_until = t + arg
        elif kind == "power_cycle":
            self.streaming = False
            self.off_until = t + arg
            self.out.clear()
        elif kind in ("gone", "tcp_drop"):
            self.streaming = False
            self.gone_until = t + arg
            self.gone_kind = kind
            self.generation += 1
            self.out.clear()
        elif kind == "bytes":
            self.out += arg

    def next_time(self) -> float:
        te = self.script[0][1] if self.script else float("inf")
        tf = self.next_frame if self.streaming else float("inf")
        return min(te, tf)

    def hear(self, data: bytes) -> None:
        now = self.clock()
        self.advance()
        if not self.reachable(now):
            return
        self.host_bytes.append((now, bytes(data)))
        for byte in data:
            if self.streaming:
                self.streaming = False
                if byte != 0x02:
                    continue
            if byte == 0x02:
                self.out += b"BPMS"
            elif byte == 0x01:
                self.out += b"V3.30\n"
            elif byte == 0x00:
                self.out += frame(STALE)
                self.stale_sent += 1
                self.streaming = True
                self.next_frame = now + PERIOD

    # -- the host's side ------------------------------------------------------------------
    def open(self, port: str, baud: int) -> FakeTransport:
        self.advance()
        if self.clock() < self.gone_until:
            if self.gone_kind == "tcp_drop":
                raise ConnectionRefusedError(errno.ECONNREFUSED, "Connection refused")
            raise FileNotFoundError(errno.ENOENT, "No such file or directory")
        self.opens += 1
        return FakeTransport(self)


class FakeTransport:
    """The host's end of :class:`ScriptedSuit` (a :class:`bpms.io.link.Transport`)."""

    def __init__(self, suit: ScriptedSuit) -> None:
        self.suit = suit
        self.generation = suit.generation
        self.closed = False
        self.goodbye = b""

    def _check(self) -> None:
        if self.closed:
            raise LinkClosedError("closed")
        if self.generation != self.suit.generation:
            if self.suit.gone_kind == "tcp_drop":
                raise ConnectionResetError(errno.ECONNRESET, "Connection reset by peer")
            raise OSError(errno.EIO, "Input/output error")

    def read(self, wait_s: float) -> bytes:
        suit = self.suit
        suit.advance()
        self._check()
        if not suit.out:
            target = min(suit.clock() + max(wait_s, 0.0), suit.next_time())
            suit.clock.t = max(suit.clock.t, target)
            suit.advance()
            self._check()
        data = bytes(suit.out)
        suit.out.clear()
        return data

    def write(self, data: bytes) -> None:
        self._check()
        self.suit.hear(data)

    def close(self, goodbye: bytes = b"") -> None:
        if not self.closed and goodbye and self.generation == self.suit.generation:
            self.suit.hear(goodbye)
        self.closed = True
