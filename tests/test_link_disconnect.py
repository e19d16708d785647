"""Bytes read before a disconnect reach the parser (issue 26.3): no frame is lost when the
suit's end closes right after a frame, whether the transport reports the data and the end in
one call or in two, over a real TCP connection (pyserial's socket://, ≥ 20 runs, since the
loss showed in one run of five) and over a real pseudo-terminal whose other end closes.

The suits here are small scripted peers, not the simulated arbiter: they stream numbered
frames (fake_suit.frame) and close the connection at a chosen frame, so the expected frames
are known exactly."""

from __future__ import annotations

import contextlib
import errno
import os
import select
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from fake_suit import STALE, FakeClock, FakeTransport, ScriptedSuit, frame, sample
from waiting import wait_until

from bpms.firmware.sim.server import pty_available
from bpms.io.link import DeviceGoneError, SerialTransport, SuitLink, TransportEndedError
from bpms.io.link_states import LinkState
from bpms.io.options import SerialOptions
from bpms.io.rawfile import read_raw
from bpms.pipeline.sources import SuitFrameSource

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[1]
SERIAL = SerialOptions(link_lost_after_s=1.0, discovery_timeout_s=0.5, read_timeout_s=0.05)


# --------------------------------------------------------------------------- scripted


class EndingTransport(FakeTransport):
    """A :class:`FakeTransport` whose connection ends once the suit has sent ``after`` frames:
    the read that gets the last bytes reports the end too (``together``: in the same call,
    as :class:`TransportEndedError` carrying them; otherwise the next call raises)."""

    def __init__(self, suit: ScriptedSuit, after: int, together: bool) -> None:
        super().__init__(suit)
        self.after = after
        self.together = together
        self.ended = False
        self.handed: list[int] = []  # sample numbers of the frames this transport handed over

    def _hand(self, data: bytes) -> bytes:
        for k in range(0, len(data) - 339):
            if data[k:k + 2] == b"$#" and data[k + 338:k + 340] == b"#$":
                self.handed.append(sample(data[k:k + 340]))
        return data

    def read(self, wait_s: float) -> bytes:
        if self.ended:
            raise ConnectionResetError(errno.ECONNRESET, "Connection reset by peer")
        data = super().read(wait_s)
        if len(self.suit.sent) < self.after:
            return self._hand(data)
        self.ended = True
        self.suit.streaming = False
        if self.together:
            raise TransportEndedError("connection closed by the suit", self._hand(data))
        return self._hand(data)


@pytest.mark.parametrize("together", [True, False], ids=["data+end in one call", "next call"])
def test_frames_read_with_the_end_of_the_connection_are_delivered(together):
    clock = FakeClock()
    suit = ScriptedSuit(clock)
    transports: list[EndingTransport] = []

    def opener(port: str, baud: int) -> EndingTransport:
        if transports:  # the device stays away
            raise FileNotFoundError(errno.ENOENT, "No such file or directory")
        transports.append(EndingTransport(suit, after=37, together=together))
        return transports[0]

    source = SuitFrameSource("fake", SERIAL, retry_s=30.0, opener=opener, clock=clock,
                             sleep=clock.sleep)
    got = []
    while source.state is not LinkState.GONE and clock() < 10.0:
        got += [sample(e.frame) for e in source.read(0.05)]
    assert source.state is LinkState.GONE
    handed = [k for k in transports[0].handed if k != STALE]
    assert len(handed) >= 37  # the end came with frames still to hand over
    assert got == handed == list(range(len(handed)))


def test_frames_that_arrive_during_a_probe_survive_the_end():
    """The suit starts streaming again while it is probed, and the connection ends: the
    frames the probe read are handed over (``take_pending``)."""
    chunks = [b"", frame(1) + frame(2)]

    class Probed:
        def read(self, wait_s: float) -> bytes:
            if chunks:
                return chunks.pop(0)
            raise TransportEndedError("gone", frame(3))

        def write(self, data: bytes) -> None:
            pass

        def close(self, goodbye: bytes = b"") -> None:
            pass

    link = SuitLink("probed", transport=Probed(), reply_timeout_s=5.0)
    with pytest.raises(DeviceGoneError):
        link.probe(grace_s=10.0)
    assert [sample(f) for f in link.take_pending()] == [1, 2, 3]


# --------------------------------------------------------------------------- TCP


class ClosingSuit:
    """A suit on 127.0.0.1 that answers 0x02 / 0x01 / 0x00 like the arbiter, streams
    ``frames`` numbered frames (the stale one first) at 50 Hz and closes the connection right
    after the last one, which it sends with the ``burst - 1`` before it in one write. Further
    connections are refused (the listener is closed)."""

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
                if not ready:
                    return
                data = conn.recv(64)
                if not data:
                    return
                for byte in data:
                    if byte == 0x02:
                        conn.sendall(b"BPMS")
                    elif byte == 0x01:
                        conn.sendall(b"V3.30\n")
                    elif byte == 0x00:
                        self._stream(conn)
                        return

    def _stream(self, conn: socket.socket) -> None:
        conn.sendall(frame(STALE))
        for k in range(self.frames - self.burst):
            time.sleep(0.02)
            conn.sendall(frame(k))
        time.sleep(0.02)
        conn.sendall(b"".join(frame(k) for k in range(self.frames - self.burst, self.frames)))
        conn.shutdown(socket.SHUT_WR)  # right after the frame: FIN follows the data
        self.done.set()

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.listener.close()
        self.thread.join(5)


def read_until_gone(source: SuitFrameSource, timeout: float = 10.0) -> list[int]:
    got: list[int] = []

    def step() -> bool:
        got.extend(sample(e.frame) for e in source.read(0.05))
        return source.state is LinkState.GONE

    assert wait_until(step, timeout), source.status()
    return got


def test_a_tcp_suit_that_closes_right_after_a_frame_loses_nothing_in_20_runs():
    losses = []
    for _ in range(20):
        suit = ClosingSuit(frames=8)
        source = SuitFrameSource(suit.url, SERIAL, retry_s=60.0)
        try:
            source.connect()
            got = read_until_gone(source)
        finally:
            source.close()
            suit.close()
        assert suit.done.is_set()
        losses.append(8 - len(got))
        assert got == list(range(len(got)))  # in order, nothing stale or doubled
    assert losses == [0] * 20


def test_bpms_record_keeps_the_last_frames_of_a_tcp_suit_that_closes(tmp_path):
    """The field recorder as a real process: the file holds every frame sent."""
    suit = ClosingSuit(frames=60, burst=5)
    proc = subprocess.Popen([sys.executable, "-m", "bpms", "record", suit.url, "-o",
                             str(tmp_path), "--name", "closing"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert suit.done.wait(60), "the recorder never started the stream"
        lines: list[str] = []

        def gone() -> bool:
            lines.append(proc.stdout.readline())
            return " gone " in lines[-1] or " reopening " in lines[-1]

        assert wait_until(gone, 30), "".join(lines)
    finally:
        proc.send_signal(__import__("signal").SIGINT)
        _, err = proc.communicate(timeout=30)
        suit.close()
    assert "Traceback" not in err
    recording = read_raw(tmp_path / "Raw_closing_1.bpmsraw")
    assert [sample(recording.frame_bytes(k)) for k in range(len(recording))] == list(range(60))


# --------------------------------------------------------------------------- pseudo-terminal


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


@pytest.mark.skipif(not pty_available(), reason="this platform has no pseudo-terminals")
def test_a_pseudo_terminal_whose_other_end_closes_after_a_frame():
    """The suit's end of a real pty writes frames and closes as soon as the host has read the
    last one (the kernel discards what is still unread when a pty closes, as a radio loses
    what is in flight): every frame the host read is delivered, then the link is gone."""
    import tty

    for run in range(5):
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)
        path = os.ttyname(slave)
        n = 10 + run
        opened: list[CountingTransport] = []

        def opener(port: str, baud: int, opened: list = opened) -> CountingTransport:
            opened.append(CountingTransport(port, baud))
            return opened[-1]

        def serve(master: int = master, n: int = n, opened: list = opened) -> None:
            written = 0
            while True:
                ready, _, _ = select.select([master], [], [], 10.0)
                if not ready:
                    return
                for byte in os.read(master, 64):
                    reply = {0x02: b"BPMS", 0x01: b"V3.30\n"}.get(byte, b"")
                    written += os.write(master, reply) if reply else 0
                    if byte == 0x00:
                        written += os.write(master, frame(STALE))
                        for k in range(n):
                            time.sleep(0.02)
                            written += os.write(master, frame(k))
                        wait_until(lambda total=written: opened[-1].read_bytes >= total, 5.0)
                        os.close(master)  # right after the host read the last frame
                        return

        thread = threading.Thread(target=serve, daemon=True)
        thread.start()
        source = SuitFrameSource(path, SERIAL, retry_s=60.0, opener=opener)
        try:
            source.connect()
            got = read_until_gone(source)
        finally:
            source.close()
            thread.join(5)
            os.close(slave)
        assert got == list(range(n))
