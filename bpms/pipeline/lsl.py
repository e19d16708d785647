"""Lab Streaming Layer outlets: the live (or replayed) session as five LSL streams.

Streams (docs/lsl.md lists every channel):

- ``BPMS Segments`` (type ``MoCap``, 72 float32 channels, 50 Hz): each of the 18 segment
  orientations after Reset Zero as a unit quaternion w, x, y, z (segment axes → world
  north-east-down);
- ``BPMS Joint Angles`` (type ``MoCap``, 28 float32 channels, degrees, the joint-angle
  convention in force, docs/joint-angles.md);
- ``BPMS Sensors`` (type ``IMU``, 162 float32 channels): calibrated accelerometer m/s²,
  magnetometer gauss, gyroscope rad/s per IMU in signed board axes (the numbers of the GUI's
  table and ``bpms extract``);
- ``BPMS Disturbance`` (type ``Misc``, 36 int8 channels, 50 Hz): per IMU 1 when its
  magnetometer is disturbed, then per IMU 1 when it accelerates (the accelerometer is then no
  gravity reference; :mod:`bpms.filter.disturbance`); -1 when not computed;
- ``BPMS Events`` (type ``Markers``, one string channel, irregular): the session's events
  (:mod:`bpms.pipeline.events`, the lines of the event log and of the raw recording), each
  stamped at the frame it applies at: ``Reset Zero (manual) at 12.30 s, window 0.50 s, moved
  1.2° (IMU 4)``, ``alignment off (sensor angles) at 20.00 s``, ``marker at 21.40 s: TEXT``,
  ``filter …``, ``filter settings …``, ``filters re-initialised …``, ``logging start``,
  ``logging stop``, warnings; and ``link lost``, ``link recovered``.

Time stamps are on LSL's clock (``pylsl.local_clock``): each frame's sampling time from the
de-jittered frame clock (:mod:`bpms.pipeline.frame_clock`), minus the configured link delay
(option ``lsl.link_delay_s``). The first second of a stream (:data:`SETTLE_S`; and after each
reconnection or seek) is held back and stamped together on the lower envelope of all its
frames' arrivals: the frames that open a stream come late (the link and the threads starting),
and a clock anchored on them alone would slew for its first tenth of a second. Samples before
the first Reset Zero (NaN orientations) are sent as NaN, so every stream has one sample per
processed frame.

pylsl is imported when the outlets are created, never at module import.
"""

from __future__ import annotations

import itertools
import logging
import os
import secrets
import socket
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bpms.filter.joints import CONVENTION_TEXT, JOINT_ANGLE_NAMES
from bpms.io.frames import FRAME_PERIOD_S, IMU_NAMES
from bpms.io.names import imu_column, joint_column, slug
from bpms.pipeline.frame_clock import FrameClock

log = logging.getLogger(__name__)

STREAM_NAMES = {"segments": "BPMS Segments", "joints": "BPMS Joint Angles",
                "sensors": "BPMS Sensors", "disturbance": "BPMS Disturbance",
                "events": "BPMS Events"}
#: Source states in which the link counts as lost (the suit's silent, gone and reopening;
#: "link lost" is what a UDP client source reports).
LINK_LOST_STATES = frozenset({"silent", "gone", "reopening", "link lost"})

MARKERS = ("Reset Zero (source) at T s, ...", "alignment on/off", "marker at T s: TEXT",
           "filter NAME", "filter settings ...", "filters re-initialised", "logging start",
           "logging stop", "link lost", "link recovered", "warnings")
#: Stream time held back at the start of a run (a stream start, reconnection or seek) so that
#: its frames are stamped on the envelope of all their arrivals, s (50 frames at 50 Hz; a
#: replay at speed s holds 50 · s frames).
SETTLE_S = 1.0
_QUAT = ("W", "X", "Y", "Z")
#: (XDF channel type, the channel's letter as in bpms extract's ax … gz columns, unit)
_SENSOR_AXES = (("Acceleration", "a", "m/s^2"), ("MagneticField", "m", "gauss"),
                ("AngularVelocity", "g", "rad/s"))


def unique_source_id() -> str:
    """The base of the streams' ``source_id``: this host, this process and this session, so
    that no two senders ever share one (an inlet that recovers a lost stream finds only its
    own sender again, never another bpms; docs/lsl.md). The stream's key follows after a
    colon: ``bpms@HOST/pid1234/20261207T051620-a3f9c1:joints``."""
    started = time.strftime("%Y%m%dT%H%M%S")
    return f"bpms@{socket.gethostname()}/pid{os.getpid()}/{started}-{secrets.token_hex(3)}"


@dataclass(frozen=True)
class Channel:
    label: str
    type: str
    unit: str
    marker: str = ""  # the body segment (XDF MoCap meta-data "marker")


def segment_channels() -> list[Channel]:
    """72 channels: per segment the quaternion w, x, y, z (XDF types OrientationA..D)."""
    return [Channel(imu_column(i, f"q{c.lower()}"), f"Orientation{'ABCD'[k]}",
                    "normalized", slug(name))
            for i, name in enumerate(IMU_NAMES) for k, c in enumerate(_QUAT)]


def joint_channels() -> list[Channel]:
    """28 channels in :data:`bpms.filter.joints.JOINT_ANGLE_NAMES` order, degrees."""
    return [Channel(joint_column(name), "JointAngle", "degrees", name.split(".")[0])
            for name in JOINT_ANGLE_NAMES]


def sensor_channels() -> list[Channel]:
    """162 channels: per IMU accel x, y, z, mag x, y, z, gyro x, y, z (``imu0_right_leg_ax``
    … ``imu17_head_gz``, the names of ``bpms extract``'s columns)."""
    return [Channel(imu_column(i, f"{short}{axis}"), f"{kind}{axis.upper()}", unit, slug(name))
            for i, name in enumerate(IMU_NAMES) for kind, short, unit in _SENSOR_AXES
            for axis in "xyz"]


def disturbance_channels() -> list[Channel]:
    """36 channels: the 18 magnetometer flags (IMU order), then the 18 acceleration flags."""
    return [Channel(imu_column(i, f"{kind}_disturbed"), f"{kind.capitalize()}Disturbed",
                    "flag", slug(name))
            for kind in ("mag", "acc") for i, name in enumerate(IMU_NAMES)]


def _describe(info, channels: Sequence[Channel], extra: dict[str, str]) -> None:
    desc = info.desc()
    acq = desc.append_child("acquisition")
    acq.append_child_value("manufacturer", "BPMS Suite")
    acq.append_child_value("model", "BPMS 18-IMU inertial suit")
    for key, value in extra.items():
        desc.append_child_value(key, value)
    chans = desc.append_child("channels")
    for ch in channels:
        node = chans.append_child("channel")
        node.append_child_value("label", ch.label)
        node.append_child_value("type", ch.type)
        node.append_child_value("unit", ch.unit)
        if ch.marker:
            node.append_child_value("marker", ch.marker)


class LslOutlets:
    """The four outlets. ``convention``: joint-angle convention name; ``period``: the frame
    period of the stream being sent (s; replay at speed ``s``: ``0.02 / s``); ``link_delay``:
    s subtracted from every stamp."""

    def __init__(self, convention: str = "isb", period: float = FRAME_PERIOD_S,
                 link_delay: float = 0.0, source_id: str | None = None) -> None:
        import pylsl

        self._lsl = pylsl
        self.clock = FrameClock(period, link_delay)
        self.link_delay = link_delay
        # perf_counter (frame arrival) → LSL's clock; both are monotonic seconds
        self._to_lsl = pylsl.local_clock() - time.perf_counter()
        base = source_id or unique_source_id()
        rate = 1.0 / FRAME_PERIOD_S
        sync = {"reference_frame": "segment axes (x forward, y right, z down in the calibration "
                                   "pose) -> world north-east-down",
                "time_stamps": "de-jittered 50 Hz frame clock anchored to receive times, "
                               f"link delay {link_delay:g} s subtracted",
                "docs": "docs/lsl.md",
                "sender": f"{base} (host/process/session: unique to this sender)"}
        self.outlets = {}
        for key, channels, stype, fmt, extra in (
                ("segments", segment_channels(), "MoCap", pylsl.cf_float32,
                 {"quaternion_order": "w x y z"}),
                ("joints", joint_channels(), "MoCap", pylsl.cf_float32,
                 {"convention": CONVENTION_TEXT.get(convention, convention)}),
                ("sensors", sensor_channels(), "IMU", pylsl.cf_float32,
                 {"axes": "signed board axes"}),
                ("disturbance", disturbance_channels(), "Misc", pylsl.cf_int8, {
                    "meaning": "1: the IMU's magnetometer is disturbed (the field off the "
                               "earth's learnt at rest by more than 10 %, or its horizontal "
                               "part turned) / it accelerates by over 0.2 g RMS; 0: not; -1: "
                               "not computed",
                    "order": "18 mag flags then 18 acc flags, IMU order"})):
            info = pylsl.StreamInfo(STREAM_NAMES[key], stype, len(channels), rate, fmt,
                                    f"{base}:{key}")
            _describe(info, channels, {**extra, **sync})
            self.outlets[key] = pylsl.StreamOutlet(info, chunk_size=1, max_buffered=360)
        info = pylsl.StreamInfo(STREAM_NAMES["events"], "Markers", 1, pylsl.IRREGULAR_RATE,
                                pylsl.cf_string, f"{base}:events")
        _describe(info, [Channel("event", "Marker", "")],
                  {"events": ", ".join(MARKERS), **sync})
        self.outlets["events"] = pylsl.StreamOutlet(info)
        self._stamps: dict[int, float] = {}
        self._held: list[tuple] = []  # the run's first frames: (index, arrival, q, a, s, d)
        self._held_markers: list[tuple[str, int]] = []
        self._settled = False  # False until a run's first second has been stamped
        self.settle_frames = max(1, round(SETTLE_S / period))
        self.sent = 0

    def local_clock(self) -> float:
        return self._lsl.local_clock()

    def push_frames(self, indices: Sequence[int], arrivals: Sequence[float],
                    quaternions: np.ndarray, joint_angles: np.ndarray, sensors: np.ndarray,
                    discontinuity: bool = False,
                    disturbance: np.ndarray | None = None) -> list[float]:
        """One sample per frame on every data stream. ``arrivals``: ``time.perf_counter()``
        at receipt; quaternions ``[N, 18, 4]``; joint_angles ``[N, 28]`` rad; sensors
        ``[N, 18, 9]``; disturbance ``[N, 36]`` (mag flags, acc flags; -1 unknown; None: all
        -1); ``discontinuity``: the first frame starts a new run (reconnection, seek).
        Returns the LSL time stamps of the frames sent now: a run's first
        :attr:`settle_frames` (:data:`SETTLE_S` of stream) are sent together once they have
        all arrived."""
        n = len(indices)
        q = np.asarray(quaternions, dtype=np.float32).reshape(n, -1)
        a = np.degrees(np.asarray(joint_angles, dtype=np.float64)).astype(np.float32)
        s = np.asarray(sensors, dtype=np.float32).reshape(n, -1)
        d = (np.full((n, 36), -1, dtype=np.int8) if disturbance is None
             else np.asarray(disturbance, dtype=np.int8).reshape(n, -1))
        frames = [(int(indices[k]), float(arrivals[k]) + self._to_lsl, q[k], a[k], s[k], d[k])
                  for k in range(n)]
        if discontinuity and frames:
            stamps = self.flush()  # the previous run's held frames, on their own envelope
            self._settled = False
            self._held = [(*frames[0], True)]  # (..., discontinuity)
            frames = frames[1:]
        else:
            stamps = []
        if not self._settled:
            self._held += [(*f, False) for f in frames]
            if len(self._held) >= self.settle_frames:
                stamps += self.flush()
            return stamps
        return stamps + self._send(frames)

    def flush(self) -> list[float]:
        """Send the held frames of a run now (at a run's end, or once it has
        :attr:`settle_frames`), stamped on the lower envelope of their arrivals."""
        if not self._held:
            return []
        held, self._held = self._held, []
        period = self.clock.period
        offset = min(f[1] - f[0] * period for f in held)  # never later than any arrival
        stamps = self._send([(f[0], offset + f[0] * period, *f[2:6]) for f in held],
                            discontinuity=held[0][6])
        self._settled = True
        markers, self._held_markers = self._held_markers, []
        for text, index in markers:
            self.marker(text, index)
        return stamps

    def _send(self, frames: list[tuple], discontinuity: bool = False) -> list[float]:
        if not frames:
            return []
        stamps = self.clock.stamp_many([f[0] for f in frames], [f[1] for f in frames],
                                       discontinuity)
        seg, jnt, sen, dis = (self.outlets[k] for k in ("segments", "joints", "sensors",
                                                        "disturbance"))
        for (_, _, q, a, s, d), t in zip(frames, stamps, strict=True):
            seg.push_sample(q, t)
            jnt.push_sample(a, t)
            sen.push_sample(s, t)
            dis.push_sample(d.tolist(), t)
        for (i, *_), t in zip(frames[-64:], stamps[-64:], strict=True):
            self._stamps[i] = t
        if len(self._stamps) > 512:
            for key in sorted(self._stamps)[:-256]:
                del self._stamps[key]
        self.sent += len(stamps)
        return stamps

    def marker(self, text: str, index: int = -1) -> float:
        """Send an event; stamped at frame ``index``'s time when known, else now (minus the
        link delay for link events, which concern frames). An event of a held frame waits
        for its frame (:meth:`flush`); then the return value is NaN."""
        if index >= 0 and any(f[0] == index for f in self._held):
            self._held_markers.append((text, index))
            return float("nan")
        t = self._stamps.get(index)
        if t is None:
            t = self.local_clock() - (self.link_delay if text.startswith("link") else 0.0)
        self.outlets["events"].push_sample([text], t)
        return t

    def close(self) -> None:
        """Send what is held, then release the outlets (liblsl closes them)."""
        if self.outlets:
            self.flush()
        self.outlets.clear()


class LslBridge:
    """Feeds a :class:`bpms.pipeline.session.LiveSession` into :class:`LslOutlets` from its own
    thread (a bounded subscription: it never slows the processing)."""

    def __init__(self, session, convention: str | None = None, period: float | None = None,
                 link_delay: float | None = None) -> None:
        options = session.options
        self.session = session
        self.outlets = LslOutlets(
            convention or session.processor.options.joints.convention,
            period or FRAME_PERIOD_S,
            options.lsl.link_delay_s if link_delay is None else link_delay)
        self._samples = session.subscribe(maxlen=3000, lossless=True)
        self._markers = session.events.subscribe(maxlen=500)
        self._dt = session.processor.options.filter.dt
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="bpms-lsl", daemon=True)
        self._last_index: int | None = None
        self._link_state: str | None = None
        self._pending: list[tuple[str, int, float]] = []  # markers waiting for their frame
        self.errors = 0

    def start(self) -> LslBridge:
        self._thread.start()
        return self

    def stop(self, timeout: float = 5.0) -> None:
        """Send what is waiting, then close the outlets."""
        self._stop.set()
        self._thread.join(timeout)
        self.session.unsubscribe(self._samples)
        self.session.events.unsubscribe(self._markers)
        self.outlets.close()

    @property
    def sent(self) -> int:
        return self.outlets.sent

    def _run(self) -> None:
        while True:
            stopping = self._stop.is_set()
            first = self._samples.get(0.1)
            batch = ([first] if first is not None else []) + self._samples.drain()
            try:
                if batch:
                    self._send(batch)
                self._send_markers(stopping)
                self._watch_link()
            except Exception as exc:  # an LSL failure must not take the session down
                self.errors += 1
                log.warning("LSL send failed: %s", exc)
            if stopping and not batch:
                break

    def _send_markers(self, flush: bool) -> None:
        """A frame-tied marker waits (up to 1 s) until its frame has been stamped."""
        now = time.monotonic()
        self._pending += [(event.describe(self._dt), event.frame, now)
                          for event in self._markers.drain()]
        keep = []
        for text, index, since in self._pending:
            waiting = index >= 0 and (self._last_index is None or index > self._last_index)
            if waiting and not flush and now - since < 1.0:
                keep.append((text, index, since))
            else:
                self.outlets.marker(text, index)
        self._pending = keep

    def _send(self, batch) -> None:
        from bpms.filter.rotations import finite_dcm_to_quaternion

        q = finite_dcm_to_quaternion(np.stack([s.C for s in batch]))
        acc, mag, gyr = self.session.processor.sensor_calibration.physical_units(
            np.stack([s.raw for s in batch]))
        sensors = np.concatenate([acc, mag, gyr], axis=-1)
        flags = np.array([np.concatenate([s.mag_disturbed, s.acc_disturbed])
                          if s.mag_disturbed is not None and s.acc_disturbed is not None
                          else np.full(36, -1) for s in batch], dtype=np.int8)
        # runs split where the source index does not continue (a seek or reconnection)
        idx = [s.index for s in batch]
        starts = [0] + [k for k in range(1, len(idx)) if idx[k] != idx[k - 1] + 1] + [len(idx)]
        for lo, hi in itertools.pairwise(starts):
            jump = self._last_index is not None and idx[lo] != self._last_index + 1
            self.outlets.push_frames(idx[lo:hi], [s.arrival for s in batch[lo:hi]], q[lo:hi],
                                     np.stack([s.joint_angles for s in batch[lo:hi]]),
                                     sensors[lo:hi], discontinuity=jump,
                                     disturbance=flags[lo:hi])
            self._last_index = idx[hi - 1]

    def _watch_link(self) -> None:
        state = self.session.source.status().state
        lost = state in LINK_LOST_STATES
        if lost and self._link_state not in LINK_LOST_STATES:
            self.outlets.marker("link lost")
        elif self._link_state in LINK_LOST_STATES and state == "streaming":
            self.outlets.marker("link recovered")
        self._link_state = state


def wait_for_consumers(bridges: Sequence, seconds: float) -> None:
    """Wait up to ``seconds`` in all until every stream of the LSL bridges among ``bridges``
    has a consumer (e.g. LabRecorder); the other bridges are ignored."""
    deadline = time.monotonic() + seconds
    for bridge in bridges:
        if isinstance(bridge, LslBridge):
            for outlet in bridge.outlets.outlets.values():
                outlet.wait_for_consumers(max(0.0, deadline - time.monotonic()))


def attach_lsl(session, period: float | None = None) -> LslBridge:
    """Start LSL streaming of ``session`` (the GUI's switch calls this; ``bridge.stop()`` ends
    it). ``period``: the frame period of the stream (replay at speed s: ``0.02 / s``)."""
    return LslBridge(session, period=period).start()
