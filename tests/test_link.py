"""The suit link against the simulated suit over real pseudo-terminals and TCP sockets."""

from __future__ import annotations

import itertools
import os
import select
import threading
import time
import tty

import pytest
from pty_suit import suit_pty
from waiting import wait_until

from bpms.firmware.sim.arbiter import Arbiter, Faults, MotionSource
from bpms.firmware.sim.server import TcpServer
from bpms.io.frames import decode_frame
from bpms.io.link import LinkError, SuitLink, discover_suit, list_candidate_ports

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(scope="module")
def source() -> MotionSource:
    return MotionSource.simulated(duration_s=12.0, seed=7)


def check_sequence(frames: list[bytes], source: MotionSource, first: int = 0) -> None:
    for j, frame in enumerate(frames):
        assert frame == source.frame(first + j), f"frame {j} is not motion sample {first + j}"


def test_end_to_end_over_a_pty(source):
    with suit_pty(Arbiter(source)) as (server, pty_path):
        assert discover_suit([pty_path], timeout_s=1.0) == pty_path
        with SuitLink(pty_path, reply_timeout_s=1.0) as link:
            link.identify()
            volts = link.battery_volts()
            assert 2.6 <= volts <= 3.6
            link.start()
            t0 = time.monotonic()
            frames: list[bytes] = []
            while time.monotonic() - t0 < 5.0:
                frames += link.read_frames(0.05)
            elapsed = time.monotonic() - t0
            link.stop()
            tail = link.read_frames(0.1)
            assert link.read_frames(0.1) == []  # quiet after stop
            assert link.battery_volts() == pytest.approx(volts, abs=0.01)
        # 50 Hz ± 2 % over the 5 s window (the stale frame came before t0).
        assert abs(len(frames) / elapsed - 50.0) <= 1.0
        # The first frame received is motion sample 0, not the stale all-zero reading.
        assert frames[0] == source.frame(0) and decode_frame(frames[0]).raw.any()
        check_sequence(frames + tail, source)
        assert link.parser.stats.resyncs == 0 and link.parser.stats.discarded_bytes == 0
        assert link.stats.stale_discarded == 1
        assert server.arbiter.stats.frames_sent == len(frames) + len(tail) + 1


def test_tcp_transport_one_client_at_a_time(source):
    with TcpServer(Arbiter(source)) as server:
        assert server.url.startswith("socket://127.0.0.1:")
        assert discover_suit([server.url], timeout_s=1.0) == server.url
        with SuitLink(server.url) as link:
            link.identify()
            link.start()
            frames: list[bytes] = []
            t0 = time.monotonic()
            while time.monotonic() - t0 < 1.0:
                frames += link.read_frames(0.05)
        # Closed while streaming: the server stops the stream for the next client.
        assert wait_until(lambda: not server.arbiter.streaming, 10)
        with SuitLink(server.url) as again:
            assert again.battery_volts() > 2.6
            again.start()
            more = again.read_frames(0.5)
            again.stop()
            more += again.read_frames(0.1)
        assert 45 <= len(frames) <= 55
        check_sequence(frames, source)
        n = len(frames)
        # The frame sent at the first client's disconnect may have been lost with it.
        assert more[0] in (source.frame(n), source.frame(n + 1))
        assert server.clients == 3


def test_fault_injection_is_counted_by_the_parser(source):
    faults = Faults(drop_rate=0.05, corrupt_rate=0.02, error_rate=0.001)
    arbiter = Arbiter(source, faults, realtime=False, seed=11)
    with suit_pty(arbiter) as (_server, pty_path), SuitLink(pty_path) as link:
        link.start()
        frames: list[bytes] = []
        t0 = time.monotonic()
        while len(frames) < 1500 and time.monotonic() - t0 < 20:
            frames += link.read_frames(0.05)
        link.stop()
        frames += link.read_frames(0.1)
    st = arbiter.stats
    ps = link.parser.stats
    damaged = st.frames_with_dropped_bytes
    assert damaged > 40 and st.corrupted_frames > 10 and st.error_flags > 0
    assert ps.resyncs >= 0.8 * damaged and ps.discarded_bytes > 300 * damaged
    sent = st.frames_sent - 1  # without the stale frame
    assert sent - damaged - st.corrupted_frames <= len(frames) <= sent - damaged + 1


def test_pty_survives_clients_closing_and_reopening(source):
    with suit_pty(Arbiter(source)) as (_server, pty_path):
        for _ in range(3):
            with SuitLink(pty_path) as link:
                link.identify()


def test_a_host_that_does_not_read_does_not_block_the_suit(source):
    with suit_pty(Arbiter(source)) as (server, pty_path), SuitLink(pty_path) as link:
        link.start()
        t0 = time.monotonic()  # the pty holds ≈ 50 frames, the server's backlog 16 more
        while server.frames_unread == 0 and time.monotonic() - t0 < 6.0:
            time.sleep(0.1)
        assert server.frames_unread > 0
        link.stop()  # the suit still answers: the reply comes after the backlog
        assert not server.arbiter.streaming


class GarbagePty:
    """A pty whose far end answers every byte with junk (a port that is not the suit)."""

    def __init__(self, reply: bytes | None = b"OK\r\n\x00\xff garbage") -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.reply = reply
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.02)
            if ready:
                os.read(self.master, 1024)
                if self.reply:
                    os.write(self.master, self.reply)

    def __enter__(self) -> GarbagePty:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(1.0)
        os.close(self.master)
        os.close(self.slave)


def test_bad_ports_raise_one_line_errors():
    with pytest.raises(LinkError, match="cannot open /dev/nonexistent-bpms") as exc:
        SuitLink("/dev/nonexistent-bpms")
    assert "\n" not in str(exc.value)
    with pytest.raises(LinkError, match=r"Connection refused|cannot open"):
        SuitLink("socket://127.0.0.1:1")
    with GarbagePty() as garbage, SuitLink(garbage.path, reply_timeout_s=0.3) as link:
        with pytest.raises(LinkError, match=r"did not answer 'BPMS' within 0\.3 s") as exc:
            link.identify()
        assert "\n" not in str(exc.value)
        with pytest.raises(LinkError, match="battery"):
            link.battery_volts()
    with (GarbagePty(reply=None) as silent, SuitLink(silent.path, reply_timeout_s=0.2) as link,
          pytest.raises(LinkError, match="no answer")):
        link.identify()
    with (GarbagePty(reply=b"BPMS") as mute, SuitLink(mute.path, reply_timeout_s=0.2) as link,
          pytest.raises(LinkError, match=r"no frame within 0\.2 s of the start command")):
        link.start()


def test_discovery_skips_ports_that_are_not_the_suit(source):
    with GarbagePty() as garbage, suit_pty(Arbiter(source)) as (_server, pty_path):
        candidates = ["/dev/nonexistent-bpms", garbage.path, pty_path]
        assert discover_suit(candidates, timeout_s=0.3) == pty_path
        assert discover_suit(candidates[:2], timeout_s=0.3) is None


def test_candidate_ports_are_strings():
    ports = list_candidate_ports()
    assert isinstance(ports, list) and all(isinstance(p, str) for p in ports)


def test_a_vanishing_tcp_suit_raises_link_error(source):
    server = TcpServer(Arbiter(source)).start()
    with SuitLink(server.url) as link:
        link.start()
        assert link.read_frames(0.5)
        server.stop()
        with pytest.raises(LinkError, match="cannot read from socket://"):
            t0 = time.monotonic()
            while time.monotonic() - t0 < 5.0:
                link.read_frames(0.05)
        assert not link.streaming


def test_start_after_a_host_left_the_suit_streaming(source):
    with suit_pty(Arbiter(source)) as (server, pty_path):
        with SuitLink(pty_path) as first:
            first.start()
            first.read_frames(0.3)
        sent = server.arbiter.stats.frames_sent
        # still streaming, nobody reading
        assert wait_until(lambda: server.arbiter.stats.frames_sent >= sent + 10, 10)
        with SuitLink(pty_path) as second:
            # old-stream frames arrive after the open's input flush
            sent = server.arbiter.stats.frames_sent
            assert wait_until(lambda: server.arbiter.stats.frames_sent >= sent + 3, 10)
            second.start()
            frames = second.read_frames(0.3)
            second.stop()
            frames += second.read_frames(0.1)
            skipped = second.stats.reply_bytes_skipped
        # Old frames went before the sync reply; the new stream is consecutive samples that
        # end with the last one the suit sent.
        assert skipped > 0 and second.parser.stats.discarded_bytes == 0
        check_sequence(frames, source, first=server.arbiter.motion_index - len(frames))


def test_silence_while_streaming_over_a_pty(source):
    with suit_pty(Arbiter(source)) as (server, pty_path), SuitLink(pty_path) as link:
        link.start()
        arrivals: list[float] = []
        t0 = time.monotonic()
        silenced = False
        while time.monotonic() - t0 < 1.5:
            if not silenced and time.monotonic() - t0 > 0.3:
                server.arbiter.silence(0.5)  # from this thread, while the server polls
                silenced = True
            arrivals += [time.monotonic()] * len(link.read_frames(0.02))
        gaps = [b - a for a, b in itertools.pairwise(arrivals)]
        assert max(gaps) >= 0.45 and len(arrivals) > 40  # it came back after the silence
        assert server.arbiter.stats.silenced_frames >= 20
