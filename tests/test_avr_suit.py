"""The suit's firmware in an AVR simulator (bpms sim --avr): the arbiter and six cluster images
on simulated ATmega328P boards (simavr), fed by the Python suit's motion, read by bpms.

Truth comes from outside the firmware: the Python simulated suit's raw counts for the same
motion and seed (the chips' registers hold them in chip axes, the firmware must turn them into
the frame's board axes), the documented protocol (docs/suit.md), the battery divider of
docs/firmware.md worked out here, and the simulated time of the boards (50 frames per
simulated second)."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from waiting import wait_until

from bpms.firmware.avr_build import build, missing_tools
from bpms.firmware.avr_suit import BOARD_FROM_CHIP, AvrSuit, BusStuck, SensorOff, chip_counts
from bpms.firmware.sim.arbiter import MotionSource
from bpms.firmware.sim.server import TcpServer
from bpms.io.frames import FRAME_SIZE, decode_frames
from bpms.io.link import SuitLink
from bpms.io.parser import FrameParser
from bpms.io.rawfile import read_raw

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def avr_build():
    missing = missing_tools()
    if missing:
        pytest.skip(f"cannot build the AVR suit here: missing {', '.join(missing)} "
                    "(tools/dev.sh setup installs them)")
    return build()


@pytest.fixture(scope="module")
def motion() -> MotionSource:
    return MotionSource.simulated(seed=3, duration_s=30.0)


def battery_reply(cell_v: float) -> float:
    """What the arbiter must answer for a cell at ``cell_v``: the divider halves it, the ADC
    (AVcc = 3.3 V, 10 bits) truncates, the firmware scales back and rounds to 10 mV."""
    counts = math.floor(cell_v / 2 / 3.3 * 1024)
    return round(counts * 3.3 * 2 / 1024 + 1e-9, 2)


def sample_of(frame_raw: np.ndarray, motion: MotionSource) -> list[int]:
    """The motion samples whose raw counts equal this frame's."""
    return [j for j in range(len(motion)) if np.array_equal(frame_raw, motion.raw[j])]


def test_chips_get_the_frame_values_in_their_own_axes() -> None:
    # docs/firmware.md, "Axis order": board x = chip y for the ADXL345 and the ITG-3200,
    # the HMC5883L's axes are the board's.
    raw = np.arange(9, dtype=np.int16).reshape(1, 1, 9).repeat(18, axis=1)  # ax..gz = 0..8
    chip = chip_counts(raw)
    assert chip.shape == (1, 18, 3, 3)
    np.testing.assert_array_equal(chip[0, 5, 0], [1, 0, 2])  # accel chip x, y, z = ay, ax, az
    np.testing.assert_array_equal(chip[0, 5, 1], [3, 4, 5])
    np.testing.assert_array_equal(chip[0, 5, 2], [7, 6, 8])
    assert BOARD_FROM_CHIP[0] == BOARD_FROM_CHIP[2] == (1, 0, 2)


def test_sensor_off_needs_a_real_sensor_and_a_span() -> None:
    with pytest.raises(ValueError):
        SensorOff(18, 0, 1.0, 2.0)
    with pytest.raises(ValueError):
        SensorOff(3, 1, 2.0, 2.0)


class Suit:
    """The AVR suit on TCP, with the link a host would open."""

    def __init__(self, build_, motion: MotionSource, **kwargs) -> None:
        self.avr = AvrSuit(motion, build=build_, **kwargs).start()
        self.server = TcpServer(self.avr).start()
        self.link = SuitLink(self.server.url)

    def frames(self, n: int, timeout: float = 60.0) -> list[bytes]:
        out: list[bytes] = []
        assert wait_until(lambda: out.extend(self.link.read_frames(0.05)) or len(out) >= n,
                          timeout), self.state(f"{len(out)} of {n} frames")
        return out

    def state(self, what: str) -> str:
        """What a failed wait saw, for its message: the simulator's last status and error, the
        server's byte counts."""
        return (f"{what}; simulator error: {self.avr.error}; stderr: {self.avr._stderr[-3:]}; "
                f"server: {self.server.bytes_read} bytes read, {self.server.bytes_written} "
                f"written, {self.server.frames_unread} frames unread; last status: "
                f"{self.avr.status}")

    def close(self) -> dict:
        self.link.close()
        self.server.stop()
        return self.avr.close()


def test_commands_stale_frame_and_values_on_the_firmware(avr_build, motion) -> None:
    suit = Suit(avr_build, motion, realtime=False, battery_v=3.27, battery_drain_v_per_h=0.0)
    try:
        link = suit.link
        link.identify()
        assert link.battery_volts() == battery_reply(3.27)
        link.start()  # drops the stale first frame (the power-up reading)
        first = suit.frames(60)
        # Frames carry the Python suit's values for the same motion, from sample 0 on,
        # converted by the firmware from chip axes to board axes: equal to the count.
        decoded = decode_frames(b"".join(first))
        assert not decoded.errors.any()
        for i in range(len(first)):
            np.testing.assert_array_equal(decoded.raw[i], motion.raw[i], err_msg=f"frame {i}")
        # 0x01 while streaming stops the stream between frames and is then answered: the
        # bytes before the reply are whole frames (SuitLink keeps them), none after it.
        assert link.battery_volts() == battery_reply(3.27)
        first += link.read_frames(0.0)
        k = len(first)
        assert link.parser.stats.discarded_bytes == 0
        assert link.read_frames(0.3) == []  # stopped
        # Restart by hand to see the stale frame: the reading the cluster took at the last
        # poll of the previous stream (sample k), which the host never saw; then k + 1, ...
        parser = FrameParser()
        link._write(b"\x00")
        got: list[bytes] = []
        assert wait_until(lambda: got.extend(parser.feed(link._t.read(0.05))) or len(got) >= 3,
                          30), suit.state(f"{len(got)} of 3 frames after the restart")
        link.stop()  # 0x02 stops it, BPMS follows the last frame
        again = decode_frames(b"".join(got[:3]))
        assert [sample_of(again.raw[i], motion) for i in range(3)] == [[k], [k + 1], [k + 2]]
        # Idle: identify is answered at once, an unknown byte is ignored, and a burst of
        # commands larger than the arbiter's queue (8) is answered in full.
        link._write(b"\x7f")
        link.identify()
        link._write(b"\x02" * 20)
        replies = bytearray()
        assert wait_until(lambda: replies.extend(link._t.read(0.05)) or len(replies) >= 80, 30)
        assert bytes(replies) == b"BPMS" * 20
    finally:
        final = suit.close()
    c = final["counters"]
    assert c["misrouted"] == c["cut"] == c["unheard"] == c["host_bytes_lost"] == 0, c
    assert c["framing_errors"] == 0 and not any(c["overruns"]), c
    assert c["host_bytes_in"] == 28  # 0x02 0x01 0x00 0x01 0x00 0x02 0x7f 0x02, 20 x 0x02
    for board, figure in final["cycles_per_frame"].items():
        assert 0 < figure["max"] < 320_000, (board, figure)


def test_a_stream_stopped_and_started_again_many_times_never_stalls(avr_build, motion) -> None:
    # The arbiter waits in Serial.flush() before each frame for the USART's transmit-complete
    # flag. The simulator once counted a byte off on its own clock at the instant it was
    # written, so the flag came and went at once and the arbiter waited for ever: about once
    # in 90 of these cycles (docs/firmware.md, "Where simavr 1.6 is corrected").
    suit = Suit(avr_build, motion, realtime=False, battery_drain_v_per_h=0.0)
    try:
        suit.link.identify()
        for _ in range(300):
            suit.link.start()
            suit.frames(3, timeout=10.0)
            suit.link.battery_volts()  # stops the stream between two frames
    finally:
        final = suit.close()
    c = final["counters"]
    assert c["host_bytes_lost"] == c["misrouted"] == c["cut"] == 0, c


def test_a_switched_off_sensor_and_a_stuck_bus_set_exactly_their_error_bits(avr_build,
                                                                            motion) -> None:
    # IMU 7 (cluster 2, slot 1) accelerometer and IMU 14 (cluster 4, slot 2) gyroscope lose
    # power for a while, cluster 3's I2C bus is held later; everything else must read as the
    # Python suit, and every frame must come on time.
    off = [SensorOff(7, 0, 2.0, 2.5), SensorOff(14, 2, 2.2, 2.4)]
    stuck = BusStuck(3, 2.6, 2.9)
    suit = Suit(avr_build, motion, realtime=False, sensor_off=off, bus_stuck=[stuck])
    try:
        suit.link.start()
        frames = suit.frames(160)
        suit.link.stop()
        start_s = suit.avr.wait_status(lambda s: bool(s["streams"]), 10)["streams"][-1]["start_s"]
    finally:
        final = suit.close()
    d = decode_frames(b"".join(frames))
    # frame i (after the stale one) carries the reading taken right after the stream's poll
    # i + 1, at start_s + i * 20 ms (plus the few ms it takes to reach that cluster)
    t = start_s + np.arange(len(frames)) * 0.02
    expect = np.zeros_like(d.errors)
    for e in off:
        expect[(t > e.from_s) & (t < e.to_s), e.imu, e.sensor] = True
    expect[(t > stuck.from_s) & (t < stuck.to_s), 9:12] = True  # the whole cluster
    edge = np.zeros(len(frames), bool)
    for a, b in [(e.from_s, e.to_s) for e in off] + [(stuck.from_s, stuck.to_s)]:
        edge |= (np.abs(t - a) < 0.015) | (np.abs(t - b) < 0.015)
    np.testing.assert_array_equal(d.errors[~edge], expect[~edge])
    assert d.errors[:, 7, 0].sum() >= 20 and d.errors[:, 14, 2].sum() >= 5
    assert d.errors[:, 9:12].all(axis=(1, 2)).sum() >= 10
    assert final["late_frames"] == 0 and final["counters"]["twi_stalls"][3] > 0
    # a failed sensor sends zeros; every other value is the Python suit's, before and after
    # (the chips come back in their power-on state: the firmware configures them again)
    for i in range(len(frames)):
        want = motion.raw[i].reshape(18, 3, 3).copy()
        want[d.errors[i]] = 0
        np.testing.assert_array_equal(d.raw[i].reshape(18, 3, 3), want, err_msg=f"frame {i}")
    assert final["counters"]["i2c_nacks"][2] > 0 and final["counters"]["i2c_nacks"][4] > 0


class Cli:
    """A `bpms` subprocess whose output lines are collected as they come."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "bpms", *args], cwd=ROOT,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.lines: list[str] = []
        self.errors: list[str] = []
        self._threads = [threading.Thread(target=self._collect, args=(s, out), daemon=True)
                         for s, out in ((self.proc.stdout, self.lines),
                                        (self.proc.stderr, self.errors))]
        for t in self._threads:
            t.start()

    @staticmethod
    def _collect(stream, out: list[str]) -> None:
        for line in stream:
            out.append(line.rstrip("\n"))

    def wait_line(self, predicate, timeout: float) -> str:
        found: list[str] = []

        def check() -> bool:
            found.extend(line for line in self.lines if predicate(line))
            return bool(found) or self.proc.poll() is not None

        assert wait_until(check, timeout) and found, "\n".join(self.lines[-10:] +
                                                              self.errors[-10:])
        return found[0]

    def stop(self, timeout: float = 60.0) -> int:
        self.proc.send_signal(signal.SIGINT)
        code = self.proc.wait(timeout)
        for t in self._threads:
            t.join(10)
        return code


@pytest.mark.slow
def test_bpms_record_against_bpms_sim_avr(avr_build, motion, tmp_path) -> None:
    """`bpms record socket://...` against `bpms sim --avr --tcp` for 10 simulated seconds, in
    real time (or slower, when this computer cannot keep up)."""
    report = tmp_path / "avr.json"
    sim = Cli("sim", "--avr", "--tcp", "0", "--seed", "3", "--battery", "3.35",
              "--sensor-off", "7:accel:6:7", "--report", str(report))
    record = None
    try:
        url = sim.wait_line(lambda s: s.startswith("socket://"), 120)
        record = Cli("record", url, "-o", str(tmp_path), "--name", "avr")

        def frames_on_disk(line: str) -> bool:
            return line.startswith("t ") and int(line.split("frames")[1].split()[0]) >= 500

        record.wait_line(frames_on_disk, 150)
        assert record.stop() == 0, "\n".join(record.errors[-10:])
    finally:
        if record is not None and record.proc.poll() is None:
            record.proc.kill()
        assert sim.stop() == 0, "\n".join(sim.errors[-10:])
    final = json.loads(report.read_text())
    recording = read_raw(tmp_path / "Raw_avr_1.bpmsraw")
    assert recording.problems == []
    n = len(recording)
    raw = decode_frames(b"".join(recording.frame_bytes(k) for k in range(n)))
    stream = final["streams"][-1]

    # 50 frames per simulated second, whatever the real-time factor was; every frame the
    # firmware sent reached the file, but the stale first one and those still in flight when
    # bpms record stopped the stream at Ctrl-C (its stop byte arrived: the stream ended)
    rate = (stream["frames"] - 1) / (stream["last_s"] - stream["start_s"])
    assert abs(rate - 50.0) <= 0.1, rate
    assert final["frames_per_second"] == {"min": 50, "max": 50}, final["frames_per_second"]
    assert 0 <= stream["frames"] - 1 - n <= 10, (stream["frames"], n)
    assert final["sim_s"] - stream["last_s"] > 0.02
    assert final["late_frames"] == 0

    # stale frame dropped: the file starts with motion sample 0, then 1, 2, ... (same seed);
    # IMU 7's accelerometer is off from 6 to 7 s: exactly its error bit, zeros for its values
    t = stream["start_s"] + np.arange(n) * 0.02
    off = (t > 6.0) & (t < 7.0)
    edge = (np.abs(t - 6.0) < 0.015) | (np.abs(t - 7.0) < 0.015)
    assert raw.errors[off & ~edge, 7, 0].all() and off.sum() >= 45
    others = raw.errors.copy()
    others[:, 7, 0] = False
    assert not others.any()
    assert not raw.errors[~off & ~edge, 7, 0].any()
    for i in range(n):
        want = motion.raw[i].reshape(18, 3, 3).copy()
        want[raw.errors[i]] = 0
        np.testing.assert_array_equal(raw.raw[i].reshape(18, 3, 3), want, err_msg=f"frame {i}")

    # battery and identify answers at the start; the link never went silent
    status = [line for line in record.lines if line.startswith("t ")]
    assert status and all(f"battery {battery_reply(3.35):.2f} V" in line for line in status)
    assert not any(" silent " in line or " gone " in line for line in status)
    assert all("links lost 0" in line for line in status)
    c = final["counters"]
    assert c["misrouted"] == c["cut"] == c["host_bytes_lost"] == 0, c
    assert not any(c["overruns"]) and c["framing_errors"] == 0, c
    # the figures the command prints: real-time factor and the cycle budget
    summary = next(line for line in sim.errors if line.startswith("bpms sim: stopped;"))
    assert "real-time factor" in summary and "cycles per 20 ms frame of 320,000" in summary
    for board, figure in final["cycles_per_frame"].items():
        assert 0 < figure["max"] < 320_000, (board, figure)
    assert FRAME_SIZE * n <= c["radio_bytes_out"]


def test_sim_avr_refuses_the_python_suits_fault_injection() -> None:
    for args in (["--error-rate", "0.1"], ["--bursty"], ["--sensor-off", "7:spin:1:2"],
                 ["--sensor-off", "7:accel:3:2"], ["--bus-stuck", "9:1:2"]):
        result = subprocess.run([sys.executable, "-m", "bpms", "sim", "--avr", "--tcp", "0",
                                 *args], cwd=ROOT, capture_output=True, text=True, timeout=60,
                                check=False)
        assert result.returncode == 2, result.stderr
        assert "Traceback" not in result.stderr
        assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    result = subprocess.run([sys.executable, "-m", "bpms", "sim", "--tcp", "0", "--report",
                             "x.json"], cwd=ROOT, capture_output=True, text=True, timeout=60,
                            check=False)
    assert result.returncode == 2 and "need --avr" in result.stderr
