"""Bytes read before a disconnect reach the parser (issue 26.3): no frame is lost when the
suit's end closes right after a frame, whether the transport reports the data and the end in
one call or in two, over a real TCP connection (pyserial's socket://, ≥ 20 runs, since the
loss showed in one run of five) and over a real pseudo-terminal whose other end closes.

The suits here are small scripted peers (tests/fake_suit.py, tools/hostile_peers.py), not the
simulated arbiter: they stream numbered frames and close the connection at a chosen frame, so
the expected frames are known exactly."""

from __future__ import annotations

import errno
import importlib.util
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from fake_suit import STALE, FakeClock, FakeTransport, ScriptedSuit, frame, sample
from waiting import wait_until

from bpms.firmware.sim.server import pty_available
from bpms.io.link import DeviceGoneError, SuitLink, TransportEndedError
from bpms.io.link_states import LinkState
from bpms.io.options import SerialOptions
from bpms.io.rawfile import read_raw
from bpms.pipeline.sources import SuitFrameSource

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("hostile_peers", ROOT / "tools" / "hostile_peers.py")
peers = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(peers)
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


def test_a_tcp_suit_that_closes_right_after_a_frame_loses_nothing_in_20_runs():
    losses = []
    for _ in range(20):
        got, state = peers.closing_tcp_run(frames=8, burst=3)
        assert state is LinkState.GONE
        assert got == list(range(len(got)))  # in order, nothing stale or doubled
        losses.append(8 - len(got))
    assert losses == [0] * 20


def test_bpms_record_keeps_the_last_frames_of_a_tcp_suit_that_closes(tmp_path):
    """The field recorder as a real process: the file holds every frame sent."""
    suit = peers.ClosingTcpSuit(frames=60, burst=5)
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
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
        suit.close()
    assert "Traceback" not in err
    recording = read_raw(tmp_path / "Raw_closing_1.bpmsraw")
    assert [sample(recording.frame_bytes(k)) for k in range(len(recording))] == list(range(60))


# --------------------------------------------------------------------------- pseudo-terminal


@pytest.mark.skipif(not pty_available(), reason="this platform has no pseudo-terminals")
def test_a_pseudo_terminal_whose_other_end_closes_after_a_frame():
    """The suit's end of a real pty closes as soon as the host has read the last frame: every
    frame the host read is delivered, then the link is gone (5 runs)."""
    for run in range(5):
        got, state = peers.closing_pty_run(frames=10 + run)
        assert state is LinkState.GONE
        assert got == list(range(10 + run))
