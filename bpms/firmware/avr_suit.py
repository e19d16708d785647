"""The suit's own firmware, run in an AVR simulator: what ``bpms sim --avr`` serves.

:class:`AvrSuit` starts ``avr_suit`` (C, ``bpms/firmware/avr_host``; built by
:func:`bpms.firmware.avr_build.build`), which runs the arbiter image and six cluster images,
each on a simulated ATmega328P at 16 MHz (simavr), with the parts around them: the arbiter's
serial multiplexers, the RN-41 and its CTS line, each cluster's TCA9548A and the sensor chips'
registers, the battery divider (docs/firmware.md, "The firmware in a simulator").

This module is the small bridge between that program and the Python side:

- the sensor registers get the counts of the Python simulated suit (:class:`MotionSource`, the
  same motion script and sensor model as ``bpms sim``), turned from board axes back into each
  chip's own axes (:func:`chip_counts`, the wiring table of docs/firmware.md); the firmware
  turns them into board axes again;
- the host's bytes go to the RN-41 and the RN-41's bytes come back, unchanged.

An :class:`AvrSuit` has the interface the transports of :mod:`bpms.firmware.sim.server` drive
(``receive``, ``poll``, ``next_event``, ``host_disconnected``), so it is served on a
pseudo-terminal or a TCP port exactly like the Python suit's :class:`Arbiter`.
"""

from __future__ import annotations

import contextlib
import json
import struct
import subprocess
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from bpms.firmware.avr_build import AvrBuild, AvrBuildError
from bpms.firmware.avr_build import build as build_images
from bpms.firmware.sim.arbiter import MotionSource

SENSORS = ("accel", "mag", "gyro")
#: docs/firmware.md, "Axis order": board axis i of sensor s reads chip axis
#: ``BOARD_FROM_CHIP[s][i]`` (the ADXL345 and ITG-3200 have x and y swapped).
BOARD_FROM_CHIP = ((1, 0, 2), (0, 1, 2), (1, 0, 2))
MAGIC = b"BPMSAVR1"
POLL_INTERVAL_S = 0.002  # how often the transport asks for the radio's bytes
BOOT_TIMEOUT_S = 60.0  # for the first simulated second (real time: 1 s; a loaded host: more)


class AvrSuitError(RuntimeError):
    """The simulator host failed (one-line reason)."""


@dataclass(frozen=True)
class SensorOff:
    """A sensor chip without power from ``from_s`` to ``to_s`` simulated seconds after
    power-up: it does not answer on the bus, and starts from its power-on registers after."""

    imu: int
    sensor: int  # 0 accel, 1 mag, 2 gyro
    from_s: float
    to_s: float

    def __post_init__(self) -> None:
        if not 0 <= self.imu < 18 or not 0 <= self.sensor < 3:
            raise ValueError(f"no sensor {self.sensor} on IMU {self.imu}")
        if not 0 <= self.from_s < self.to_s:
            raise ValueError(f"the sensor must be off from a time to a later one, not "
                             f"{self.from_s:g} to {self.to_s:g} s")


@dataclass(frozen=True)
class BusStuck:
    """Cluster ``cluster``'s I2C bus held (SDA low) from ``from_s`` to ``to_s`` simulated
    seconds after power-up: no transfer completes, the firmware's I2C timeout must act."""

    cluster: int
    from_s: float
    to_s: float

    def __post_init__(self) -> None:
        if not 0 <= self.cluster < 6:
            raise ValueError(f"no cluster {self.cluster}")
        if not 0 <= self.from_s < self.to_s:
            raise ValueError(f"the bus must be held from a time to a later one, not "
                             f"{self.from_s:g} to {self.to_s:g} s")


def chip_counts(raw: np.ndarray) -> np.ndarray:
    """Board-axis raw counts ``int16 [N, 18, 9]`` (a frame's ``ax ay az mx my mz gx gy gz``) →
    what each chip's data registers hold, ``int16 [N, 18, 3, 3]`` (sensor, chip x y z)."""
    raw = np.asarray(raw, dtype=np.int16).reshape(len(raw), 18, 3, 3)
    board_axis = np.argsort(BOARD_FROM_CHIP, axis=-1)  # [sensor, chip axis]
    return raw[:, :, np.arange(3)[:, None], board_axis]


class AvrSuit:
    """The seven simulated boards behind the RN-41, for a transport to serve.

    source: the motion (its raw counts fill the chips' registers; the chips move to the next
    sample when their cluster is polled, so frame j of the first stream carries sample j);
    realtime: never faster than the wall clock (False: as fast as this computer simulates);
    battery_v, battery_drain_v_per_h: the cell at power-up and its linear drain (floor 2.6 V);
    sensor_off: chips without power for a while (:class:`SensorOff`);
    bus_stuck: clusters whose I2C bus is held for a while (:class:`BusStuck`);
    build: the built programs (default: :func:`~bpms.firmware.avr_build.build` now).
    """

    def __init__(self, source: MotionSource, *, realtime: bool = True, battery_v: float = 3.35,
                 battery_drain_v_per_h: float = 0.1, sensor_off: Iterable[SensorOff] = (),
                 bus_stuck: Iterable[BusStuck] = (), build: AvrBuild | None = None,
                 on_status: Callable[[dict], None] | None = None) -> None:
        self.source = source
        self.realtime = realtime
        self.battery_v = battery_v
        self.battery_drain_v_per_h = battery_drain_v_per_h
        self.sensor_off = tuple(sensor_off)
        self.bus_stuck = tuple(bus_stuck)
        self.build = build
        self.on_status = on_status
        self.status: dict | None = None  # the last status the simulator sent
        self.final: dict | None = None
        self.error: str | None = None  # why the simulator stopped, when it did by itself
        self.bytes_to_host = 0
        self.bytes_from_host = 0
        self._proc: subprocess.Popen | None = None
        self._radio = bytearray()
        self._discard = False
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._threads: list[threading.Thread] = []
        self._stderr: list[str] = []

    # -- life cycle -------------------------------------------------------------------------
    def start(self) -> AvrSuit:
        """Build if needed, power the boards up and feed them the motion. Raises
        :class:`AvrBuildError` or :class:`AvrSuitError`."""
        build = self.build or build_images()
        self.build = build
        header = self._header()
        try:
            self._proc = subprocess.Popen(
                [str(build.host), str(build.arbiter_hex), str(build.cluster_hex)],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        except OSError as exc:
            raise AvrSuitError(f"cannot start {build.host}: {exc.strerror or exc}") from None
        for target in (self._read_stdout, self._read_stderr):
            t = threading.Thread(target=target, name=f"avr-suit-{target.__name__}", daemon=True)
            t.start()
            self._threads.append(t)
        self._send(header)
        # The boards have been on for a while when a host connects: serve from the first status
        # (one simulated second; the clusters need ~70 ms to start their sensors).
        try:
            self.wait_status(lambda s: True, BOOT_TIMEOUT_S)
        except TimeoutError as exc:
            self.close()
            raise AvrSuitError(f"the AVR simulator did not start: {exc}") from None
        return self

    def _header(self) -> bytes:
        table = chip_counts(self.source.raw)
        off = b"".join(struct.pack("<BBII", e.imu, e.sensor, round(e.from_s * 1000),
                                   round(e.to_s * 1000)) for e in self.sensor_off)
        held = b"".join(struct.pack("<BII", e.cluster, round(e.from_s * 1000),
                                    round(e.to_s * 1000)) for e in self.bus_stuck)
        config = struct.pack("<IIIBII", len(table), round(self.battery_v * 1000),
                             max(round(self.battery_drain_v_per_h * 1e6), 0), int(self.realtime),
                             len(self.sensor_off), len(self.bus_stuck))
        return MAGIC + config + off + held + table.astype("<i2").tobytes()

    def close(self, timeout_s: float = 10.0) -> dict | None:
        """Stop the simulator; returns its final status (None when it had already failed)."""
        proc, self._proc = self._proc, None
        if proc is None:
            return self.final
        with contextlib.suppress(OSError, ValueError):
            proc.stdin.write(b"Q")
            proc.stdin.close()
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout_s)
        for t in self._threads:
            t.join(timeout_s)
        return self.final

    def __enter__(self) -> AvrSuit:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def running(self) -> bool:
        return self._proc is not None and self._proc.poll() is None

    # -- the simulator's output -------------------------------------------------------------
    def _read_stdout(self) -> None:
        out = self._proc.stdout
        while True:
            head = out.read(3)
            if len(head) < 3:
                break
            body = out.read(head[1] | head[2] << 8)
            if head[0] == ord("D"):
                with self._changed:
                    if not self._discard:
                        self._radio += body
                    self.bytes_to_host += len(body)
                    self._changed.notify_all()
            elif head[0] == ord("S"):
                status = json.loads(body)
                with self._changed:
                    self.status = status
                    if status.get("final"):
                        self.final = status
                    self._changed.notify_all()
                if self.on_status is not None:
                    self.on_status(status)
        code = self._proc.wait() if self._proc is not None else 0
        if code not in (0, None) and self.error is None:
            detail = self._stderr[-1] if self._stderr else f"exit status {code}"
            self.error = f"the AVR simulator stopped: {detail}"
        with self._changed:
            self._changed.notify_all()

    def _read_stderr(self) -> None:
        for line in self._proc.stderr:
            self._stderr.append(line.decode("utf-8", "replace").rstrip())

    def wait_status(self, predicate: Callable[[dict], bool], timeout_s: float) -> dict:
        """Wait (bounded) for a status that satisfies ``predicate``; raise TimeoutError."""
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while self.status is None or not predicate(self.status):
                left = deadline - time.monotonic()
                if left <= 0 or self.error:
                    raise TimeoutError(self.error or f"no such status within {timeout_s:g} s")
                self._changed.wait(min(left, 0.1))
            return self.status

    # -- what a transport drives ------------------------------------------------------------
    def _send(self, data: bytes) -> None:
        proc = self._proc
        if proc is None or proc.stdin is None:
            return
        try:
            proc.stdin.write(data)
            proc.stdin.flush()
        except (OSError, ValueError):
            if self.error is None:
                self.error = "the AVR simulator is not running"

    def receive(self, data: bytes, now: float | None = None) -> None:
        """Bytes from the host, for the RN-41 (sent on to the arbiter as its CTS allows)."""
        self._discard = False  # a host is there
        for i in range(0, len(data), 65535):
            chunk = data[i:i + 65535]
            self.bytes_from_host += len(chunk)
            self._send(b"H" + struct.pack("<H", len(chunk)) + chunk)

    def poll(self, now: float | None = None, max_frames: int | None = None) -> list[bytes]:
        """The bytes the RN-41 received from the arbiter since the last call."""
        with self._lock:
            if self._discard:  # a host connected after a disconnect: the radio kept nothing
                self._radio.clear()
                self._discard = False
            if not self._radio:
                return []
            out, self._radio = bytes(self._radio), bytearray()
        return [out]

    def next_event(self) -> float:
        now = time.monotonic()
        with self._lock:
            return now if self._radio else now + POLL_INTERVAL_S

    def host_disconnected(self) -> None:
        """The host went away: the radio drops what the arbiter sends until one connects (the
        arbiter itself goes on, as a real one would)."""
        with self._lock:
            self._radio.clear()
            self._discard = True

    def switch(self, imu: int, sensor: int, on: bool) -> None:
        """Switch a sensor chip off (or on again, from its power-on registers) now."""
        if not 0 <= imu < 18 or not 0 <= sensor < 3:
            raise ValueError(f"no sensor {sensor} on IMU {imu}")
        self._send(b"O" + bytes([imu, sensor, int(bool(on))]))


__all__ = ["AvrBuildError", "AvrSuit", "AvrSuitError", "BusStuck", "SensorOff", "chip_counts"]
