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
