"""The sender: :class:`UdpForwarder` sends frames and poses to one or more targets
(docs/udp.md "Sender"). Thread-safe: any thread may send, read stats or close.

Every datagram is version 3: besides its session id it carries this computer's sender id and
the session's epoch (docs/udp.md "Freshness"), which a shared key signs with the rest."""

from __future__ import annotations

import errno
import hashlib
import logging
import os
import select
import socket
import threading
import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bpms.io.closing import Closing
from bpms.io.frames import FRAME_SIZE, is_frame
from bpms.io.timebase import stream_time
from bpms.io.udp.addresses import UdpConfigError, is_multicast, parse_address
from bpms.io.udp.auth import sign_datagram
from bpms.io.udp.codec import (
    SEQ_MOD,
    MessageType,
    ZeroMessage,
    encode_header,
    encode_pose_extensions,
    encode_pose_payload,
    encode_raw_frame,
    encode_zero,
)
from bpms.io.udp.ratelog import RateLimitedLog

log = logging.getLogger(__name__)
#: Longest a waiting forwarder (``wait=True``) waits for room in a socket buffer, s.
WAIT_S = 2.0


def new_session_id() -> int:
    """A random non-zero 32-bit session id."""
    return int.from_bytes(os.urandom(4), "big") or 1


def sender_id() -> int:
    """This computer's sender id: 64 bits of a hash of its network address and host name
    (the same for every run and process on it; the address itself is not sent)."""
    seed = f"bpms sender {uuid.getnode():012x} {socket.gethostname()}".encode()
    return int.from_bytes(hashlib.sha256(seed).digest()[:8], "big") or 1


_epoch_lock = threading.Lock()
_last_epoch = 0


def new_epoch() -> int:
    """The epoch of a new session: µs since 1970 on this computer's clock, and above every
    epoch handed out before in this process (two sessions never share one)."""
    global _last_epoch
    with _epoch_lock:
        _last_epoch = max(time.time_ns() // 1000, _last_epoch + 1)
        return _last_epoch


@dataclass(frozen=True)
class ForwarderStats:
    """Counters of a :class:`UdpForwarder`. ``sent``, ``errors`` and ``refused`` count
    datagrams (one per target and message); ``frames`` / ``poses`` count messages handed to
    ``send_*``. ``refused``: the target said nobody listens there (ECONNREFUSED), not an
    error of this computer; ``errors``: every other failed send. ``poses_sent``: those of
    ``sent`` that are POSE datagrams (the rest are RAW frames and ZERO messages)."""

    frames: int = 0
    poses: int = 0
    sent: int = 0
    errors: int = 0
    last_error: str = ""
    refused: int = 0
    poses_sent: int = 0


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
        self.log = RateLimitedLog(log)
        self.refused_said = False  # "nobody is listening" is said once per target


class UdpForwarder(Closing):
    """Sends every frame (and optionally poses) to one or more ``"host:port"`` targets.

    Unicast and IPv4 multicast (224.0.0.0/4: TTL ``multicast_ttl``, loopback ``multicast_loop``,
    outgoing interface ``multicast_interface`` or the system's default) and broadcast addresses.
    Sockets are non-blocking: a send never waits. A target where nobody listens (the other
    computer refuses the datagrams) is said once, at the first refusal, and counted in
    ``stats.refused``; any other failed send (full buffer, network down) is counted in
    ``stats.errors`` and logged at most once per second per target. Sequence numbers count per
    message type from 0 in a fresh random session; ``sender`` (this computer) and ``epoch``
    (the session's start, µs) go into every datagram.
    """

    def __init__(self, targets: Sequence[str], multicast_ttl: int = 1, *,
                 multicast_loop: bool = True, multicast_interface: str | None = None,
                 session: int | None = None, key: bytes | None = None,
                 wait: bool = False) -> None:
        self._key = key or None  # shared key: every datagram signed (docs/udp.md)
        #: a full socket buffer waits (up to WAIT_S) instead of failing: a recording played
        #: as fast as possible sends every datagram (a live stream never waits)
        self.wait = wait
        if isinstance(targets, str):
            targets = [targets]
        if not targets:
            raise UdpConfigError("no UDP target given (host:port)")
        self.session = new_session_id() if session is None else session & 0xFFFFFFFF
        self.sender = sender_id()
        self.epoch = new_epoch()
        self._targets: list[_Target] = []
        try:
            for text in targets:
                self._targets.append(_Target(text, multicast_ttl, multicast_loop,
                                             multicast_interface))
        except UdpConfigError:
            self.close()
            raise
        self._lock = threading.Lock()
        self._seq = {MessageType.RAW_FRAME: 0, MessageType.POSE: 0, MessageType.ZERO: 0}
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
            sent = errors = refused = 0
            last_error = self._stats.last_error
            for target in self._targets:
                try:
                    self._send_one(target, datagram)
                    sent += 1
                except ConnectionRefusedError:
                    refused += 1
                    if not target.refused_said:
                        target.refused_said = True
                        log.warning("UDP target %s: nobody is listening there (connection "
                                    "refused); sending on, counted as refused", target.text)
                except OSError as exc:
                    errors += 1
                    reason = (errno.errorcode.get(exc.errno or 0, "")
                              + f" {exc.strerror or exc}").strip()
                    last_error = f"{target.text}: {reason}"
                    target.log.warn("UDP send to %s failed: %s", target.text, reason)
            s = self._stats
            self._stats = ForwarderStats(
                s.frames + (mtype == MessageType.RAW_FRAME), s.poses + (mtype == MessageType.POSE),
                s.sent + sent, s.errors + errors, last_error, s.refused + refused,
                s.poses_sent + (sent if mtype == MessageType.POSE else 0))
            return sent

    def _send_one(self, target: _Target, datagram: bytes) -> None:
        try:
            target.sock.send(datagram)
        except BlockingIOError:
            if not self.wait:
                raise
            deadline = time.monotonic() + WAIT_S
            while True:  # the socket buffer is full: wait until it drains
                select.select([], [target.sock], [], max(0.0, deadline - time.monotonic()))
                try:
                    target.sock.send(datagram)
                    return
                except BlockingIOError:
                    if time.monotonic() >= deadline:
                        raise

    def send_frame(self, frame: bytes, suit_time: float | None = None) -> int:
        """Forward one 340-byte frame. ``suit_time`` defaults to its sequence number × 0.02 s.
        Returns the number of targets it was handed to. Raises ValueError on a non-frame."""
        if not is_frame(frame):
            raise ValueError(f"not a {FRAME_SIZE}-byte frame with $#/#$ markers")
        frame = bytes(frame)

        def build(seq: int) -> bytes:
            t = stream_time(seq) if suit_time is None else suit_time
            return encode_raw_frame(frame, session=self.session, seq=seq, suit_time=t,
                                    send_time=time.time(), sender=self.sender,
                                    epoch=self.epoch)

        return self._send(MessageType.RAW_FRAME, build)

    def send_pose(self, quaternions: np.ndarray, angles: np.ndarray, suit_time: float,
                  positions: np.ndarray | None = None, convention: str | None = None,
                  disturbance: tuple[np.ndarray, np.ndarray] | None = None,
                  valid: np.ndarray | None = None) -> int:
        """Forward one filtered pose: ``quaternions[18, 4]`` (w, x, y, z, body→NED) and
        ``angles[28]`` rad; with ``positions[21, 3]`` (m, NED), ``convention``,
        ``disturbance`` = (mag[18], acc[18]) bool flags and/or ``valid[18]`` bool (the segments
        with data: the others, and the angles and positions needing them, go as NaN with the
        validity block, docs/udp.md) a POSE carrying them (extension blocks). Raises
        ValueError on bad shapes, infinite values or NaN where ``valid`` does not allow it."""
        payload = encode_pose_payload(quaternions, angles, valid)
        if (positions is not None or convention or disturbance is not None
                or valid is not None):
            payload += encode_pose_extensions(positions, convention, disturbance, valid)

        def build(seq: int) -> bytes:
            return encode_header(MessageType.POSE, self.session, seq, suit_time, time.time(),
                                 sender=self.sender, epoch=self.epoch) + payload

        return self._send(MessageType.POSE, build)

    def send_zero(self, zero: ZeroMessage, suit_time: float) -> int:
        """Forward the Reset Zero in force (a ZERO datagram; ``suit_time``: its capture
        frame's). Raises ValueError on a malformed zero."""
        def build(seq: int) -> bytes:
            return encode_zero(zero, session=self.session, seq=seq, suit_time=suit_time,
                               send_time=time.time(), sender=self.sender, epoch=self.epoch)

        build(0)  # a malformed zero raises here, before a sequence number is used
        return self._send(MessageType.ZERO, build)

    def close(self) -> None:
        lock = getattr(self, "_lock", None)
        if lock is not None:
            with lock:
                self._closed = True
        for target in self._targets:
            target.sock.close()
