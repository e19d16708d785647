"""Every transition of the suit link's state machine, driven by a scripted fake suit on a fake
clock (tests/fake_suit.py), and the thread-safe close over a real pseudo-terminal."""

from __future__ import annotations

import threading
import time

import pytest
from fake_suit import STALE, FakeClock, ScriptedSuit, sample
from pty_suit import suit_pty
from waiting import inside, wait_until

from bpms.firmware.sim.arbiter import Arbiter, MotionSource
from bpms.io.link_states import TRANSITIONS, LinkEvent, LinkState, TransitionError, next_state
from bpms.io.options import SerialOptions
from bpms.pipeline.sources import SuitFrameSource

pytestmark = pytest.mark.timeout(60)
S = LinkState


class Run:
    """A SuitFrameSource on a ScriptedSuit; ``until(t)`` reads until fake time ``t``."""

    def __init__(self, script: list[tuple]) -> None:
        self.clock = FakeClock()
        self.suit = ScriptedSuit(self.clock, script)
        serial = SerialOptions(link_lost_after_s=1.0, discovery_timeout_s=0.3,
                               read_timeout_s=0.05)
        self.source = SuitFrameSource("fake", serial, retry_s=1.0, opener=self.suit.open,
                                      clock=self.clock, sleep=self.clock.sleep)
        self.events = []  # (fake time, FrameEvent)
        self.states = [S.CONNECTING]

    def until(self, t: float) -> Run:
        while self.clock() < t:
            for e in self.source.read(0.05):
                self.events.append((self.clock(), e))
            if self.source.state is not self.states[-1]:
                self.states.append(self.source.state)
        return self

    @property
    def samples(self) -> list[int]:
        return [sample(e.frame) for _, e in self.events]

    def first_after(self, t: float) -> float:
        return next(tt for tt, _ in self.events if tt > t)

    def check_nothing_lost_or_stale(self) -> None:
        got = self.samples
        assert STALE not in got  # no stale frame ever reaches the pipeline
        assert len(set(got)) == len(got)  # no duplicate
        assert got == self.suit.sent  # every frame the suit sent, in order


def test_the_table_is_explicit():
    # every state but closed can be closed; closed is final; unknown pairs are refused
    for state in LinkState:
        if state is not S.CLOSED:
            assert next_state(state, LinkEvent.CLOSE) is S.CLOSED
    assert not any(src is S.CLOSED for src, _ in TRANSITIONS)
    with pytest.raises(TransitionError, match="'frames' in state 'gone'"):
        next_state(S.GONE, LinkEvent.FRAMES)
    assert set(TRANSITIONS.values()) == set(LinkState)  # every state is reachable


def test_connect_then_stream():
    run = Run([]).until(2.0)
    assert run.states == [S.CONNECTING, S.STREAMING]
    assert run.suit.stale_sent == 1 and len(run.events) >= 90
    assert run.events[0][1].discontinuity and not any(e.discontinuity for _, e in run.events[1:])
    run.check_nothing_lost_or_stale()


def test_silence_then_the_suit_streams_again():
    # The suit returns at 5.5 s, between two probes (at 4.0 and 5.0 s).
    run = Run([("silence", 2.0, 3.5)]).until(8.0)
    assert run.states == [S.CONNECTING, S.STREAMING, S.SILENT, S.STREAMING]
    assert run.source.links_lost == 1 and run.source.restarts == 0
    back = run.first_after(5.4)
    assert back - 5.5 <= 0.1  # taken at once: the port kept listening
    assert run.suit.stale_sent == 1  # never restarted
    first_back = next(e for tt, e in run.events if tt == back)
    assert first_back.discontinuity
    # only the frames due while the suit was really silent are missing
    got = run.samples
    missing = sorted(set(range(got[-1] + 1)) - set(got))
    assert len(missing) == pytest.approx(3.5 / 0.02, abs=2)
    run.check_nothing_lost_or_stale()
    into_silent = [(old, ev) for old, ev, new in run.source.history
                   if new is S.SILENT and old is not S.SILENT]
    assert into_silent == [(S.STREAMING, LinkEvent.QUIET)]
    probes = [ev for old, ev, new in run.source.history if old is new is S.SILENT]
    assert probes == [LinkEvent.PROBE_UNANSWERED] * 2  # at 4.0 and 5.0 s


def test_silence_then_the_suit_was_power_cycled():
    run = Run([("power_cycle", 2.0, 3.0)]).until(9.0)
    assert run.states == [S.CONNECTING, S.STREAMING, S.SILENT, S.STREAMING]
    assert (S.SILENT, LinkEvent.RESTARTED, S.STREAMING) in run.source.history
    assert run.source.restarts == 1 and run.suit.stale_sent == 2  # a new start, stale dropped
    back = run.first_after(4.9)
    assert back - 5.0 <= 2.0  # goal: frames flow within 2 s of the suit's return
    run.check_nothing_lost_or_stale()


def test_read_error_then_the_device_returns_after_n_seconds():
    run = Run([("gone", 2.0, 3.5)]).until(9.0)
    assert run.states[:3] == [S.CONNECTING, S.STREAMING, S.GONE]
    assert run.states[-1] is S.STREAMING
    assert (S.GONE, LinkEvent.RETRY, S.REOPENING) in run.source.history
    assert (S.REOPENING, LinkEvent.OPEN_FAILED, S.GONE) in run.source.history
    assert (S.REOPENING, LinkEvent.OPENED, S.STREAMING) in run.source.history
    assert run.source.connections == 2 and run.source.links_lost == 1
    assert run.first_after(5.4) - 5.5 <= 2.0
    run.check_nothing_lost_or_stale()


def test_tcp_connection_dropped_and_the_server_listening_again():
    run = Run([("tcp_drop", 2.0, 2.0)])
    run.until(3.0)
    assert run.source.state in (S.GONE, S.REOPENING)
    assert "reset" in run.source.reason.lower() or "refused" in run.source.reason.lower()
    run.until(8.0)
    assert run.source.state is S.STREAMING and run.source.connections == 2
    assert run.first_after(3.9) - 4.0 <= 2.0
    run.check_nothing_lost_or_stale()


def test_stop_data_during_silence():
    run = Run([("silence", 2.0, 5.0)]).until(3.5)
    assert run.source.state is S.SILENT
    run.source.stop_stream()
    run.until(3.6)
    assert run.source.state is S.STOPPED
    heard = len(run.suit.host_bytes)
    run.until(6.5)  # no probes while stopped: nothing more is sent to the suit
    assert run.source.state is S.STOPPED and len(run.suit.host_bytes) == heard
    run.until(9.0)  # the suit returns still streaming (it never heard the stop): told again
    assert not run.suit.streaming and run.source.state is S.STOPPED
    run.source.start_stream()
    run.until(11.0)
    assert run.source.state is S.STREAMING and run.suit.stale_sent == 2
    assert run.states[-3:] == [S.SILENT, S.STOPPED, S.STREAMING]
    run.check_nothing_lost_or_stale()


def test_a_probe_that_meets_the_returning_suit():
    # The suit returns at 5.0 s, just as a probe goes out: the probe stops its stream and
    # gets BPMS, so the stream is restarted (stale frame dropped); within the 1 s goal.
    run = Run([("silence", 2.0, 3.0)]).until(8.0)
    assert run.states[-1] is S.STREAMING
    assert run.first_after(4.9) - 5.0 <= 1.0
    run.check_nothing_lost_or_stale()


def test_frames_during_an_unanswered_probe_mean_streaming_again():
    # The probe at 4.0 s goes out while the radio is still silent; the suit is back at 4.1 s,
    # within the probe's wait: its frames end the wait (no restart, no stale frame).
    run = Run([("silence", 2.0, 2.1)]).until(7.0)
    assert run.states == [S.CONNECTING, S.STREAMING, S.SILENT, S.STREAMING]
    assert run.source.restarts == 0 and run.suit.stale_sent == 1
    assert run.first_after(4.05) - 4.1 <= 0.2
    run.check_nothing_lost_or_stale()


def test_start_data_while_the_suit_is_away_goes_silent_then_recovers():
    run = Run([("silence", 2.0, 4.0)]).until(1.0)
    run.source.stop_stream()
    run.until(2.5)
    assert run.source.state is S.STOPPED
    run.source.start_stream()
    run.until(3.5)
    assert (S.STOPPED, LinkEvent.START_FAILED, S.SILENT) in run.source.history
    run.until(9.0)
    assert run.source.state is S.STREAMING
    run.check_nothing_lost_or_stale()


def test_close_from_another_thread_wakes_a_blocking_read():
    motion = MotionSource.simulated(duration_s=5.0, seed=3)
    with suit_pty(Arbiter(motion)) as (_server, pty_path):
        source = SuitFrameSource(pty_path, SerialOptions())
        source.stop_stream()  # connected, nothing streaming: a read blocks for its timeout
        source.connect()
        assert source.state is S.STOPPED
        done = threading.Event()
        errors: list[BaseException] = []

        def reader() -> None:
            try:
                while source.state is not S.CLOSED:
                    source.read(30.0)
            except BaseException as exc:
                errors.append(exc)
            done.set()

        thread = threading.Thread(target=reader, daemon=True)
        thread.start()
        assert wait_until(lambda: inside(thread, "read"), 10)  # blocked in its read
        t0 = time.monotonic()
        source.close()
        assert done.wait(5.0)
        woke = time.monotonic() - t0
    assert errors == [] and source.state is S.CLOSED
    assert woke < 2.0  # far below the 30 s read timeout
    assert source.read(0.1) == []


def test_a_connect_that_finishes_after_close_leaves_nothing_open():
    run = Run([])
    run.source.close()  # e.g. the GUI closed while a connect was under way
    run.source.connect()
    assert run.source.state is S.CLOSED and run.source.connected_port is None
    assert run.suit.opens == 1 and not run.suit.streaming  # the stream it started was stopped
    assert run.source.read(0.1) == []
