"""The arbiter board's protocol (docs/suit.md), transport-independent, with fault injection.

Host → suit bytes go to :meth:`Arbiter.receive`; the bytes due for the host come out of
:meth:`Arbiter.poll` (a transport calls it often, see :mod:`bpms.firmware.sim.server`).

- 0x02 → ``BPMS``; 0x01 → battery voltage ``V3.27\\n`` (ASCII, two decimals, slowly
  draining, never below 2.60 V); 0x00 → stream one frame every 20 ms. Other bytes are ignored
  (counted). While streaming, any byte stops the stream and is then taken as a command.
- The first frame after every start is stale: it repeats the previous reading (the last frame
  sent, with its error bits); at power-up an all-zero reading.
- Numbering: the j-th non-stale frame the arbiter emits (j = 0, 1, ... over its whole life)
  carries motion sample ``j mod N`` of its :class:`MotionSource` (the script loops; it starts
  and ends in the same still calibration pose, so the loop is seamless for the sensors).
- Pacing: realtime frames are due at absolute deadlines ``t_start + k * 0.02`` s (no drift; a
  late caller gets the missed frames at once); ``realtime=False`` emits frames as fast as the
  transport takes them.

Fault injection (:class:`Faults`, all off by default): error bits, dropped byte runs, corrupted
bytes, Bluetooth-like bursty delivery and going silent. Frames lost while the link is silent
are never emitted, so they take no motion sample.
"""

from __future__ import annotations

import functools
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from bpms.io.frames import FRAME_PERIOD_S, FRAME_SIZE, N_IMUS, N_SENSORS, encode_frame

CMD_START = 0x00
CMD_BATTERY = 0x01
CMD_IDENTIFY = 0x02
IDENTITY = b"BPMS"
BATTERY_CUTOFF_V = 2.6


@dataclass
class Faults:
    """Fault injection settings (all off by default). Rates are probabilities per frame."""

    error_rate: float = 0.0  # per frame, IMU and sensor: error bit set, values 0
    drop_rate: float = 0.0  # per frame: a run of 1..drop_max_bytes bytes is lost
    drop_max_bytes: int = 8
    corrupt_rate: float = 0.0  # per frame: one byte is replaced by another value
    bursty: bool = False  # Bluetooth-like delivery (realtime mode only)
    burst_prob: float = 0.05  # per frame: the radio starts holding frames back
    burst_max_s: float = 0.3  # longest hold, s
    jitter_s: tuple[float, float] = (0.002, 0.010)  # delay outside holds, s
    silence_at_s: float | None = None  # go silent this long after power-up, s (once)
    silence_s: float = 0.0  # for this long, s


@dataclass
class ArbiterStats:
    """Counters since power-up."""

    frames_sent: int = 0  # every frame emitted, stale ones included
    stale_frames: int = 0
    motion_frames: int = 0  # non-stale frames = the next motion sample number
    starts: int = 0
    stops: int = 0
    identify_replies: int = 0
    battery_replies: int = 0
    ignored_bytes: int = 0  # bytes that are not commands (after stopping a stream, if any)
    error_flags: int = 0  # injected error bits
    frames_with_dropped_bytes: int = 0
    dropped_bytes: int = 0
    corrupted_frames: int = 0
    silenced_frames: int = 0  # frames due while silent (never emitted)
    silenced_bytes_in: int = 0  # host bytes ignored while silent


def _locked(method):
    """Serialise a public method: a transport thread and the caller may both drive the arbiter
    (e.g. ``silence()`` from a test while the server thread polls)."""

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        with self._lock:
            return method(self, *args, **kwargs)

    return wrapper


class MotionSource:
    """Raw readings to stream: ``raw[N, 18, 9]`` int16 and ``errors[N, 18, 3]``, looped."""

    def __init__(self, raw: np.ndarray, errors: np.ndarray | None = None,
                 frames: bytes | None = None) -> None:
        self.raw = np.asarray(raw, dtype=np.int16)
        n = len(self.raw)
        if n == 0:
            raise ValueError("a motion source needs at least one sample")
        self.errors = (np.zeros((n, N_IMUS, N_SENSORS), bool) if errors is None
                       else np.asarray(errors, dtype=bool))
        self._frames = frames if frames is not None and len(frames) == n * FRAME_SIZE else None

    @classmethod
    def simulated(cls, seed: int = 0, **kwargs) -> MotionSource:
        """The scripted motion of :func:`bpms.firmware.sim.session.simulate` (kwargs pass on)."""
        from bpms.firmware.sim.session import simulate

        rec = simulate(seed=seed, **kwargs)
        return cls(rec.raw, rec.errors, rec.frames)

    def __len__(self) -> int:
        return len(self.raw)

    def starting_at(self, sample: int) -> MotionSource:
        """The same loop begun at motion sample ``sample`` (``bpms sim --start-at``)."""
        k = int(sample) % len(self.raw)
        if not k:
            return self
        frames = (self._frames[k * FRAME_SIZE:] + self._frames[:k * FRAME_SIZE]
                  if self._frames is not None else None)
        return MotionSource(np.roll(self.raw, -k, axis=0), np.roll(self.errors, -k, axis=0),
                            frames)

    def reading(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """(raw ``[18, 9]``, errors ``[18, 3]``) of motion sample ``j`` (looped)."""
        k = j % len(self.raw)
        return self.raw[k], self.errors[k]

    def frame(self, j: int) -> bytes:
        """The encoded 340-byte frame of motion sample ``j`` (looped), no faults."""
        k = j % len(self.raw)
        if self._frames is not None:
            return self._frames[k * FRAME_SIZE:(k + 1) * FRAME_SIZE]
        return encode_frame(self.raw[k], self.errors[k])


@dataclass
class Arbiter:
    """The arbiter board's state machine. Times are ``clock()`` seconds (monotonic).

    battery_v: voltage at power-up; battery_drain_v_per_h: linear drain (never below 2.6 V).
    """

    source: MotionSource
    faults: Faults = field(default_factory=Faults)
    realtime: bool = True
    battery_v: float = 3.35
    battery_drain_v_per_h: float = 0.1
    seed: int = 0
    clock: Callable[[], float] = time.monotonic

    def __post_init__(self) -> None:
        self.stats = ArbiterStats()
        self._rng = np.random.default_rng(self.seed)
        self._t0 = self.clock()
        self.streaming = False
        self._stream_start = 0.0
        self._stream_k = 0  # frames emitted (or silenced) in the current stream
        # the last frame sent (repeated by the stale first frame of a stream): all zero at first
        self._last = encode_frame(np.zeros((N_IMUS, 9), np.int16),
                                  np.zeros((N_IMUS, N_SENSORS), bool))
        self._queue: deque[tuple[float, bytes]] = deque()  # (release time, bytes)
        self._last_release = 0.0
        self._hold_until = 0.0
        self._silent_until = 0.0
        self._silence_done = False
        self._lock = threading.RLock()

    # -- host → suit --------------------------------------------------------------------
    @_locked
    def receive(self, data: bytes, now: float | None = None) -> None:
        """Bytes from the host, in order."""
        now = self.clock() if now is None else now
        self._scheduled_silence(now)
        if now < self._silent_until:
            self.stats.silenced_bytes_in += len(data)
            return
        for byte in data:
            if self.streaming:
                if self.realtime:
                    self._emit_due(now)  # frames due before the stop byte still go out
                self.streaming = False
                self.stats.stops += 1
            if byte == CMD_START:
                self._start(now)
            elif byte == CMD_BATTERY:
                self._send_at(f"V{self.battery_volts(now):.2f}\n".encode("ascii"), now)
                self.stats.battery_replies += 1
            elif byte == CMD_IDENTIFY:
                self._send_at(IDENTITY, now)
                self.stats.identify_replies += 1
            else:
                self.stats.ignored_bytes += 1

    @_locked
    def host_disconnected(self) -> None:
        """The host went away (TCP client closed): stop streaming, forget undelivered bytes."""
        if self.streaming:
            self.streaming = False
            self.stats.stops += 1
        self._queue.clear()

    # -- suit → host --------------------------------------------------------------------
    @_locked
    def poll(self, now: float | None = None, max_frames: int | None = None) -> list[bytes]:
        """Byte chunks (whole frames or replies) due for the host by ``now``, in order.

        ``max_frames`` caps the frames produced by this call (fast mode: the room left in the
        transport's buffer); realtime frames never wait for room, the transport drops them.
        """
        now = self.clock() if now is None else now
        self._scheduled_silence(now)
        self._emit_due(now, max_frames)
        out = []
        while self._queue and self._queue[0][0] <= now:
            out.append(self._queue.popleft()[1])
        return out

    @_locked
    def next_event(self) -> float | None:
        """The next time (clock s) :meth:`poll` has something to do, or None."""
        times = []
        if self._queue:
            times.append(self._queue[0][0])
        if self.streaming:
            times.append(self._deadline(self._stream_k) if self.realtime else self.clock())
        return min(times) if times else None

    @_locked
    def silence(self, seconds: float, now: float | None = None) -> None:
        """Go silent for ``seconds``: nothing is emitted and host bytes are ignored (a lost
        radio link). A stream in progress resumes afterwards; its frames due meanwhile are
        lost (counted in ``stats.silenced_frames``)."""
        now = self.clock() if now is None else now
        self._silent_until = now + seconds
        self._queue.clear()

    def battery_volts(self, now: float | None = None) -> float:
        """Battery voltage, V, draining linearly since power-up, floored at 2.6 V."""
        now = self.clock() if now is None else now
        hours = (now - self._t0) / 3600.0
        return max(BATTERY_CUTOFF_V, self.battery_v - self.battery_drain_v_per_h * hours)

    @property
    def motion_index(self) -> int:
        """Motion sample number of the next non-stale frame."""
        return self.stats.motion_frames

    # -- internals ----------------------------------------------------------------------
    def _scheduled_silence(self, now: float) -> None:
        at = self.faults.silence_at_s
        if at is not None and not self._silence_done and now - self._t0 >= at:
            self._silence_done = True
            self.silence(self.faults.silence_s, self._t0 + at)

    def _deadline(self, k: int) -> float:
        return self._stream_start + k * FRAME_PERIOD_S

    def _start(self, now: float) -> None:
        self.streaming = True
        self.stats.starts += 1
        self._stream_start = now
        self._stream_k = 0

    def _send_at(self, data: bytes, now: float) -> None:
        """Queue ``data`` for release at ``now``, never before the bytes queued earlier."""
        release = max(now, self._last_release)
        self._last_release = release
        self._queue.append((release, data))

    def _emit_due(self, now: float, max_frames: int | None = None) -> None:
        produced = 0
        if not self.realtime:
            if now < self._silent_until:
                return
            max_frames = 10 if max_frames is None else max_frames
        while self.streaming and (max_frames is None or produced < max_frames):
            due = self._deadline(self._stream_k) if self.realtime else now
            if due > now:
                break
            first = self._stream_k == 0
            self._stream_k += 1
            if due < self._silent_until:
                self.stats.silenced_frames += 1
                continue
            if first:
                frame = self._last
                self.stats.stale_frames += 1
            else:
                frame = self._next_reading()
            self.stats.frames_sent += 1
            produced += 1
            self._deliver(self._damage(frame), due)

    def _next_reading(self) -> bytes:
        j = self.stats.motion_frames
        self.stats.motion_frames += 1
        rate = self.faults.error_rate
        if rate <= 0:
            self._last = self.source.frame(j)
        else:
            raw, errors = self.source.reading(j)
            raw = raw.copy()
            fail = self._rng.random((N_IMUS, N_SENSORS)) < rate
            raw.reshape(N_IMUS, N_SENSORS, 3)[fail] = 0
            self.stats.error_flags += int(fail.sum())
            self._last = encode_frame(raw, errors | fail)
        return self._last

    def _damage(self, frame: bytes) -> bytes:
        f = self.faults
        if f.drop_rate <= 0 and f.corrupt_rate <= 0:
            return frame
        data = bytearray(frame)
        if f.corrupt_rate > 0 and self._rng.random() < f.corrupt_rate:
            pos = int(self._rng.integers(len(data)))
            data[pos] = (data[pos] + int(self._rng.integers(1, 256))) % 256
            self.stats.corrupted_frames += 1
        if f.drop_rate > 0 and self._rng.random() < f.drop_rate:
            n = int(self._rng.integers(1, max(f.drop_max_bytes, 1) + 1))
            pos = int(self._rng.integers(0, len(data) - n + 1))
            del data[pos:pos + n]
            self.stats.frames_with_dropped_bytes += 1
            self.stats.dropped_bytes += n
        return bytes(data)

    def _deliver(self, data: bytes, due: float) -> None:
        f = self.faults
        release = due
        if f.bursty and self.realtime:
            if due < self._hold_until:
                release = self._hold_until
            elif self._rng.random() < f.burst_prob:
                self._hold_until = due + float(self._rng.uniform(0.05, f.burst_max_s))
                release = self._hold_until
            else:
                release = due + float(self._rng.uniform(*f.jitter_s))
        self._send_at(data, release)
