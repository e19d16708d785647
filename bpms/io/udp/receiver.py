"""The receiver: :class:`UdpSource` listens for BPMS datagrams and yields raw frames
(docs/udp.md "Receiver"). Nothing a peer sends can raise here. Thread-safe: any thread may
read stats or close. Which sender it follows is the gate's decision (:mod:`bpms.io.udp.gate`:
no takeover of a live session, freshness with a key); the accounting within the followed
session is the tracker's (:mod:`bpms.io.udp.sequence`)."""

from __future__ import annotations

import contextlib
import logging
import math
import select
import socket
import threading
import time
import zlib
from collections import OrderedDict
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

from bpms.io.closing import Closing
from bpms.io.udp.addresses import DEFAULT_PORT, UdpConfigError, is_multicast, parse_address
from bpms.io.udp.auth import split_tag, tag_is_valid
from bpms.io.udp.codec import (
    MAX_DATAGRAM,
    DatagramError,
    MessageType,
    ZeroMessage,
    decode_datagram,
)
from bpms.io.udp.gate import (
    TAKEOVER_AFTER_S,
    TAKEOVER_DATAGRAMS,
    Admission,
    SessionGate,
    SessionKey,
)
from bpms.io.udp.ratelog import RateLimitedLog
from bpms.io.udp.sequence import REORDER_WINDOW, SequenceTracker, Verdict

log = logging.getLogger(__name__)

#: Receiver's sanity range of header times: suit time, s (≈ 3 years of frames) and send
#: time, s since the epoch (1970 .. 2286). Outside: a malformed datagram.
MAX_SUIT_TIME_S = 1e8
MAX_SEND_TIME_S = 1e10
#: "another sender", "another sender on this session" and a takeover show this long, s.
FOREIGN_SHOWN_S = 5.0
TAKEOVER_SHOWN_S = 10.0


@dataclass(frozen=True)
class SourceStats:
    """Counters of a :class:`UdpSource` (semantics in docs/udp.md).

    ``datagrams = received + zeros + malformed + ignored + stale + foreign + unauthenticated +
    replayed``; ``received = delivered + duplicated + implausible`` (RAW_FRAME datagrams of
    the sessions followed); ``reordered`` ⊂ ``delivered``; ``lost`` = sequence numbers never
    received between the first and the highest of each session, plausible gaps only
    (``pending`` of them may still arrive late); ``conflicts``: evidence of another sender on
    the followed session (a number received again with a different frame, or far too late).
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
    replayed: int = 0  # keyed: older than the newest epoch followed for their sender: refused
    implausible: int = 0  # sequence numbers jumped implausibly far: dropped, not counted lost
    jumps: int = 0  # such jumps confirmed by JUMP_CONFIRM consecutive datagrams
    conflicts: int = 0  # datagrams contradicting the followed session (another sender on it)
    same_session_sender: str = ""  # "host:port" of the last conflicting datagram, while recent
    takeover: str = ""  # the last takeover, in words, while recent
    zeros: int = 0  # ZERO datagrams of the session followed (the sender's Reset Zero)
    takeovers: int = 0  # switches of the session followed (takeovers and returns)
    #: "host:port" of a replaced session whose datagrams were dropped, while recent
    stale_sender: str = ""
    #: the last datagram refused for its trust (replayed, unauthenticated), in words, while
    #: recent: "replayed from host:port"
    refused_recently: str = ""

    #: The reasons a datagram is refused or dropped, in the order shown.
    REJECTIONS = ("malformed", "unauthenticated", "replayed", "foreign", "stale", "implausible",
                  "duplicated", "conflicts")

    def rejections(self) -> dict[str, int]:
        """The datagrams refused or dropped so far, by reason (those with a count only)."""
        return {k: getattr(self, k) for k in self.REJECTIONS if getattr(self, k)}


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
    #: the first frame of a session followed from here (the first, a takeover, a confirmed
    #: jump): what came before does not continue into it
    restart: bool = False


class UdpSource(Closing):
    """Receives BPMS datagrams on ``listen`` (``"host:port"``), optionally joining an IPv4
    ``multicast_group`` (on ``multicast_interface``, default any), and yields raw frames.

    ``read(timeout)`` returns the next frame, or None after ``timeout`` s or once closed;
    iterating yields frames until :meth:`close`, which any thread may call and which wakes a
    blocked reader at once. Duplicates and datagrams of a replaced session are dropped;
    reordered frames are delivered (flagged) in arrival order. Malformed datagrams (including
    times outside the sanity range) are counted and logged at most once per second with the
    reason. Nothing a peer sends can raise here.

    One sender at a time (:class:`bpms.io.udp.gate.SessionGate`): while the followed session
    streams, datagrams of another session are dropped and counted (``stats.foreign``,
    ``stats.another_sender``); a newcomer takes over only once the followed session has been
    silent for ``takeover_after_s`` (5 s) and the newcomer has sent ``takeover_datagrams``
    (25) consecutive datagrams; takeovers are logged and shown (``stats.takeover``).
    ``key``: the shared key; datagrams without a valid HMAC-SHA256 tag are then refused and
    counted (``stats.unauthenticated``), so are datagrams before version 3 (they carry no
    freshness), and a run older than the newest one followed from the same sender is refused
    as replayed (``stats.replayed``).
    """

    def __init__(self, listen: str = f"0.0.0.0:{DEFAULT_PORT}",
                 multicast_group: str | None = None, *, multicast_interface: str = "0.0.0.0",
                 rcvbuf: int | None = 1 << 22, poll_s: float = 0.5,
                 window: int = REORDER_WINDOW, takeover_after_s: float = TAKEOVER_AFTER_S,
                 takeover_datagrams: int = TAKEOVER_DATAGRAMS,
                 key: bytes | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        host, port = parse_address(listen)
        self.poll_s = poll_s
        self.takeover_after_s = takeover_after_s
        self.key = key or None
        #: monotonic seconds for the takeover rule and what the status shows (tests inject one)
        self.clock = clock
        self._gate = SessionGate(takeover_after_s, takeover_datagrams, keyed=self.key is not None)
        self._last_foreign = self._last_conflict = self._last_stale = -math.inf
        self._last_refused, self._refused = -math.inf, ""
        self._foreign_sender = self._conflict_sender = self._stale_sender = ""
        self._stale_log = RateLimitedLog(log, 5.0)
        #: per session: the highest ZERO number taken (an older or repeated one never is)
        self._zero_top: OrderedDict[SessionKey, int] = OrderedDict()
        self._foreign_log = RateLimitedLog(log, 5.0)
        self._auth_log = RateLimitedLog(log, 5.0)
        self._replay_log = RateLimitedLog(log, 5.0)
        self._conflict_log = RateLimitedLog(log, 5.0)
        self._lock = threading.Lock()
        self._read_lock = threading.Lock()
        self._tracker = SequenceTracker(window, keyed=self.key is not None)
        self._counts = {"datagrams": 0, "malformed": 0, "ignored": 0, "socket_errors": 0,
                        "foreign": 0, "unauthenticated": 0, "replayed": 0, "stale": 0,
                        "zeros": 0}
        #: the followed session's latest Reset Zero not yet taken: (suit time s, the zero)
        self._zero: tuple[float, ZeroMessage] | None = None
        self._zero_seen: tuple | None = None
        self._last_malformed = ""
        self._started = False
        self._conflicts_seen = 0
        self._malformed_log = RateLimitedLog(log)
        self._error_log = RateLimitedLog(log)
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
            c = dict(self._counts)  # datagrams, malformed, ignored, socket errors, ... as kept
            c["replayed"] += t.replayed
            now = self.clock()
            return SourceStats(
                received=t.unique + t.duplicated + t.implausible, delivered=t.unique,
                lost=t.lost, pending=t.pending, duplicated=t.duplicated, reordered=t.reordered,
                stale=t.stale + c.pop("stale"), restarts=t.restarts,
                last_malformed=self._last_malformed,
                another_sender=self._recent(self._foreign_sender, self._last_foreign, now),
                implausible=t.implausible, jumps=t.jumps, conflicts=t.conflicts,
                same_session_sender=self._recent(self._conflict_sender, self._last_conflict,
                                                 now),
                takeover=self._takeover_text(now), takeovers=self._gate.takeovers,
                stale_sender=self._recent(self._stale_sender, self._last_stale, now),
                refused_recently=self._recent(self._refused, self._last_refused, now), **c)

    @staticmethod
    def _recent(text: str, at: float, now: float) -> str:
        return text if now - at < FOREIGN_SHOWN_S else ""

    def _takeover_text(self, now: float) -> str:
        last = self._gate.last_takeover
        if last is None or now - last.at >= TAKEOVER_SHOWN_S:
            return ""
        if last.returned:
            return (f"sender changed: session {last.new} came back and replaced {last.old} "
                    "(the session it had replaced)")
        why = ("a newer run of the same sender" if last.newer_run
               else f"after {last.silent_s:.1f} s of silence")
        return f"sender changed: session {last.new} replaced {last.old} ({why})"

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

    @property
    def followed(self) -> SessionKey | None:
        """The session followed (None before the first datagram)."""
        with self._lock:
            return self._gate.active

    def _malformed(self, sender: tuple[str, int], why: object) -> None:
        self._counts["malformed"] += 1
        self._last_malformed = f"{sender[0]}:{sender[1]}: {why}"
        self._malformed_log.warn("malformed UDP datagram from %s:%s ignored: %s",
                                 sender[0], sender[1], why)

    def _handle(self, data: bytes, sender: tuple[str, int]) -> ReceivedFrame | None:
        recv_time = time.time()
        now = self.clock()
        with self._lock:
            self._counts["datagrams"] += 1
            body, tag = split_tag(data)
            if self.key is not None and not tag_is_valid(body, tag, self.key):
                self._counts["unauthenticated"] += 1
                self._note_refused("unauthenticated", sender, now)
                self._auth_log.warn("UDP datagram from %s:%s refused: %s", sender[0],
                                    sender[1], "no shared-key tag" if tag is None
                                    else "wrong shared-key tag")
                return None
            try:
                dg = decode_datagram(body)
            except DatagramError as exc:
                self._malformed(sender, exc)
                return None
            if self.key is not None and dg.version < 3:
                self._counts["unauthenticated"] += 1
                self._note_refused("unauthenticated", sender, now)
                self._auth_log.warn("UDP datagram from %s:%s refused: format version %d "
                                    "carries no freshness (a shared key needs version 3)",
                                    sender[0], sender[1], dg.version)
                return None
            if not (0.0 <= dg.suit_time <= MAX_SUIT_TIME_S
                    and 0.0 <= dg.send_time <= MAX_SEND_TIME_S):
                self._malformed(sender, f"times out of range (suit {dg.suit_time:.6g} s, "
                                        f"send {dg.send_time:.6g} s)")
                return None
            if dg.type == MessageType.ZERO and dg.zero is not None and (
                    SessionKey(dg.session, dg.sender, dg.epoch) == self._gate.active):
                self._take_zero(dg, sender)
                return None
            if dg.type != MessageType.RAW_FRAME:
                self._counts["ignored"] += 1
                return None
            assert dg.frame is not None
            verdict = self._account(dg, sender, now)
        if verdict is None or verdict in (Verdict.DUPLICATE, Verdict.STALE, Verdict.REPLAYED,
                                          Verdict.IMPLAUSIBLE, Verdict.CONFLICT):
            return None
        restart = verdict is Verdict.RESYNC or self._started
        return ReceivedFrame(dg.frame, dg.seq, dg.session, dg.suit_time, dg.send_time,
                             recv_time, verdict == Verdict.REORDERED, sender, restart)

    def _account(self, dg, sender: tuple[str, int], now: float) -> Verdict | None:
        """The gate's and the tracker's verdict on one RAW_FRAME datagram (lock held); None:
        dropped by the gate (foreign, stale, replayed)."""
        key = SessionKey(dg.session, dg.sender, dg.epoch)
        who = f"{sender[0]}:{sender[1]}"
        admission = self._gate.admit(key, dg.seq, now)
        self._started = admission in (Admission.FIRST, Admission.TAKEOVER, Admission.RETURN)
        if admission is Admission.FOREIGN:
            self._counts["foreign"] += 1
            self._foreign_sender, self._last_foreign = who, now
            self._foreign_log.warn("UDP datagrams of another sender (%s, session %s) ignored "
                                   "while session %s streams", who, key, self._gate.active)
            return None
        if admission is Admission.STALE:
            self._counts["stale"] += 1
            self._stale_sender, self._last_stale = who, now
            self._stale_log.warn("UDP datagrams of replaced session %s (%s) dropped while "
                                 "session %s is followed", key, who, self._gate.active)
            return None
        if admission is Admission.REPLAYED:
            self._counts["replayed"] += 1
            self._note_refused("replayed", sender, now)
            self._replay_log.warn("UDP datagram from %s refused as replayed: session %s is "
                                  "older than the newest run followed from its sender, or "
                                  "number %d was followed already", who, key, dg.seq)
            return None
        if admission in (Admission.TAKEOVER, Admission.RETURN):
            log.warning("UDP: %s", self._takeover_text(now))
        verdict = self._tracker.observe(key, dg.seq, zlib.crc32(dg.frame),
                                        switch=self._started)
        if verdict is Verdict.RESYNC:
            self._gate.followed_to(key, dg.seq)
        if verdict is Verdict.REPLAYED:
            self._note_refused("replayed", sender, now)
            self._replay_log.warn("UDP datagram from %s refused as replayed: number %d of "
                                  "session %s is older than the stream followed", who, dg.seq,
                                  key)
        if verdict is Verdict.CONFLICT or (verdict is Verdict.REORDERED
                                           and self._tracker.conflicts > self._conflicts_seen):
            self._conflict_sender, self._last_conflict = who, now
            self._conflict_log.warn("UDP: another sender on session %s (%s): its sequence "
                                    "numbers contradict the stream", key, who)
        self._conflicts_seen = self._tracker.conflicts
        return verdict

    def _note_refused(self, why: str, sender: tuple[str, int], now: float) -> None:
        self._refused, self._last_refused = f"{why} from {sender[0]}:{sender[1]}", now

    def _take_zero(self, dg, sender: tuple[str, int]) -> None:
        """A ZERO of the session followed (lock held): taken when its number is above every
        ZERO number taken from that session (sent again every second: taken once); an older
        or repeated one is refused as replayed, so a Reset Zero is never applied twice."""
        key = SessionKey(dg.session, dg.sender, dg.epoch)
        top = self._zero_top.get(key)
        if top is not None and not 0 < (dg.seq - top) % (1 << 32) < 1 << 31:
            self._counts["replayed"] += 1
            self._note_refused("replayed", sender, self.clock())
            self._replay_log.warn("UDP ZERO datagram from %s:%s refused as replayed: number %d "
                                  "of session %s is not newer than the last one taken",
                                  sender[0], sender[1], dg.seq, key)
            return None
        self._zero_top[key] = dg.seq
        self._zero_top.move_to_end(key)
        while len(self._zero_top) > 16:
            self._zero_top.popitem(last=False)
        self._counts["zeros"] += 1
        seen = (dg.session, dg.suit_time, dg.zero.source, dg.zero.yaw0)
        if seen != self._zero_seen:  # (sent again every second: taken once)
            self._zero_seen = seen
            self._zero = (dg.suit_time, dg.zero)
        return None

    def take_zero(self) -> tuple[float, ZeroMessage] | None:
        """The followed sender's newest Reset Zero (its capture's suit time s, the zero), once:
        None when there is none new."""
        with self._lock:
            zero, self._zero = self._zero, None
            return zero

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
