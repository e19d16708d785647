"""The BPMS datagram (docs/udp.md): its layout, encoding and the one decoder.

The byte-exact format, the counter semantics and multicast notes are in ``docs/udp.md``.
Every datagram is a header followed by a payload; all fields are big-endian (network byte
order, like the suit's frame). Versions 3 and 4 (4 is what this software sends) have a 48-byte
header; versions 1 and 2 (still read) stop after the send time, 32 bytes::

    offset size type     field
    0      4    bytes    magic b"BPMS"
    4      1    uint8    format version (4)
    5      1    uint8    message type: 1 RAW_FRAME, 2 POSE, 3 ZERO (version 4)
    6      2    uint16   flags (bit 0: an HMAC-SHA256 tag follows; readers ignore unknown bits)
    8      4    uint32   session id (random per forwarder, never 0)
    12     4    uint32   sequence number (per message type and session, wraps 2**32-1 -> 0)
    16     8    float64  suit time, s (frame index × 0.02 since the stream started)
    24     8    float64  host send time, s since the Unix epoch
    32     8    uint64   sender id (one per computer; version 3)
    40     8    uint64   epoch: µs since 1970 on the sender's clock when the session started,
                         rising with every session of one sender (version 3)
    48     ...           payload

With a shared key the tag signs the whole header, so the sender id and the epoch are the
signed freshness of docs/udp.md "Freshness".

RAW_FRAME payload: the 340-byte suit frame exactly as received. POSE payload: uint16 segment
count S, uint16 angle count A, S quaternions (w, x, y, z float32, body→NED, IMU order), then A
joint angles (float32 rad, order :data:`bpms.filter.joints.JOINT_ANGLE_NAMES`). From version
2 on, POSE appends extension blocks (uint16 tag, uint16 length, data; readers skip unknown
tags): tag 1 joint positions (uint16 P, P × 3 float32 m NED, order ``POINT_NAMES``), tag 2 the
joint-angle convention name (ASCII), tag 3 the disturbance masks, tag 4 the segments that
carry data (uint32 mask; a segment without data, and every angle and position needing it, is
NaN).

ZERO payload (version 4): the sender's Reset Zero in force (sent at each capture and once a
second), so that a client shows the sender's segment angles: uint8 source
(:data:`bpms.io.session_events.ZERO_SOURCES` index), uint8 heading (0 hip, 1 mean), uint16
window (frames averaged), float64 ψ0 (rad), uint32 mask (bit i: IMU i has a zero), 18 × 9
float64 R0 (row-major, 0 where the mask bit is clear); the header's suit time is the capture
frame's. 1,312 bytes.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from bpms.io.frames import FRAME_SIZE, N_IMUS, is_frame
from bpms.io.session_events import ZERO_SOURCES

MAGIC = b"BPMS"
#: What senders write: version 4 (version 3's sender id and epoch in the header, for
#: freshness, and the ZERO message).
VERSION = 4
#: The first version whose POSE payload may carry extension blocks after the angles.
EXTENSIONS_SINCE = 2
#: The first version with ZERO messages.
ZERO_SINCE = 4
READ_VERSIONS = (1, 2, 3, 4)
EXT_BLOCK = struct.Struct("!HH")
EXT_JOINT_POSITIONS = 1
EXT_CONVENTION = 2
#: POSE extension: two uint32 masks, bit i = IMU i magnetometer / acceleration disturbed.
EXT_DISTURBANCE = 3
DISTURBANCE_MASKS = struct.Struct("!II")
#: POSE extension: uint32 mask, bit i set when segment i carries data (docs/udp.md "A segment
#: without data"); a clear bit's quaternion is NaN, and so is every angle and joint position
#: that needs that segment.
EXT_VALIDITY = 4
VALIDITY_MASK = struct.Struct("!I")
HEADER = struct.Struct("!4sBBHIIdd")
#: The shortest header (versions 1 and 2), bytes.
HEADER_SIZE = HEADER.size
assert HEADER_SIZE == 32
#: Version 3's freshness fields after the send time: sender id, epoch (µs).
FRESHNESS = struct.Struct("!QQ")
HEADER_V3_SIZE = HEADER_SIZE + FRESHNESS.size
assert HEADER_V3_SIZE == 48
POSE_COUNTS = struct.Struct("!HH")
ZERO_HEAD = struct.Struct("!BBHdI")  # source, heading, window, ψ0, mask
ZERO_SIZE = ZERO_HEAD.size + N_IMUS * 9 * 8
HEADINGS = ("hip", "mean")
#: Largest UDP payload over IPv4.
MAX_DATAGRAM = 65507
#: |‖q‖ − 1| above this makes a POSE datagram malformed (float32 rounding is ~1e-7).
QUAT_NORM_TOLERANCE = 1e-3
SEQ_MOD = 1 << 32


class SeqRun:
    """Consecutive sequence numbers: how many so far, and the one expected next."""

    __slots__ = ("count", "next")

    def __init__(self, seq: int) -> None:
        self.count = 1
        self.next = (seq + 1) % SEQ_MOD

    def extend(self, seq: int) -> bool:
        """Count ``seq`` when it is the one expected next (True); else False, unchanged."""
        if seq != self.next:
            return False
        self.count += 1
        self.next = (seq + 1) % SEQ_MOD
        return True


class MessageType(IntEnum):
    RAW_FRAME = 1
    POSE = 2
    ZERO = 3


class DatagramError(ValueError):
    """The only exception :func:`decode_datagram` raises: the datagram is malformed (the
    message says why, in one line)."""


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
    #: bit i set: segment i carries data (tag 4); None: no tag, every segment does
    valid: int | None = None

    def segment_valid(self) -> np.ndarray:
        """``[S]`` bool: the segments that carry data (all of them without tag 4)."""
        n = len(self.quaternions)
        return np.ones(n, dtype=bool) if self.valid is None else mask_flags(self.valid, n)


@dataclass(frozen=True)
class ZeroMessage:
    """The sender's Reset Zero: ``R0[18, 3, 3]`` (NaN for an IMU without a zero), ``yaw0``
    rad, ``source`` (:data:`bpms.io.session_events.ZERO_SOURCES`), ``heading`` (``hip`` /
    ``mean``) and ``window`` (frames averaged)."""

    R0: np.ndarray
    yaw0: float
    source: str = "manual"
    heading: str = "hip"
    window: int = 1


@dataclass(frozen=True)
class Datagram:
    """One decoded datagram. ``frame`` is set for RAW_FRAME, ``pose`` for POSE; ``sender``
    and ``epoch`` (µs) are 0 before version 3."""

    type: MessageType
    flags: int
    session: int
    seq: int
    suit_time: float
    send_time: float
    frame: bytes | None = None
    pose: Pose | None = None
    version: int = VERSION
    zero: ZeroMessage | None = None
    sender: int = 0
    epoch: int = 0


def header_size(version: int) -> int:
    """Bytes of the header of a datagram of format ``version``."""
    return HEADER_V3_SIZE if version >= 3 else HEADER_SIZE


def encode_zero_payload(zero: ZeroMessage) -> bytes:
    """ZERO payload (version 4). Raises ValueError on a wrong shape, a non-finite ψ0 or an
    unknown source."""
    R0 = np.asarray(zero.R0, dtype=np.float64)
    if R0.shape != (N_IMUS, 3, 3) or not math.isfinite(zero.yaw0):
        raise ValueError("a zero needs R0 [18, 3, 3] and a finite heading")
    finite = np.asarray(np.isfinite(R0).all(axis=(1, 2)))
    mask = disturbance_mask(finite)
    values = np.where(finite[:, None, None], R0, 0.0)
    source = ZERO_SOURCES.index(zero.source) if zero.source in ZERO_SOURCES else 0
    heading = HEADINGS.index(zero.heading) if zero.heading in HEADINGS else 0
    return (ZERO_HEAD.pack(source, heading, max(0, min(int(zero.window), 65535)),
                           float(zero.yaw0), mask) + values.astype(">f8").tobytes())


def encode_zero(zero: ZeroMessage, *, session: int, seq: int, suit_time: float,
                send_time: float, flags: int = 0, sender: int = 0, epoch: int = 0) -> bytes:
    """A ZERO datagram (version 4; see :func:`encode_zero_payload`)."""
    return encode_header(MessageType.ZERO, session, seq, suit_time, send_time, flags,
                         VERSION, sender, epoch) + encode_zero_payload(zero)


def _decode_zero(payload: bytes) -> ZeroMessage:
    if len(payload) != ZERO_SIZE:
        raise DatagramError(f"ZERO payload is {len(payload)} bytes, not {ZERO_SIZE}")
    source, heading, window, yaw0, mask = ZERO_HEAD.unpack_from(payload)
    if source >= len(ZERO_SOURCES) or heading >= len(HEADINGS) or not math.isfinite(yaw0):
        raise DatagramError("ZERO source, heading or ψ0 out of range")
    R0 = np.frombuffer(payload, ">f8", N_IMUS * 9, ZERO_HEAD.size).reshape(N_IMUS, 3, 3)
    R0 = R0.astype(np.float64)
    has = mask_flags(mask, N_IMUS)
    if not np.isfinite(R0).all() or mask >> N_IMUS:
        raise DatagramError("ZERO holds NaN or infinite values, or an unknown IMU")
    rows = R0[has]
    if len(rows) and np.abs(rows @ np.swapaxes(rows, -1, -2) - np.eye(3)).max() > 1e-6:
        raise DatagramError("ZERO R0 is not a rotation")
    R0[~has] = np.nan
    return ZeroMessage(R0, yaw0, ZERO_SOURCES[source], HEADINGS[heading], window)


def encode_header(mtype: int, session: int, seq: int, suit_time: float, send_time: float,
                  flags: int = 0, version: int = VERSION, sender: int = 0,
                  epoch: int = 0) -> bytes:
    """The header (48 bytes for version 3, 32 before). ``seq`` is reduced modulo 2**32;
    ``sender`` and ``epoch`` (µs) are written from version 3 on."""
    head = HEADER.pack(MAGIC, version, int(mtype), flags, session, seq % SEQ_MOD,
                       float(suit_time), float(send_time))
    return head + FRESHNESS.pack(sender, epoch) if version >= 3 else head


def encode_raw_frame(frame: bytes, *, session: int, seq: int, suit_time: float,
                     send_time: float, flags: int = 0, version: int = VERSION,
                     sender: int = 0, epoch: int = 0) -> bytes:
    """A RAW_FRAME datagram. Raises ValueError when ``frame`` is not a 340-byte frame."""
    if not is_frame(frame):
        raise ValueError(f"not a {FRAME_SIZE}-byte frame with $#/#$ markers")
    return encode_header(MessageType.RAW_FRAME, session, seq, suit_time, send_time,
                         flags, version, sender, epoch) + bytes(frame)


def encode_pose_payload(quaternions: np.ndarray, angles: np.ndarray,
                        valid: np.ndarray | None = None) -> bytes:
    """POSE payload from ``quaternions[S, 4]`` (normalised here) and ``angles[A]`` rad.

    ``valid[S]`` bool (the segments with data; docs/udp.md "A segment without data"): the
    quaternion of a segment without data is written as NaN, and an angle may be NaN (it needs
    such a segment); the caller then sends the validity block (tag 4) with
    :func:`encode_pose_extensions`. Raises ValueError on wrong shapes, infinite values, NaN
    where a segment has data (or anywhere when ``valid`` is None) or a zero quaternion."""
    q = np.asarray(quaternions, dtype=np.float64)
    a = np.asarray(angles, dtype=np.float64).reshape(-1)
    if q.ndim != 2 or q.shape[1] != 4:
        raise ValueError(f"quaternions must have shape [S, 4], got {q.shape}")
    ok = (np.ones(len(q), dtype=bool) if valid is None
          else np.asarray(valid, dtype=bool).reshape(-1))
    if ok.shape != (len(q),):
        raise ValueError(f"valid must have one flag per segment ({len(q)})")
    if not (np.isfinite(q[ok]).all() and not np.isinf(a).any()
            and (valid is not None or np.isfinite(a).all())):
        raise ValueError("pose contains NaN or infinite values")
    norms = np.linalg.norm(q[ok], axis=1)
    if (norms < 1e-6).any():
        raise ValueError("pose contains a zero quaternion")
    out = np.full(q.shape, np.nan)
    out[ok] = q[ok] / norms[:, None]
    return (POSE_COUNTS.pack(len(q), len(a)) + out.astype(">f4").tobytes()
            + a.astype(">f4").tobytes())


def disturbance_mask(flags: np.ndarray) -> int:
    """``flags[n]`` bool (IMU order) → an int with bit i set where ``flags[i]``."""
    bits = np.flatnonzero(np.asarray(flags, dtype=bool).reshape(-1))
    return int(sum(1 << int(i) for i in bits))


def mask_flags(mask: int, n: int) -> np.ndarray:
    """The inverse of :func:`disturbance_mask`: ``[n]`` bool, True where bit i of ``mask`` is
    set (bits from n on ignored)."""
    return ((mask >> np.arange(n, dtype=np.int64)) & 1).astype(bool)


def encode_pose_extensions(positions: np.ndarray | None = None,
                           convention: str | None = None,
                           disturbance: tuple[np.ndarray, np.ndarray] | None = None,
                           valid: np.ndarray | None = None) -> bytes:
    """POSE extension blocks (version 2 on): joint positions ``[P, 3]`` m (NED), the joint-angle
    convention name, the disturbance flags ``(mag[18], acc[18])`` bool (tag 3, two masks)
    and/or the segments with data ``valid[S]`` bool (tag 4; then a position may be NaN: it
    needs a segment without data). Raises ValueError on infinite positions, or NaN ones
    without ``valid``."""
    out = b""
    if positions is not None:
        p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        if np.isinf(p).any() or (valid is None and not np.isfinite(p).all()):
            raise ValueError("joint positions contain NaN or infinite values")
        data = POSE_COUNTS.pack(len(p), 0)[:2] + p.astype(">f4").tobytes()
        out += EXT_BLOCK.pack(EXT_JOINT_POSITIONS, len(data)) + data
    if convention:
        data = convention.encode("ascii")
        out += EXT_BLOCK.pack(EXT_CONVENTION, len(data)) + data
    if disturbance is not None:
        data = DISTURBANCE_MASKS.pack(*(disturbance_mask(f) for f in disturbance))
        out += EXT_BLOCK.pack(EXT_DISTURBANCE, len(data)) + data
    if valid is not None:
        data = VALIDITY_MASK.pack(disturbance_mask(valid))
        out += EXT_BLOCK.pack(EXT_VALIDITY, len(data)) + data
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
            if np.isinf(p).any():
                raise DatagramError("POSE joint positions hold infinite values")
            out["positions"] = p.astype(np.float32)  # NaN: checked against tag 4 below
        elif tag == EXT_CONVENTION:
            out["convention"] = block.decode("ascii", "replace")
        elif tag == EXT_DISTURBANCE:
            if length != DISTURBANCE_MASKS.size:
                raise DatagramError("POSE disturbance block has the wrong length")
            out["mag_disturbed"], out["acc_disturbed"] = DISTURBANCE_MASKS.unpack(block)
        elif tag == EXT_VALIDITY:
            if length != VALIDITY_MASK.size:
                raise DatagramError("POSE validity block has the wrong length")
            out["valid"] = VALIDITY_MASK.unpack(block)[0]
        # other tags: skipped (later extensions)
    return out


def encode_pose(quaternions: np.ndarray, angles: np.ndarray, *, session: int, seq: int,
                suit_time: float, send_time: float, flags: int = 0, version: int = VERSION,
                sender: int = 0, epoch: int = 0) -> bytes:
    """A POSE datagram (see :func:`encode_pose_payload`)."""
    return encode_header(MessageType.POSE, session, seq, suit_time, send_time, flags,
                         version, sender, epoch) + encode_pose_payload(quaternions, angles)


def _decode_pose(payload: bytes, version: int = VERSION) -> Pose:
    if len(payload) < POSE_COUNTS.size:
        raise DatagramError(f"POSE payload is {len(payload)} bytes, shorter than its counts")
    n_seg, n_ang = POSE_COUNTS.unpack_from(payload)
    expected = POSE_COUNTS.size + 16 * n_seg + 4 * n_ang
    extensions = {}
    if version >= EXTENSIONS_SINCE and len(payload) >= expected:  # blocks after the angles
        extensions = _decode_extensions(payload[expected:])
        payload = payload[:expected]
    if len(payload) != expected:
        raise DatagramError(f"POSE payload is {len(payload)} bytes, its counts "
                            f"({n_seg} segments, {n_ang} angles) need {expected}")
    q = np.frombuffer(payload, ">f4", 4 * n_seg, POSE_COUNTS.size).reshape(n_seg, 4)
    a = np.frombuffer(payload, ">f4", n_ang, POSE_COUNTS.size + 16 * n_seg)
    mask = extensions.get("valid")
    ok = np.ones(n_seg, dtype=bool) if mask is None else mask_flags(mask, n_seg)
    # NaN marks what has no data, and only with the validity block (tag 4); never infinity
    nan_allowed = mask is not None
    positions = extensions.get("positions")
    if not (np.isfinite(q[ok]).all() and not np.isinf(a).any()
            and (nan_allowed or (np.isfinite(a).all()
                                 and (positions is None or np.isfinite(positions).all())))):
        raise DatagramError("POSE holds NaN or infinite values")
    with np.errstate(over="ignore"):
        norms = np.sqrt(np.sum(q.astype(np.float64) ** 2, axis=1))
    bad = np.flatnonzero(ok & (np.abs(norms - 1.0) > QUAT_NORM_TOLERANCE))
    if bad.size:
        raise DatagramError(f"POSE quaternion {bad[0]} is not a unit quaternion "
                            f"(norm {norms[bad[0]]:.4g})")
    q = q.astype(np.float32)
    q[~ok] = np.nan  # a segment without data: whatever was written, no value
    return Pose(q, a.astype(np.float32), **extensions)


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
    sender = epoch = 0
    if version >= 3:
        if len(data) < HEADER_V3_SIZE:
            raise DatagramError(f"{len(data)} bytes, shorter than the {HEADER_V3_SIZE}-byte "
                                "version 3 header")
        sender, epoch = FRESHNESS.unpack_from(data, HEADER_SIZE)
    payload = data[header_size(version):]
    frame = pose = zero = None
    if mtype == MessageType.RAW_FRAME:
        if len(payload) != FRAME_SIZE:
            raise DatagramError(f"RAW_FRAME payload is {len(payload)} bytes, not {FRAME_SIZE}")
        if not is_frame(payload):
            raise DatagramError("RAW_FRAME payload lacks the $#/#$ frame markers")
        frame = payload
    elif mtype == MessageType.POSE:
        pose = _decode_pose(payload, version)
    elif mtype == MessageType.ZERO and version >= ZERO_SINCE:
        zero = _decode_zero(payload)
    else:
        raise DatagramError(f"unknown message type {mtype}")
    return Datagram(MessageType(mtype), flags, session, seq, suit_time, send_time, frame, pose,
                    version, zero, sender, epoch)
