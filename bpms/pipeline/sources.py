"""Frame sources for the pipeline, besides :class:`bpms.io.replay.ReplaySource`:
the UDP client (:class:`UdpFrameSource`) and the suit link (:class:`SuitFrameSource`)."""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable

from bpms.io.event_types import ResetZero
from bpms.io.events import FrameEvent, SourceStatus
from bpms.io.link import (
    CMD_IDENTIFY,
    DeviceGoneError,
    LinkClosedError,
    LinkError,
    SuitLink,
    Transport,
    discover_suit,
)
from bpms.io.link_states import LOST_STATES, LinkEvent, LinkState, next_state
from bpms.io.options import SerialOptions
from bpms.io.session_events import SessionEvent
from bpms.io.timebase import frame_at
from bpms.io.udp.auth import key_from_env
from bpms.io.udp.gate import TAKEOVER_AFTER_S
from bpms.io.udp.receiver import UdpSource

log = logging.getLogger(__name__)

#: Frames this long after Stop Data mean the suit did not hear it: it is told again, s.
STOP_REPEAT_S = 0.5


class UdpFrameSource:
    """Raw frames received from a BPMS UDP forwarder (docs/udp.md UDP client mode).

    Frame indices come from the sender's suit time, so filtered files written here line up with
    the sender's. A new sender session (restart, takeover) is a discontinuity: the filters
    re-initialise. ``key``: the shared UDP key (default: the ``BPMS_UDP_KEY`` environment
    variable); ``takeover_after_s``: the option ``udp.takeover_after_s`` (docs/udp.md "One
    sender at a time"). The status' ``warning`` says when another sender is on this port
    (ignored), when another sender is on *this session* (its datagrams contradict the stream;
    possible without a key), and for a while after the sender changed.
    """

    def __init__(self, listen: str, multicast_group: str | None = None, *,
                 key: bytes | None = None, silent_after_s: float = 1.0,
                 takeover_after_s: float = TAKEOVER_AFTER_S) -> None:
        self.udp = UdpSource(listen, multicast_group, takeover_after_s=takeover_after_s,
                             key=key if key is not None else key_from_env())
        self.silent_after_s = silent_after_s
        self._state = "connecting"
        self._last_frame = time.monotonic()

    def read(self, timeout: float = 0.1) -> list[FrameEvent]:
        out: list[FrameEvent] = []
        received = self.udp.read(timeout)
        while received is not None:
            # the receiver keeps suit times within 0..1e8 s, so this is a sane integer
            index = frame_at(received.suit_time)
            out.append(FrameEvent(received.recv_time, received.frame, index, received.restart,
                                  marks=self._sender_zero() if not out else ()))
            self._state = "streaming"
            if len(out) >= 256:
                break
            received = self.udp.read(0.0)
        now = time.monotonic()
        if out:
            self._last_frame = now
        elif self._state == "streaming" and now - self._last_frame > self.silent_after_s:
            self._state = "silent"
        return out

    def _sender_zero(self) -> tuple:
        """The sender's newest Reset Zero, as a mark on the next frame: the session adopts it
        (docs/udp.md "ZERO"), unless its user pressed their own."""
        taken = self.udp.take_zero()
        if taken is None:
            return ()
        suit_time, zero = taken
        try:
            change = ResetZero("network", max(1, int(zero.window)), zero.R0, zero.yaw0,
                               zero.heading, adopt=True, sender_source=zero.source)
        except ValueError as exc:  # (the receiver checked it: never expected)
            log.warning("the sender's Reset Zero is not used: %s", exc)
            return ()
        return (SessionEvent.of(change, frame_at(suit_time)),)

    def status(self) -> SourceStatus:
        s = self.udp.stats
        warnings = []
        if s.same_session_sender:
            warnings.append(f"another sender on this session ({s.same_session_sender}; "
                            f"{s.conflicts} conflicting datagrams): frames may be forged")
        if s.another_sender:
            warnings.append(f"another sender ({s.another_sender}) on this port: ignored")
        if s.stale_sender:
            warnings.append(f"datagrams of a replaced sender ({s.stale_sender}) dropped: "
                            f"{s.stale} in all")
        if s.refused_recently:
            warnings.append(f"datagrams refused ({s.refused_recently}; replayed {s.replayed}, "
                            f"unauthenticated {s.unauthenticated})")
        if s.takeover:
            warnings.append(s.takeover)
        return SourceStatus(
            f"UDP on {self.udp.listening}",
            "closed" if self.udp.closed else self._state,
            counters={k: getattr(s, k) for k in (
                "lost", "duplicated", "reordered", "malformed", "restarts", "foreign",
                "unauthenticated", "replayed", "implausible", "conflicts", "stale",
                "takeovers")},
            warning="; ".join(warnings))

    def close(self) -> None:
        self.udp.close()


class SuitFrameSource:
    """The suit over serial/Bluetooth (docs/suit.md) as a pipeline source, driven by the link state
    machine of :mod:`bpms.io.link_states` (states, events and the one transition function).

    Connecting: discover the suit when no port is given, read the battery, start the stream
    (``SuitLink.start`` drops the stale first frame). The first frame after every (re)start
    carries ``discontinuity``, so the filters re-initialise while Reset Zero stays in force.

    Watchdog: a Bluetooth link that leaves range often raises nothing: reads just time out.
    After ``serial.link_lost_after_s`` without a byte the state becomes *silent* and the port
    keeps listening, so a suit that comes back streaming is taken at once; every ``retry_s``
    of further silence the suit is probed and, when it answers ``BPMS`` (it was switched off
    and on), the stream is restarted. A read or write error (device removed, TCP connection
    dropped) makes it *gone*: the port is closed and reopened every ``retry_s``. Everything
    already received stays received.

    ``simulated``: the source is the simulated suit (status says SIMULATED). ``opener``
    (port, baud) → :class:`Transport` and ``clock`` / ``sleep`` replace the real port and
    time in tests. :meth:`read` runs on one (acquisition) thread; :meth:`close`,
    :meth:`stop_stream`, :meth:`start_stream` and :meth:`status` are safe from any thread.
    """

    def __init__(self, port: str | None = None, serial: SerialOptions | None = None, *,
                 retry_s: float = 1.0, simulated: bool = False,
                 opener: Callable[[str, int], Transport] | None = None,
                 clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], object] | None = None) -> None:
        self.port = port
        self.serial = serial or SerialOptions()
        self.retry_s = retry_s
        self.simulated = simulated
        self._opener = opener
        self._clock = clock
        self._wake = threading.Event()
        self._sleep = sleep or self._wake.wait
        self._lock = threading.RLock()  # guards state and link changes
        self._link: SuitLink | None = None
        self._state = LinkState.CONNECTING
        self._reason = ""
        self._battery: float | None = None
        self._count = 0
        self._discontinuity = True
        self._last_data = clock()
        self._next_attempt = 0.0
        self._old_resyncs = 0
        self._old_discarded = 0
        self.connections = 0
        self.links_lost = 0
        self.restarts = 0  # streams restarted after a power-cycle or a reopened port
        # the last 64 transitions (frames while streaming left out)
        self.history: list[tuple[LinkState, LinkEvent, LinkState]] = []
        self._want_stream = True  # Start/Stop Data; applied by read() (the acquisition thread)
        self._stop_sent = 0.0

    # -- the one place where the state changes ----------------------------------------------
    def _event(self, event: LinkEvent, reason: str = "") -> LinkState:
        """Apply ``event``: the new state comes from :func:`next_state`; entering a state
        does its bookkeeping here and nowhere else."""
        with self._lock:
            old = self._state
            if old is LinkState.CLOSED:  # closed by another thread meanwhile: nothing to do
                return old
            new = next_state(old, event)
            self._state = new
            if new is not old or event is not LinkEvent.FRAMES:
                self.history = [*self.history, (old, event, new)][-64:]
            now = self._clock()
            if new is LinkState.STREAMING:
                self._reason = ""
                self._last_data = now
                if old is not LinkState.STREAMING:
                    self._discontinuity = True
                    if old in LOST_STATES:
                        log.warning("suit link %s: streaming again (%s)",
                                    self.connected_port or self.port, event.value)
            elif new in LOST_STATES or new is LinkState.CONNECTING:
                self._reason = reason or self._reason
                if old not in LOST_STATES and new is not LinkState.CONNECTING:
                    self.links_lost += 1
                    log.warning("suit link lost (%s): %s", new.value, reason)
                if new is LinkState.SILENT and old is not LinkState.SILENT:
                    self._next_attempt = now + self.retry_s
                if new in (LinkState.GONE, LinkState.CONNECTING):
                    self._next_attempt = now + self.retry_s
                    if new is LinkState.GONE:
                        self._close_link()
            elif new is LinkState.STOPPED:
                self._reason = ""
            elif new is LinkState.CLOSED:
                self._wake.set()
            return new

    @property
    def state(self) -> LinkState:
        return self._state

    @property
    def connected_port(self) -> str | None:
        link = self._link
        return link.port if link is not None else None

    @property
    def reason(self) -> str:
        """Why the link is not streaming (empty while it is)."""
        return self._reason

    # -- opening --------------------------------------------------------------------------
    def _open(self) -> SuitLink:
        """Open the port (discovering it when none was given), identify the suit, read the
        battery and start the stream when wanted. Raises LinkError."""
        timeout = self.serial.discovery_timeout_s
        port = self.port or discover_suit(None, timeout, self.serial.baud)
        if port is None:
            raise LinkError("no suit answered on any serial port (is it paired, switched on, "
                            "charged?)")
        transport = None
        if self._opener is not None:
            try:
                transport = self._opener(port, self.serial.baud)
            except OSError as exc:
                raise DeviceGoneError(f"cannot open {port}: {exc.strerror or exc}") from None
        link = SuitLink(port, self.serial.baud, self.serial.read_timeout_s, timeout,
                        transport=transport, clock=self._clock)
        try:
            link.identify()
            try:
                self._battery = link.battery_volts()
            except LinkError as exc:
                if isinstance(exc, DeviceGoneError):
                    raise
                log.info("battery not read: %s", exc)
            if self._want_stream:
                link.start()
        except LinkError:
            link.close()
            raise
        return link

    def _attach(self, link: SuitLink) -> None:
        with self._lock:
            if self._state is LinkState.CLOSED:
                link.close(CMD_IDENTIFY if link.streaming else b"")
                return
            self._link = link
            self.connections += 1
            if self.connections > 1:
                self.restarts += 1
            self._event(LinkEvent.OPENED if link.streaming else LinkEvent.OPENED_IDLE)

    def _open_in(self, state: LinkState) -> None:
        """Open and attach the link; a failure while still ``state`` is an OPEN_FAILED event
        (LinkError raised)."""
        try:
            link = self._open()
        except LinkError as exc:
            if self._state is state:
                self._event(LinkEvent.OPEN_FAILED, str(exc))
            raise
        self._attach(link)

    def connect(self) -> None:
        """Open the port (discovering it when none was given) and start the stream.
        Raises LinkError with a one-line reason (the source stays *connecting*)."""
        self._open_in(LinkState.CONNECTING)

    def _reopen(self) -> None:
        self._event(LinkEvent.RETRY)
        with contextlib.suppress(LinkError):
            self._open_in(LinkState.REOPENING)

    def _close_link(self) -> None:
        with self._lock:
            link, self._link = self._link, None
        if link is not None:
            self._old_resyncs += link.parser.stats.resyncs
            self._old_discarded += link.parser.stats.discarded_bytes
            link.close()

    # -- Start / Stop Data ----------------------------------------------------------------
    def stop_stream(self) -> None:
        """Stop Data: the suit stops streaming (frames already sent still arrive); the link
        stays open and the watchdog rests. Safe from any thread."""
        self._want_stream = False

    def start_stream(self) -> None:
        """Start Data again: restart the stream (its stale first frame dropped)."""
        self._want_stream = True

    def _apply_stream_request(self, link: SuitLink) -> None:
        state = self._state
        if self._want_stream and state is LinkState.STOPPED:
            try:
                link.start()
            except DeviceGoneError:
                raise
            except LinkError as exc:
                self._event(LinkEvent.START_FAILED, str(exc))
                return
            self._event(LinkEvent.START)
        elif not self._want_stream and state in (LinkState.STREAMING, LinkState.SILENT):
            link.send_stop()
            self._stop_sent = self._clock()
            self._event(LinkEvent.STOP)

    # -- the acquisition loop -------------------------------------------------------------
    def read(self, timeout: float = 0.1) -> list[FrameEvent]:
        state = self._state
        if state is LinkState.CLOSED:
            return []
        link = self._link
        if link is None:  # connecting or gone: (re)open when it is time
            now = self._clock()
            wait = self._next_attempt - now
            if wait > 0 or (not self._want_stream and state is LinkState.GONE):
                self._sleep(min(timeout, wait) if wait > 0 else timeout)
                return []
            if state is LinkState.GONE:
                self._reopen()
            else:
                with contextlib.suppress(LinkError):  # the reason is kept in the status
                    self.connect()
            return []
        gone: DeviceGoneError | None = None
        try:
            self._apply_stream_request(link)
            frames = link.read_frames(timeout)
            if not frames:
                self._watchdog(link)
                frames = link.read_frames(0.0) if link.streaming else []
        except LinkClosedError:
            return []
        except DeviceGoneError as exc:
            # frames that came before the end (read while a command waited) still count
            frames, gone = link.take_pending(), exc
        if gone is not None and not frames:
            self._gone(gone)
            return []
        if not frames:
            return []
        if (gone is None and self._state is LinkState.STOPPED
                and self._clock() - self._stop_sent > STOP_REPEAT_S):
            # Frames long after Stop Data: the suit did not hear it (it was out of range)
            try:
                link.send_stop()
            except LinkError as exc:
                log.info("Stop Data repeated: %s", exc)
            self._stop_sent = self._clock()
        with self._lock:
            if self._state is LinkState.CLOSED:
                return []
            self._event(LinkEvent.FRAMES)
            self._last_data = self._clock()
            host_time = time.time()
            events = []
            for frame in frames:
                events.append(FrameEvent(host_time, frame, self._count, self._discontinuity))
                self._discontinuity = False
                self._count += 1
        if gone is not None:
            self._gone(gone)
        return events

    def _gone(self, exc: DeviceGoneError) -> None:
        if self._state is not LinkState.CLOSED:
            self._event(LinkEvent.DEVICE_GONE, str(exc))

    def _watchdog(self, link: SuitLink) -> None:
        """No frame in this read: maybe the link went quiet, maybe it is time to probe."""
        state = self._state
        if not self._want_stream:
            return
        now = self._clock()
        if state is LinkState.STREAMING:
            silent = now - self._last_data
            if silent > self.serial.link_lost_after_s:
                self._event(LinkEvent.QUIET, f"no data for {silent:.1f} s")
        elif state is LinkState.SILENT and now >= self._next_attempt:
            self._next_attempt = now + self.retry_s
            try:
                if not link.probe():  # frames came: it streams again (read() delivers them)
                    return
                # It answered BPMS: power-cycled (idle), or our probe stopped its stream. Start
                # anew; frames of a stream the probe just stopped stay pending, in order.
                link.start()
            except (DeviceGoneError, LinkClosedError):
                raise
            except LinkError as exc:  # still away (no answer, or no frame after the start)
                self._event(LinkEvent.PROBE_UNANSWERED, f"{self._reason_base()}; {exc}")
                return
            self.restarts += 1
            self._event(LinkEvent.RESTARTED)

    def _reason_base(self) -> str:
        return self._reason.split(";")[0] or "silent"

    def status(self) -> SourceStatus:
        link = self._link
        resyncs, discarded = self._old_resyncs, self._old_discarded
        if link is not None:
            resyncs += link.parser.stats.resyncs
            discarded += link.parser.stats.discarded_bytes
        where = link.port if link is not None else (self.port or "discovery")
        prefix = "SIMULATED suit" if self.simulated else "suit"
        return SourceStatus(f"{prefix} {where}", self._state.value,
                            battery_v=self._battery, resyncs=resyncs, discarded_bytes=discarded,
                            counters={"connections": self.connections,
                                      "links_lost": self.links_lost,
                                      "restarts": self.restarts},
                            reason=self._reason, simulated=self.simulated)

    def close(self) -> None:
        """Stop the stream (best effort) and close the port. Safe from any thread: a read
        blocked on the port returns at once."""
        with self._lock:
            if self._state is LinkState.CLOSED:
                return
            self._event(LinkEvent.CLOSE)
            link, self._link = self._link, None
        if link is not None:
            link.close(CMD_IDENTIFY)
