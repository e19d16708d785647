"""No takeover of a live session, freshness with a key, a second sender on the same session
(issue 26.1), over real UDP sockets on 127.0.0.1 and with ``bpms monitor --listen`` and
``bpms replay`` as real processes. The rules themselves, on hand-made timelines, are in
tests/test_udp_gate.py.

Every frame a sender sends is distinct (the simulated suit's motion), so which frames were
delivered, and whose, is known exactly."""

from __future__ import annotations

import logging
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from waiting import wait_until

from bpms.firmware.sim.arbiter import MotionSource
from bpms.io.udp.auth import KEY_ENV
from bpms.io.udp.codec import MessageType, encode_raw_frame
from bpms.io.udp.receiver import UdpSource
from bpms.io.udp.sender import UdpForwarder
from bpms.pipeline.sources import UdpFrameSource

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[1]
KEY = b"lab key 26"
PERIOD = 0.02  # the suit's 50 Hz


@pytest.fixture(scope="module")
def frames():
    motion = MotionSource.simulated(duration_s=20.0, seed=26)
    out = [motion.frame(j) for j in range(800)]
    assert len(set(out)) == len(out)
    return out


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def send_at_50_hz(fw: UdpForwarder, frames: list[bytes], first_index: int = 0) -> None:
    """Paced like the suit: one frame every 20 ms (the pacing is the scenario, not a wait)."""
    t0 = time.monotonic()
    for k, frame in enumerate(frames):
        time.sleep(max(0.0, t0 + k * PERIOD - time.monotonic()))
        fw.send_frame(frame, (first_index + k) * PERIOD)


def capture_earlier_run(frames: list[bytes], key: bytes) -> list[bytes]:
    """Signed datagrams of an earlier run with the same key, as an eavesdropper records them."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as cap:
        cap.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        cap.bind(("127.0.0.1", 0))
        cap.settimeout(5.0)
        with UdpForwarder([f"127.0.0.1:{cap.getsockname()[1]}"], key=key) as earlier:
            for k, frame in enumerate(frames):
                earlier.send_frame(frame, k * PERIOD)
        return [cap.recv(2048) for _ in frames]


class Monitor:
    """``bpms monitor --listen`` as a real process; its status lines as they come."""

    LINE = re.compile(r"^t +[\d.]+ s  rate +[\d.]+ Hz  frames +(?P<frames>\d+)  (?P<rest>.*)$")

    def __init__(self, port: int, key: bytes | None = None) -> None:
        env = {k: v for k, v in os.environ.items() if k != KEY_ENV}
        if key:
            env[KEY_ENV] = key.decode()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "bpms", "monitor", "--listen", f"127.0.0.1:{port}",
             "--seconds", "60"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True, env=env)
        self.lines: list[str] = []
        first = self.proc.stdout.readline()
        assert first.startswith("listening for UDP on 127.0.0.1:"), first
        self._thread = threading.Thread(target=self._collect, daemon=True)
        self._thread.start()

    def _collect(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))

    def counters(self, line: str) -> dict[str, int]:
        m = self.LINE.match(line)
        assert m, line
        found = dict(re.findall(r"([a-z]+) (\d+)", m["rest"]))
        return {"frames": int(m["frames"]), **{k: int(v) for k, v in found.items()}}

    def wait_frames(self, n: int, timeout: float = 30.0) -> str:
        def seen() -> bool:
            return any(self.LINE.match(x) and self.counters(x)["frames"] >= n
                       for x in list(self.lines))

        assert wait_until(seen, timeout), "\n".join(self.lines[-10:])
        return next(x for x in list(self.lines)
                    if self.LINE.match(x) and self.counters(x)["frames"] >= n)

    def stop(self) -> str:
        self.proc.send_signal(signal.SIGINT)
        _, err = self.proc.communicate(timeout=30)
        self._thread.join(5)
        assert self.proc.returncode == 0 and "Traceback" not in err, err
        return err


@pytest.mark.parametrize("keyed", [False, True], ids=["no key", "shared key"])
def test_one_datagram_during_a_pause_cuts_nobody_off(keyed, frames):
    """The suit pauses for 3 s and one datagram of another session arrives: without a key one
    of an unknown session, with a key a signed datagram replayed from an earlier run. The
    receiver (a real `bpms monitor --listen`) keeps the real sender: 100 of 100 frames."""
    key = KEY if keyed else None
    port = free_port()
    forged = (capture_earlier_run(frames[700:701], KEY)[0] if keyed else
              encode_raw_frame(frames[700], session=0x5EED, seq=0, suit_time=0.0,
                               send_time=time.time()))
    mon = Monitor(port, key)
    try:
        with UdpForwarder([f"127.0.0.1:{port}"], key=key) as real, \
                socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as attacker:
            send_at_50_hz(real, frames[:50])
            time.sleep(1.5)  # the suit's pause: 3 s in all, the datagram in the middle
            attacker.sendto(forged, ("127.0.0.1", port))
            time.sleep(1.5)
            send_at_50_hz(real, frames[50:100], 50)
            line = mon.wait_frames(100)
    finally:
        mon.stop()
    c = mon.counters(line)
    assert c["frames"] == 100 and c["lost"] == 0
    assert (c["foreign"], c["replayed"]) == ((0, 1) if keyed else (1, 0))
    assert not any("replaced" in x for x in mon.lines)  # no takeover


def test_a_replayed_signed_stream_never_takes_over(frames):
    """A whole recorded run, replayed while the real sender has been silent longer than the
    takeover time: every datagram refused as replayed; the real sender resumes."""
    recorded = capture_earlier_run(frames[600:700], KEY)
    with UdpSource("127.0.0.1:0", key=KEY, takeover_after_s=1.0) as src, \
            UdpForwarder([f"127.0.0.1:{src.address[1]}"], key=KEY) as real, \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as attacker:
        got = []

        def read_until(n: int) -> bool:
            frame = src.read(0.02)
            if frame is not None:
                got.append(frame.frame)
            return src.stats.datagrams >= n

        send_at_50_hz(real, frames[:30])
        assert wait_until(lambda: read_until(30), 10)
        time.sleep(1.5)  # the real sender silent longer than the takeover time
        for data in recorded:
            attacker.sendto(data, src.address)
        assert wait_until(lambda: read_until(130), 10)
        send_at_50_hz(real, frames[30:40], 30)
        assert wait_until(lambda: read_until(140), 10)
        s = src.stats
        assert src.followed.epoch == real.epoch
    assert got == frames[:40]
    assert (s.replayed, s.restarts, s.lost, s.foreign) == (100, 0, 0, 0)


def test_a_second_sender_on_the_same_session_is_detected_and_shown(frames):
    """A spoofer copies the real session id, sender id and epoch (all travel in clear without
    a key) and sends its own frames a few numbers ahead, plus two huge jumps. `bpms monitor
    --listen` says "another sender on this session"; `lost` stays plausible."""
    port = free_port()
    mon = Monitor(port)
    try:
        with UdpForwarder([f"127.0.0.1:{port}"]) as real, \
                socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as spoofer:
            def spoof(k: int, ahead: int) -> None:
                seq = real.next_seq(MessageType.RAW_FRAME) + ahead
                spoofer.sendto(encode_raw_frame(
                    frames[400 + k], session=real.session, seq=seq, suit_time=seq * PERIOD,
                    send_time=time.time(), sender=real.sender, epoch=real.epoch),
                    ("127.0.0.1", port))

            t0 = time.monotonic()
            for k in range(150):
                time.sleep(max(0.0, t0 + k * PERIOD - time.monotonic()))
                real.send_frame(frames[k], k * PERIOD)
                spoof(k, 3)
            spoof(150, 2**31 - 1)
            spoof(151, 2**30)
            line = mon.wait_frames(150)
            assert wait_until(lambda: any("another sender on this session" in x
                                          for x in mon.lines), 10), "\n".join(mon.lines)
    finally:
        mon.stop()
    c = mon.counters(line)
    warned = [x for x in mon.lines if "another sender on this session (127.0.0.1:" in x]
    assert warned and "WARNING:" in warned[0]
    assert c["conflicts"] >= 100  # nearly every real frame contradicts a forged one
    assert c["lost"] < 10 and c["implausible"] >= 2  # the two jumps: not 3 billion lost


def test_a_takeover_needs_five_seconds_of_silence_and_is_logged_and_shown(frames, caplog):
    """The default rule: a newcomer streaming while the sender followed is silent takes over
    after 5 s of that silence, not before; it is logged and shown in the status."""
    caplog.set_level(logging.WARNING, logger="bpms.io.udp.receiver")
    source = UdpFrameSource("127.0.0.1:0")
    target = f"127.0.0.1:{source.udp.address[1]}"
    try:
        with UdpForwarder([target]) as old, UdpForwarder([target]) as new:
            events = []

            def drain() -> None:
                events.extend(source.read(0.0))

            send_at_50_hz(old, frames[:25])
            silent_from = time.monotonic()
            t0 = time.monotonic()
            k = 0
            while source.udp.stats.restarts == 0 and time.monotonic() - t0 < 15:
                time.sleep(max(0.0, t0 + k * PERIOD - time.monotonic()))
                new.send_frame(frames[100 + k], k * PERIOD)
                drain()
                k += 1
            took_after = time.monotonic() - silent_from
            send_at_50_hz(new, frames[100 + k:110 + k], k)
            old.send_frame(frames[25], 25 * PERIOD)  # the old sender, late: stale
            assert wait_until(lambda: (drain(), source.udp.stats.datagrams >= 25 + k + 11)[1], 5)
        st = source.status()
    finally:
        source.close()
    assert 5.0 <= took_after < 8.0, took_after
    delivered = [e.frame for e in events]
    assert delivered[:25] == frames[:25]
    newcomer = delivered[25:]
    assert newcomer and newcomer[0] in frames[100:] and newcomer == frames[
        frames.index(newcomer[0]):frames.index(newcomer[0]) + len(newcomer)]
    assert source.udp.stats.stale == 1 and source.udp.stats.foreign >= 200  # ≈ 5 s at 50 Hz
    assert "replaced" in st.warning and "s of silence" in st.warning
    assert any("sender changed" in r.getMessage() for r in caplog.records)


def test_with_a_key_a_newer_run_of_the_same_computer_takes_over_at_once(frames):
    with UdpSource("127.0.0.1:0", key=KEY) as src:
        target = f"127.0.0.1:{src.address[1]}"
        with UdpForwarder([target], key=KEY) as first, UdpForwarder([target], key=KEY) as second:
            for k in range(20):
                first.send_frame(frames[k], k * PERIOD)
            for k in range(20):  # the newer run starts while the older still sends
                second.send_frame(frames[100 + k], k * PERIOD)
                first.send_frame(frames[20 + k], (20 + k) * PERIOD)
            got = []
            assert wait_until(lambda: (got.append(src.read(0.0)), src.stats.datagrams == 60)[1],
                              10)
        s = src.stats
    delivered = [g.frame for g in got if g is not None]
    assert delivered == frames[:20] + frames[100:120]
    assert (s.replayed, s.restarts) == (20, 1) and "newer run" in s.takeover


def test_a_sender_with_no_listener_says_so_once_and_counts_it_apart(tmp_path):
    """`bpms replay --udp` to a port nobody listens on: one line says so, the status line
    counts it as "no listener", not as send errors."""
    from bpms.firmware.sim.session import simulate

    raw = simulate(duration_s=4.0, seed=26).save_raw(tmp_path / "Raw_nobody_1.bpmsraw")
    run = subprocess.run([sys.executable, "-m", "bpms", "replay", str(raw), "--speed", "2",
                          "--udp", f"127.0.0.1:{free_port()}"], cwd=ROOT, capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    said = [x for x in run.stderr.splitlines() if "nobody is listening" in x]
    assert len(said) == 1, run.stderr
    last = run.stdout.strip().splitlines()[-1]
    assert re.search(r"send errors 0  no listener [1-9]\d*$", last), last
