"""Live-stream forwarding over UDP (docs/udp.md): codec, forwarder (server), source (client).

The byte-exact format, the counter semantics and multicast notes are in ``docs/udp.md``.
Every datagram is a 32-byte header followed by a payload; all fields are big-endian (network
byte order, like the suit's frame)::

    offset size type     field
    0      4    bytes    magic b"BPMS"
    4      1    uint8    format version (1)
    5      1    uint8    message type: 1 RAW_FRAME, 2 POSE
    6      2    uint16   flags (senders write 0; readers ignore unknown bits)
    8      4    uint32   session id (random per forwarder, never 0)
    12     4    uint32   sequence number (per message type and session, wraps 2**32-1 -> 0)
    16     8    float64  suit time, s (frame index × 0.02 since the stream started)
    24     8    float64  host send time, s since the Unix epoch
    32     ...           payload

RAW_FRAME payload: the 340-byte suit frame exactly as received. POSE payload: uint16 segment
count S, uint16 angle count A, S quaternions (w, x, y, z float32, body→NED, IMU order), then A
joint angles (float32 rad, order :data:`bpms.filter.joints.JOINT_ANGLE_NAMES`). POSE version 2
appends extension blocks (uint16 tag, uint16 length, data; readers skip unknown tags): tag 1
joint positions (uint16 P, P × 3 float32 m NED, order ``POINT_NAMES``), tag 2 the joint-angle
convention name (ASCII).

Nothing here imports Qt. :class:`UdpForwarder` and :class:`UdpSource` are thread-safe: any
thread may send / read stats / close.
"""

from __future__ import annotations

import bisect
import contextlib
import errno
import hashlib
import hmac
import ipaddress
import logging
import math
import os
import select
import socket
import struct
import threading
import time
from collections import deque
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from pathlib import Path

import numpy as np

from bpms.io.frames import FRAME_PERIOD_S, FRAME_SIZE, is_frame

log = logging.getLogger(__name__)

MAGIC = b"BPMS"
VERSION = 1
POSE_VERSION = 2  # POSE with extension blocks (joint positions, convention); docs/udp.md
READ_VERSIONS = (1, 2)
EXT_BLOCK = struct.Struct("!HH")
EXT_JOINT_POSITIONS = 1
EXT_CONVENTION = 2
#: POSE extension: two uint32 masks, bit i = IMU i magnetometer / acceleration disturbed.
EXT_DISTURBANCE = 3
DISTURBANCE_MASKS = struct.Struct("!II")
HEADER = struct.Struct("!4sBBHIIdd")
HEADER_SIZE = HEADER.size
assert HEADER_SIZE == 32
POSE_COUNTS = struct.Struct("!HH")
N_POSE_SEGMENTS = 18
N_POSE_ANGLES = 28
#: Largest UDP payload over IPv4.
MAX_DATAGRAM = 65507
#: |‖q‖ − 1| above this makes a POSE datagram malformed (float32 rounding is ~1e-7).
QUAT_NORM_TOLERANCE = 1e-3
SEQ_MOD = 1 << 32
#: Reorder window in sequence numbers (~11 min at 50 Hz). See docs/udp.md "Sequence numbers".
REORDER_WINDOW = 1 << 15
DEFAULT_PORT = 5005
#: Header flag: a 32-byte HMAC-SHA256 tag (over header and payload) follows the payload.
FLAG_HMAC = 0x0001
TAG_SIZE = 32
#: Environment variable holding the shared UDP key (text; see docs/udp.md "Shared key").
KEY_ENV = "BPMS_UDP_KEY"
#: Receiver's sanity range of header times: suit time, s (≈ 3 years of frames) and send
#: time, s since the epoch (1970 .. 2286). Outside: a malformed datagram.
MAX_SUIT_TIME_S = 1e8
MAX_SEND_TIME_S = 1e10
#: An active session keeps the receiver until it has been silent this long, s.
TAKEOVER_AFTER_S = 1.0
#: "another sender" shows while foreign datagrams came within this time, s.
FOREIGN_SHOWN_S = 5.0


class MessageType(IntEnum):
    RAW_FRAME = 1
    POSE = 2


class DatagramError(ValueError):
    """The only exception :func:`decode_datagram` raises: the datagram is malformed (the
    message says why, in one line)."""


class UdpConfigError(ValueError):
    """A bad ``host:port`` target or listen address, or a socket that cannot be opened."""


@dataclass(frozen=True)
class Pose:
    """Filtered pose: ``quaternions[S, 4]`` (w, x, y, z; body→NED; S = 18 in IMU order) and
    ``angles[A]`` joint angles in rad (A = 28, order ``JOINT_ANGLE_NAMES``), both float32."""

    quaternions: np.ndarray
    angles: np.ndarray
    positions: np.ndarray | None = None  # [P, 3] m NED (POSE version 2)
    convention: str | None = None  # joint-angle convention (POSE version 2)
    #: bit i set: IMU i's magnetometer disturbed / acceleration far from gravity (tag 3)
    mag_disturbed: int | None = None
    acc_disturbed: int | None = None


@dataclass(frozen=True)
class Datagram:
    """One decoded datagram. ``frame`` is set for RAW_FRAME, ``pose`` for POSE."""

    type: MessageType
    flags: int
    session: int
    seq: int
    suit_time: float
    send_time: float
    frame: bytes | None = None
    pose: Pose | None = None


# --------------------------------------------------------------------------- codec


def encode_header(mtype: int, session: int, seq: int, suit_time: float, send_time: float,
                  flags: int = 0, version: int = VERSION) -> bytes:
    """The 32-byte header. ``seq`` is reduced modulo 2**32."""
    return HEADER.pack(MAGIC, version, int(mtype), flags, session, seq % SEQ_MOD,
                       float(suit_time), float(send_time))


def encode_raw_frame(frame: bytes, *, session: int, seq: int, suit_time: float,
                     send_time: float, flags: int = 0) -> bytes:
    """A RAW_FRAME datagram. Raises ValueError when ``frame`` is not a 340-byte frame."""
    if not is_frame(frame):
        raise ValueError(f"not a {FRAME_SIZE}-byte frame with $#/#$ markers")
    return encode_header(MessageType.RAW_FRAME, session, seq, suit_time, send_time,
                         flags) + bytes(frame)


def encode_pose_payload(quaternions: np.ndarray, angles: np.ndarray) -> bytes:
    """POSE payload from ``quaternions[S, 4]`` (normalised here) and ``angles[A]`` rad.

    Raises ValueError on wrong shapes, non-finite values or a zero quaternion."""
    q = np.asarray(quaternions, dtype=np.float64)
    a = np.asarray(angles, dtype=np.float64).reshape(-1)
    if q.ndim != 2 or q.shape[1] != 4:
        raise ValueError(f"quaternions must have shape [S, 4], got {q.shape}")
    if not (np.isfinite(q).all() and np.isfinite(a).all()):
        raise ValueError("pose contains NaN or infinite values")
    norms = np.linalg.norm(q, axis=1)
    if (norms < 1e-6).any():
        raise ValueError("pose contains a zero quaternion")
    q = q / norms[:, None]
    return (POSE_COUNTS.pack(len(q), len(a)) + q.astype(">f4").tobytes()
            + a.astype(">f4").tobytes())


def disturbance_mask(flags: np.ndarray) -> int:
    """``flags[n]`` bool (IMU order) → an int with bit i set where ``flags[i]``."""
    bits = np.flatnonzero(np.asarray(flags, dtype=bool).reshape(-1))
    return int(sum(1 << int(i) for i in bits))


def encode_pose_extensions(positions: np.ndarray | None = None,
                           convention: str | None = None,
                           disturbance: tuple[np.ndarray, np.ndarray] | None = None) -> bytes:
    """POSE version 2 extension blocks: joint positions ``[P, 3]`` m (NED), the joint-angle
    convention name and/or the disturbance flags ``(mag[18], acc[18])`` bool (tag 3, two
    masks). Raises ValueError on non-finite positions."""
    out = b""
    if positions is not None:
        p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        if not np.isfinite(p).all():
            raise ValueError("joint positions contain NaN or infinite values")
        data = POSE_COUNTS.pack(len(p), 0)[:2] + p.astype(">f4").tobytes()
        out += EXT_BLOCK.pack(EXT_JOINT_POSITIONS, len(data)) + data
    if convention:
        data = convention.encode("ascii")
        out += EXT_BLOCK.pack(EXT_CONVENTION, len(data)) + data
    if disturbance is not None:
        data = DISTURBANCE_MASKS.pack(*(disturbance_mask(f) for f in disturbance))
        out += EXT_BLOCK.pack(EXT_DISTURBANCE, len(data)) + data
    return out


def _decode_extensions(data: bytes) -> dict:
    out: dict = {}
    pos = 0
    while pos < len(data):
        if len(data) - pos < EXT_BLOCK.size:
            raise DatagramError("POSE extension block header is truncated")
        tag, length = EXT_BLOCK.unpack_from(data, pos)
        pos += EXT_BLOCK.size
        block = data[pos:pos + length]
        if len(block) != length:
            raise DatagramError(f"POSE extension block {tag} is truncated")
        pos += length
        if tag == EXT_JOINT_POSITIONS:
            n = struct.unpack_from("!H", block)[0] if length >= 2 else -1
            if length != 2 + 12 * n:
                raise DatagramError("POSE joint-position block has the wrong length")
            p = np.frombuffer(block, ">f4", 3 * n, 2).reshape(n, 3)
            if not np.isfinite(p).all():
                raise DatagramError("POSE joint positions hold NaN or infinite values")
            out["positions"] = p.astype(np.float32)
        elif tag == EXT_CONVENTION:
            out["convention"] = block.decode("ascii", "replace")
        elif tag == EXT_DISTURBANCE:
            if length != DISTURBANCE_MASKS.size:
                raise DatagramError("POSE disturbance block has the wrong length")
            out["mag_disturbed"], out["acc_disturbed"] = DISTURBANCE_MASKS.unpack(block)
        # other tags: skipped (later extensions)
    return out


def encode_pose(quaternions: np.ndarray, angles: np.ndarray, *, session: int, seq: int,
                suit_time: float, send_time: float, flags: int = 0) -> bytes:
    """A POSE datagram (see :func:`encode_pose_payload`)."""
    return encode_header(MessageType.POSE, session, seq, suit_time, send_time,
                         flags) + encode_pose_payload(quaternions, angles)


def _decode_pose(payload: bytes, version: int = VERSION) -> Pose:
    if len(payload) < POSE_COUNTS.size:
        raise DatagramError(f"POSE payload is {len(payload)} bytes, shorter than its counts")
    n_seg, n_ang = POSE_COUNTS.unpack_from(payload)
    expected = POSE_COUNTS.size + 16 * n_seg + 4 * n_ang
    extensions = {}
    if version >= 2 and len(payload) >= expected:  # i16: extension blocks after the angles
        extensions = _decode_extensions(payload[expected:])
        payload = payload[:expected]
    if len(payload) != expected:
        raise DatagramError(f"POSE payload is {len(payload)} bytes, its counts "
                            f"({n_seg} segments, {n_ang} angles) need {expected}")
    q = np.frombuffer(payload, ">f4", 4 * n_seg, POSE_COUNTS.size).reshape(n_seg, 4)
    a = np.frombuffer(payload, ">f4", n_ang, POSE_COUNTS.size + 16 * n_seg)
    if not (np.isfinite(q).all() and np.isfinite(a).all()):
        raise DatagramError("POSE holds NaN or infinite values")
    with np.errstate(over="ignore"):
        norms = np.sqrt(np.sum(q.astype(np.float64) ** 2, axis=1))
    bad = np.flatnonzero(np.abs(norms - 1.0) > QUAT_NORM_TOLERANCE)
    if bad.size:
        raise DatagramError(f"POSE quaternion {bad[0]} is not a unit quaternion "
                            f"(norm {norms[bad[0]]:.4g})")
    return Pose(q.astype(np.float32), a.astype(np.float32), **extensions)


def decode_datagram(data: bytes | bytearray | memoryview) -> Datagram:
    """Decode one datagram. Raises :class:`DatagramError` (and nothing else) when it is short,
    has the wrong magic, an unknown version or type, the wrong length, non-finite times, a
    RAW_FRAME payload that is not a valid frame, or a POSE with NaN / non-unit quaternions."""
    data = bytes(data)
    if len(data) < HEADER_SIZE:
        raise DatagramError(f"{len(data)} bytes, shorter than the {HEADER_SIZE}-byte header")
    magic, version, mtype, flags, session, seq, suit_time, send_time = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise DatagramError(f"wrong magic {magic!r} (expected {MAGIC!r})")
    if version not in READ_VERSIONS:
        raise DatagramError(f"unknown format version {version} (this software reads "
                            f"{', '.join(map(str, READ_VERSIONS))})")
    if not (math.isfinite(suit_time) and math.isfinite(send_time)):
        raise DatagramError("suit time or send time is not a finite number")
    payload = data[HEADER_SIZE:]
    if mtype == MessageType.RAW_FRAME:
        if len(payload) != FRAME_SIZE:
            raise DatagramError(f"RAW_FRAME payload is {len(payload)} bytes, not {FRAME_SIZE}")
        if not is_frame(payload):
            raise DatagramError("RAW_FRAME payload lacks the $#/#$ frame markers")
        return Datagram(MessageType.RAW_FRAME, flags, session, seq, suit_time, send_time,
                        frame=payload)
    if mtype == MessageType.POSE:
        return Datagram(MessageType.POSE, flags, session, seq, suit_time, send_time,
                        pose=_decode_pose(payload, version))
    raise DatagramError(f"unknown message type {mtype}")


# --------------------------------------------------------------------------- addresses


def parse_address(text: str, *, default_host: str = "0.0.0.0") -> tuple[str, int]:
    """``"host:port"`` (or ``":port"`` / ``"port"``) → (dotted IPv4, port). Host names are
    resolved (IPv4 only). Raises UdpConfigError with a one-line message."""
    text = str(text).strip()
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host, port_text = "", text
    host = host.strip() or default_host
    try:
        port = int(port_text)
    except ValueError:
        raise UdpConfigError(f"{text!r}: the port must be a number (host:port)") from None
    if not 0 <= port <= 65535:
        raise UdpConfigError(f"{text!r}: port {port} is out of range 0..65535")
    try:
        addr = socket.gethostbyname(host)
    except (OSError, UnicodeError) as exc:
        raise UdpConfigError(f"{text!r}: cannot resolve host {host!r} ({exc})") from None
    return addr, port


def is_multicast(host: str) -> bool:
    """True for an IPv4 multicast address (224.0.0.0/4)."""
    try:
        return ipaddress.IPv4Address(host).is_multicast
    except ValueError:
        return False


class _RateLimitedLog:
    """Logs a warning at most once per ``interval_s``, with the count of suppressed ones."""

    def __init__(self, interval_s: float = 1.0) -> None:
        self.interval_s = interval_s
        self._last = -math.inf
        self._suppressed = 0

    def warn(self, message: str, *args: object) -> None:
        now = time.monotonic()
        if now - self._last < self.interval_s:
            self._suppressed += 1
            return
        extra = f" ({self._suppressed} more since the last message)" if self._suppressed else ""
        log.warning(message + extra, *args)
        self._last = now
        self._suppressed = 0


def new_session_id() -> int:
    """A random non-zero 32-bit session id."""
    return int.from_bytes(os.urandom(4), "big") or 1


def key_from_env() -> bytes | None:
    """The shared UDP key from :data:`KEY_ENV` (UTF-8), or None when unset or empty."""
    text = os.environ.get(KEY_ENV, "")
    return text.encode("utf-8") if text else None


class UdpKeyError(UdpConfigError):
    """The configured key file cannot be read (one line, naming the file)."""


def shared_key(key_file: str = "") -> bytes | None:
    """The shared UDP key: :data:`KEY_ENV` when set, else the text of ``key_file`` (the
    options' ``udp.key_file``; surrounding white space stripped), else None (no key). A key
    file that is set but unreadable or empty raises :class:`UdpKeyError`: a receiver must not
    silently accept unauthenticated datagrams because its key went missing."""
    key = key_from_env()
    if key is not None or not key_file:
        return key
    try:
        text = Path(key_file).expanduser().read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError) as exc:
        raise UdpKeyError(f"the UDP key file {key_file} cannot be read ({exc})") from None
    if not text:
        raise UdpKeyError(f"the UDP key file {key_file} is empty")
    return text.encode("utf-8")


def sign_datagram(datagram: bytes, key: bytes) -> bytes:
    """Set :data:`FLAG_HMAC` in the header and append HMAC-SHA256(key, header + payload)."""
    flags = struct.unpack_from("!H", datagram, 6)[0] | FLAG_HMAC
    body = datagram[:6] + struct.pack("!H", flags) + datagram[8:]
    return body + hmac.new(key, body, hashlib.sha256).digest()


def split_tag(data: bytes) -> tuple[bytes, bytes | None]:
    """(datagram without its tag, tag) when :data:`FLAG_HMAC` is set, else (data, None)."""
    if len(data) >= HEADER_SIZE + TAG_SIZE and struct.unpack_from("!H", data, 6)[0] & FLAG_HMAC:
        return data[:-TAG_SIZE], data[-TAG_SIZE:]
    return data, None


def tag_is_valid(body: bytes, tag: bytes | None, key: bytes) -> bool:
    """True when ``tag`` is HMAC-SHA256(key, body) (constant-time comparison)."""
    return tag is not None and hmac.compare_digest(
        tag, hmac.new(key, body, hashlib.sha256).digest())


# --------------------------------------------------------------------------- forwarder


@dataclass(frozen=True)
class ForwarderStats:
    """Counters of a :class:`UdpForwarder`. ``sent`` and ``errors`` count datagrams (one per
    target and message); ``frames`` / ``poses`` count messages handed to ``send_*``."""

    frames: int = 0
    poses: int = 0
    sent: int = 0
    errors: int = 0
    last_error: str = ""


class _Target:
    def __init__(self, text: str, ttl: int, loop: bool, interface: str | None) -> None:
        self.text = text
        self.address = parse_address(text, default_host="127.0.0.1")
        self.multicast = is_multicast(self.address[0])
        try:
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        except OSError as exc:
            raise UdpConfigError(f"cannot open a UDP socket: {exc}") from None
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            if self.multicast:
                sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, ttl)
                sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, int(loop))
                if interface:
                    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF,
                                    socket.inet_aton(interface))
            sock.setblocking(False)
            # connect(): per-target errors (ECONNREFUSED from ICMP) are reported on send.
            sock.connect(self.address)
        except OSError as exc:
            sock.close()
            raise UdpConfigError(f"{text!r}: cannot send there ({exc.strerror or exc})") from None
        self.sock = sock
        self.log = _RateLimitedLog()


class UdpForwarder:
    """Sends every frame (and optionally poses) to one or more ``"host:port"`` targets.

    Unicast and IPv4 multicast (224.0.0.0/4: TTL ``multicast_ttl``, loopback ``multicast_loop``,
    outgoing interface ``multicast_interface`` or the system's default) and broadcast addresses.
    Sockets are non-blocking: a send never waits; a failed send (nobody listening, full buffer,
    network down) is counted in ``stats.errors`` and logged at most once per second per target.
    Sequence numbers count per message type from 0 in a fresh random session.
    """

    def __init__(self, targets: Sequence[str], multicast_ttl: int = 1, *,
                 multicast_loop: bool = True, multicast_interface: str | None = None,
                 session: int | None = None, key: bytes | None = None) -> None:
        self._key = key or None  # shared key: every datagram signed (docs/udp.md)
        if isinstance(targets, str):
            targets = [targets]
        if not targets:
            raise UdpConfigError("no UDP target given (host:port)")
        self.session = new_session_id() if session is None else session & 0xFFFFFFFF
        self._targets: list[_Target] = []
        try:
            for text in targets:
                self._targets.append(_Target(text, multicast_ttl, multicast_loop,
                                             multicast_interface))
        except UdpConfigError:
            self.close()
            raise
        self._lock = threading.Lock()
        self._seq = {MessageType.RAW_FRAME: 0, MessageType.POSE: 0}
        self._stats = ForwarderStats()
        self._closed = False

    @property
    def targets(self) -> list[tuple[str, int]]:
        return [t.address for t in self._targets]

    @property
    def stats(self) -> ForwarderStats:
        with self._lock:
            return self._stats

    def next_seq(self, mtype: MessageType) -> int:
        """The sequence number the next message of this type will carry."""
        with self._lock:
            return self._seq[mtype]

    def _send(self, mtype: MessageType, build: object) -> int:
        with self._lock:
            if self._closed:
                return 0
            seq = self._seq[mtype]
            self._seq[mtype] = (seq + 1) % SEQ_MOD
            datagram = build(seq)  # type: ignore[operator]
            if self._key is not None:
                datagram = sign_datagram(datagram, self._key)
            sent = errors = 0
            last_error = self._stats.last_error
            for target in self._targets:
                try:
                    target.sock.send(datagram)
                    sent += 1
                except OSError as exc:
                    errors += 1
                    reason = (errno.errorcode.get(exc.errno or 0, "")
                              + f" {exc.strerror or exc}").strip()
                    last_error = f"{target.text}: {reason}"
                    target.log.warn("UDP send to %s failed: %s", target.text, reason)
            s = self._stats
            self._stats = ForwarderStats(
                s.frames + (mtype == MessageType.RAW_FRAME), s.poses + (mtype == MessageType.POSE),
                s.sent + sent, s.errors + errors, last_error)
            return sent

    def send_frame(self, frame: bytes, suit_time: float | None = None) -> int:
        """Forward one 340-byte frame. ``suit_time`` defaults to its sequence number × 0.02 s.
        Returns the number of targets it was handed to. Raises ValueError on a non-frame."""
        if not is_frame(frame):
            raise ValueError(f"not a {FRAME_SIZE}-byte frame with $#/#$ markers")
        frame = bytes(frame)

        def build(seq: int) -> bytes:
            t = seq * FRAME_PERIOD_S if suit_time is None else suit_time
            return encode_raw_frame(frame, session=self.session, seq=seq, suit_time=t,
                                    send_time=time.time())

        return self._send(MessageType.RAW_FRAME, build)

    def send_pose(self, quaternions: np.ndarray, angles: np.ndarray, suit_time: float,
                  positions: np.ndarray | None = None, convention: str | None = None,
                  disturbance: tuple[np.ndarray, np.ndarray] | None = None) -> int:
        """Forward one filtered pose: ``quaternions[18, 4]`` (w, x, y, z, body→NED) and
        ``angles[28]`` rad; with ``positions[21, 3]`` (m, NED), ``convention`` and/or
        ``disturbance`` = (mag[18], acc[18]) bool flags a version-2 POSE carrying them. Raises
        ValueError on bad shapes or non-finite values."""
        payload = encode_pose_payload(quaternions, angles)
        version = VERSION
        if positions is not None or convention or disturbance is not None:
            payload += encode_pose_extensions(positions, convention, disturbance)
            version = POSE_VERSION

        def build(seq: int) -> bytes:
            return encode_header(MessageType.POSE, self.session, seq, suit_time,
                                 time.time(), version=version) + payload

        return self._send(MessageType.POSE, build)

    def close(self) -> None:
        lock = getattr(self, "_lock", None)
        if lock is not None:
            with lock:
                self._closed = True
        for target in self._targets:
            target.sock.close()

    def __enter__(self) -> UdpForwarder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# --------------------------------------------------------------------------- sequence tracking


class Verdict(IntEnum):
    NEW = 0  # in order (possibly after a gap), or the first of a session
    REORDERED = 1  # fills an earlier gap (arrived after a higher sequence number)
    DUPLICATE = 2  # this sequence number was already received in this session
    STALE = 3  # from a session that has since been replaced: dropped


def _signed(d: int) -> int:
    d %= SEQ_MOD
    return d - SEQ_MOD if d >= SEQ_MOD // 2 else d


class SequenceTracker:
    """Exact loss / duplicate / reorder accounting of one message type (docs/udp.md).

    Within a session, sequence numbers compare by serial-number arithmetic modulo 2**32, so
    the wrap 2**32−1 → 0 is seamless. A new session id, or a jump back by more than
    ``window``, starts a new session (a sender restart); gaps left open in the old session
    become final losses. Datagrams of a replaced session are STALE and dropped.

    Gaps are kept as ranges of unwrapped sequence numbers, so the cost of one datagram is
    O(log gaps) whatever the jump (a jump of 40,000 costs what a jump of 2 does).
    """

    def __init__(self, window: int = REORDER_WINDOW) -> None:
        self.window = window
        self.session: int | None = None
        self._first = 0  # unwrapped
        self._highest = 0  # unwrapped
        self._starts: list[int] = []  # open gaps [start, end), sorted, disjoint
        self._ends: list[int] = []
        self._open = 0  # sequence numbers inside the open gaps
        self._retired: deque[int] = deque(maxlen=8)
        self.unique = 0
        self.duplicated = 0
        self.reordered = 0
        self.stale = 0
        self.restarts = 0
        self.lost_final = 0

    @property
    def first(self) -> int:
        return self._first % SEQ_MOD

    @property
    def highest(self) -> int:
        return self._highest % SEQ_MOD

    @property
    def lost(self) -> int:
        """Sequence numbers not received: final losses plus gaps still open in the window."""
        return self.lost_final + self._open

    @property
    def pending(self) -> int:
        """Gaps still inside the reorder window (a late datagram may still fill them)."""
        return self._open

    def is_retired(self, session: int) -> bool:
        return session in self._retired

    def _start(self, session: int, seq: int) -> None:
        self.lost_final += self._open
        self._starts.clear()
        self._ends.clear()
        self._open = 0
        self.session = session
        self._first = self._highest = seq

    def _add_gap(self, start: int, end: int) -> None:
        """Open the gap [start, end) (unwrapped), kept to the window below the highest."""
        floor = self._highest - self.window
        if start < floor:
            self.lost_final += min(end, floor) - start
            start = floor
        if start >= end:
            return
        k = bisect.bisect_left(self._starts, start)
        self._starts.insert(k, start)
        self._ends.insert(k, end)
        self._open += end - start

    def _prune(self) -> None:
        """Gaps that left the window (more than ``window`` below the highest) are final."""
        floor = self._highest - self.window
        while self._starts and self._starts[0] < floor:
            start, end = self._starts[0], self._ends[0]
            cut = min(end, floor)
            self.lost_final += cut - start
            self._open -= cut - start
            if cut == end:
                del self._starts[0], self._ends[0]
            else:
                self._starts[0] = cut

    def _fill(self, u: int) -> bool:
        """Remove ``u`` from the open gaps; False when it was not missing."""
        k = bisect.bisect_right(self._starts, u) - 1
        if k < 0 or u >= self._ends[k]:
            return False
        start, end = self._starts[k], self._ends[k]
        self._open -= 1
        if start == u and end == u + 1:
            del self._starts[k], self._ends[k]
        elif start == u:
            self._starts[k] = u + 1
        elif end == u + 1:
            self._ends[k] = u
        else:
            self._ends[k] = u
            self._starts.insert(k + 1, u + 1)
            self._ends.insert(k + 1, end)
        return True

    def observe(self, session: int, seq: int) -> Verdict:
        """Account for one well-formed datagram; tell the caller what it was."""
        if self.session is None:
            self._start(session, seq)
            self.unique += 1
            return Verdict.NEW
        if session != self.session:
            if session in self._retired:
                self.stale += 1
                return Verdict.STALE
            self._retired.append(self.session)
            self.restarts += 1
            self._start(session, seq)
            self.unique += 1
            return Verdict.NEW
        d = _signed(seq - self._highest)
        u = self._highest + d
        if d > 0:
            old = self._highest
            self._highest = u
            self._prune()
            self._add_gap(old + 1, u)
            self.unique += 1
            return Verdict.NEW
        if d == 0:
            self.duplicated += 1
            return Verdict.DUPLICATE
        if d < -self.window:
            # Same session id yet far behind: a sender that restarted without a new session.
            self.restarts += 1
            self._start(session, seq)
            self.unique += 1
            return Verdict.NEW
        if u < self._first:
            # Earlier than anything seen so far in this session: extends the session backwards.
            self._add_gap(u + 1, self._first)
            self._first = u
            self.reordered += 1
            self.unique += 1
            return Verdict.REORDERED
        if self._fill(u):
            self.reordered += 1
            self.unique += 1
            return Verdict.REORDERED
        self.duplicated += 1
        return Verdict.DUPLICATE


# --------------------------------------------------------------------------- source (client)


@dataclass(frozen=True)
class SourceStats:
    """Counters of a :class:`UdpSource` (semantics in docs/udp.md).

    ``datagrams = received + malformed + ignored + stale + foreign + unauthenticated``;
    ``received = delivered + duplicated`` (RAW_FRAME datagrams of the current sessions);
    ``reordered`` ⊂ ``delivered``; ``lost`` = sequence numbers never received between the
    first and the highest of each session (``pending`` of them may still arrive late).
    """

    datagrams: int = 0
    received: int = 0
    delivered: int = 0
    lost: int = 0
    pending: int = 0
    duplicated: int = 0
    reordered: int = 0
    malformed: int = 0
    ignored: int = 0
    stale: int = 0
    restarts: int = 0
    socket_errors: int = 0
    last_malformed: str = ""
    foreign: int = 0  # datagrams of another session while the active one streams: dropped
    unauthenticated: int = 0  # refused: no valid HMAC tag while a key is set
    another_sender: str = ""  # "host:port" of a foreign sender seen in the last few seconds


@dataclass(frozen=True)
class ReceivedFrame:
    """One raw frame from the network, in arrival order."""

    frame: bytes
    seq: int
    session: int
    suit_time: float  # s, from the sender
    send_time: float  # s since the epoch, the sender's clock
    recv_time: float  # s since the epoch, this host's clock
    reordered: bool = False
    sender: tuple[str, int] = field(default=("", 0))


class UdpSource:
    """Receives BPMS datagrams on ``listen`` (``"host:port"``), optionally joining an IPv4
    ``multicast_group`` (on ``multicast_interface``, default any), and yields raw frames.

    ``read(timeout)`` returns the next frame, or None after ``timeout`` s or once closed;
    iterating yields frames until :meth:`close`, which any thread may call and which wakes a
    blocked reader at once. Duplicates and datagrams of a replaced session are dropped;
    reordered frames are delivered (flagged) in arrival order. Malformed datagrams (including
    times outside the sanity range) are counted and logged at most once per second with the
    reason. Nothing a peer sends can raise here.

    One sender at a time: while the active session streams, datagrams of another session are
    dropped and counted (``stats.foreign``, ``stats.another_sender``); a new session takes
    over once the active one has been silent for ``takeover_after_s`` (a restarted sender
    thus loses at most that long). ``key``: the shared key; datagrams without a valid
    HMAC-SHA256 tag are then refused and counted (``stats.unauthenticated``).
    """

    def __init__(self, listen: str = f"0.0.0.0:{DEFAULT_PORT}",
                 multicast_group: str | None = None, *, multicast_interface: str = "0.0.0.0",
                 rcvbuf: int | None = 1 << 22, poll_s: float = 0.5,
                 window: int = REORDER_WINDOW, takeover_after_s: float = TAKEOVER_AFTER_S,
                 key: bytes | None = None) -> None:
        host, port = parse_address(listen)
        self.poll_s = poll_s
        self.takeover_after_s = takeover_after_s
        self.key = key or None
        self._last_active = -math.inf  # monotonic time of the active session's last datagram
        self._last_foreign = -math.inf
        self._foreign_sender = ""
        self._foreign_log = _RateLimitedLog(5.0)
        self._auth_log = _RateLimitedLog(5.0)
        self._lock = threading.Lock()
        self._read_lock = threading.Lock()
        self._tracker = SequenceTracker(window)
        self._counts = {"datagrams": 0, "malformed": 0, "ignored": 0, "socket_errors": 0,
                        "foreign": 0, "unauthenticated": 0}
        self._last_malformed = ""
        self._malformed_log = _RateLimitedLog()
        self._error_log = _RateLimitedLog()
        self._closed = False
        try:
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        except OSError as exc:
            raise UdpConfigError(f"cannot open a UDP socket: {exc}") from None
        self._wake_r, self._wake_w = socket.socketpair()
        try:
            if rcvbuf:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
            if multicast_group is not None:
                group = parse_address(f"{multicast_group}:0")[0]
                if not is_multicast(group):
                    raise UdpConfigError(f"{multicast_group!r} is not an IPv4 multicast group "
                                         "(224.0.0.0 - 239.255.255.255)")
                # Several receivers on one host may share a multicast port.
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                sock.bind((host, port))
                mreq = socket.inet_aton(group) + socket.inet_aton(multicast_interface)
                sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
            else:
                sock.bind((host, port))
            sock.setblocking(False)
        except UdpConfigError:
            self._close_sockets(sock)
            raise
        except OSError as exc:
            self._close_sockets(sock)
            where = f"{listen}" + (f" (group {multicast_group})" if multicast_group else "")
            raise UdpConfigError(f"cannot listen on {where}: {exc.strerror or exc}") from None
        self._sock = sock
        self.address: tuple[str, int] = sock.getsockname()
        #: Effective receive buffer, bytes (the kernel caps the request at net.core.rmem_max).
        self.rcvbuf: int = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        self.multicast_group = multicast_group

    def _close_sockets(self, sock: socket.socket) -> None:
        sock.close()
        self._wake_r.close()
        self._wake_w.close()

    @property
    def stats(self) -> SourceStats:
        with self._lock:
            t = self._tracker
            c = self._counts
            return SourceStats(
                datagrams=c["datagrams"], received=t.unique + t.duplicated, delivered=t.unique,
                lost=t.lost, pending=t.pending, duplicated=t.duplicated, reordered=t.reordered,
                malformed=c["malformed"], ignored=c["ignored"], stale=t.stale,
                restarts=t.restarts, socket_errors=c["socket_errors"],
                last_malformed=self._last_malformed, foreign=c["foreign"],
                unauthenticated=c["unauthenticated"], another_sender=self._another_sender())

    def _another_sender(self) -> str:
        fresh = time.monotonic() - self._last_foreign < FOREIGN_SHOWN_S
        return self._foreign_sender if fresh else ""

    @property
    def listening(self) -> str:
        """Where it listens, in words, with the exposure (docs/udp.md "Exposure")."""
        host, port = self.address
        if host == "0.0.0.0":
            where = f"all interfaces, port {port} (any host that can reach this one may send)"
        elif host.startswith("127."):
            where = f"{host}:{port} (this computer only)"
        else:
            where = f"{host}:{port} (hosts that reach this address may send)"
        group = f", group {self.multicast_group}" if self.multicast_group else ""
        return where + group + (", shared key required" if self.key else "")

    @property
    def closed(self) -> bool:
        return self._closed

    def _malformed(self, sender: tuple[str, int], why: object) -> None:
        self._counts["malformed"] += 1
        self._last_malformed = f"{sender[0]}:{sender[1]}: {why}"
        self._malformed_log.warn("malformed UDP datagram from %s:%s ignored: %s",
                                 sender[0], sender[1], why)

    def _handle(self, data: bytes, sender: tuple[str, int]) -> ReceivedFrame | None:
        recv_time = time.time()
        now = time.monotonic()
        with self._lock:
            self._counts["datagrams"] += 1
            body, tag = split_tag(data)
            if self.key is not None and not tag_is_valid(body, tag, self.key):
                self._counts["unauthenticated"] += 1
                self._auth_log.warn("UDP datagram from %s:%s refused: %s", sender[0],
                                    sender[1], "no shared-key tag" if tag is None
                                    else "wrong shared-key tag")
                return None
            try:
                dg = decode_datagram(body)
            except DatagramError as exc:
                self._malformed(sender, exc)
                return None
            if not (0.0 <= dg.suit_time <= MAX_SUIT_TIME_S
                    and 0.0 <= dg.send_time <= MAX_SEND_TIME_S):
                self._malformed(sender, f"times out of range (suit {dg.suit_time:.6g} s, "
                                        f"send {dg.send_time:.6g} s)")
                return None
            if dg.type != MessageType.RAW_FRAME:
                self._counts["ignored"] += 1
                return None
            t = self._tracker
            if (t.session is not None and dg.session != t.session
                    and not t.is_retired(dg.session)
                    and now - self._last_active < self.takeover_after_s):
                self._counts["foreign"] += 1
                self._foreign_sender = f"{sender[0]}:{sender[1]}"
                self._last_foreign = now
                self._foreign_log.warn("UDP datagrams of another sender (%s:%s, session %08x) "
                                       "ignored while session %08x streams", sender[0],
                                       sender[1], dg.session, t.session)
                return None
            verdict = t.observe(dg.session, dg.seq)
            if verdict != Verdict.STALE:
                self._last_active = now
        if verdict in (Verdict.DUPLICATE, Verdict.STALE):
            return None
        assert dg.frame is not None
        return ReceivedFrame(dg.frame, dg.seq, dg.session, dg.suit_time, dg.send_time,
                             recv_time, verdict == Verdict.REORDERED, sender)

    def read(self, timeout: float | None = None) -> ReceivedFrame | None:
        """The next frame, or None when ``timeout`` s (default ``poll_s``) pass without one or
        the source is closed. Waits on the socket with a timeout every time."""
        timeout = self.poll_s if timeout is None else timeout
        deadline = time.monotonic() + timeout
        with self._read_lock:
            while not self._closed:
                try:
                    data, sender = self._sock.recvfrom(MAX_DATAGRAM + 1)
                except (BlockingIOError, InterruptedError):
                    remaining = deadline - time.monotonic()
                    if remaining <= 0:
                        return None
                    try:
                        select.select([self._sock, self._wake_r], [], [], remaining)
                    except (OSError, ValueError):
                        return None  # closed under our feet
                    continue
                except OSError as exc:
                    if self._closed:
                        return None
                    with self._lock:
                        self._counts["socket_errors"] += 1
                    self._error_log.warn("UDP receive error on %s: %s", self.address, exc)
                    if time.monotonic() >= deadline:
                        return None
                    continue
                frame = self._handle(data, sender)
                if frame is not None:
                    return frame
                if time.monotonic() >= deadline:
                    return None
            return None

    def __iter__(self) -> Iterator[ReceivedFrame]:
        """Frames in arrival order until :meth:`close`."""
        while not self._closed:
            frame = self.read()
            if frame is not None:
                yield frame

    def close(self) -> None:
        """Stop receiving; a reader blocked in :meth:`read` returns None promptly."""
        if self._closed:
            return
        self._closed = True
        with contextlib.suppress(OSError):
            self._wake_w.send(b"x")
        with self._read_lock:  # wait for a reader to leave select() before closing its fds
            self._sock.close()
            self._wake_r.close()
            self._wake_w.close()

    def __enter__(self) -> UdpSource:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
