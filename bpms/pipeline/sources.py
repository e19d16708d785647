"""Frame sources for the pipeline, besides :class:`bpms.io.replay.ReplaySource`:
the UDP client (:class:`UdpFrameSource`) and the suit link (:class:`SuitFrameSource`)."""

from __future__ import annotations

import contextlib
import logging
import time

from bpms.io.events import FrameEvent, SourceStatus
from bpms.io.link import LinkError, SuitLink, discover_suit
from bpms.io.options import SerialOptions
from bpms.io.udp import UdpSource

log = logging.getLogger(__name__)


class UdpFrameSource:
    """Raw frames received from a BPMS UDP forwarder (docs/udp.md UDP client mode).

    Frame indices come from the sender's suit time, so filtered files written here line up with
    the sender's. A new sender session (restart) is a discontinuity: the filters re-initialise.
    """

    def __init__(self, listen: str, multicast_group: str | None = None) -> None:
        self.udp = UdpSource(listen, multicast_group)
        self._session: int | None = None
        self._state = "connecting"

    def read(self, timeout: float = 0.1) -> list[FrameEvent]:
        out: list[FrameEvent] = []
        received = self.udp.read(timeout)
        while received is not None:
            new_session = received.session != self._session
            self._session = received.session
            index = round(received.suit_time / 0.02)
            out.append(FrameEvent(received.recv_time, received.frame, index, new_session))
            self._state = "streaming"
            if len(out) >= 256:
                break
            received = self.udp.read(0.0)
        return out

    def status(self) -> SourceStatus:
        s = self.udp.stats
        host, port = self.udp.address
        return SourceStatus(
            f"UDP {host}:{port}" + (f" group {self.udp.multicast_group}"
                                    if self.udp.multicast_group else ""),
            "closed" if self.udp.closed else self._state,
            counters={"lost": s.lost, "duplicated": s.duplicated, "reordered": s.reordered,
                      "malformed": s.malformed, "restarts": s.restarts})

    def close(self) -> None:
        self.udp.close()


class SuitFrameSource:
    """The suit over serial/Bluetooth (docs/suit.md) as a pipeline source, with a watchdog.

    Connecting: discover the suit when no port is given, read the battery, start the stream
    (``SuitLink.start`` drops the stale first frame). The first frame after every (re)start
    carries ``discontinuity``, so the filters re-initialise while Reset Zero stays in force.

    Watchdog: a Bluetooth link that leaves range often raises nothing — reads just time out.
    After ``serial.link_lost_after_s`` without a byte the state becomes "link lost" and the
    port is kept listening, so a suit that comes back streaming is picked up at once; every
    ``retry_s`` of further silence the stream is restarted (identify + start), which brings
    back a suit that was switched off and on. A read error (the device vanished) closes the
    port and reopens it every ``retry_s``. Everything already recorded stays recorded.
    """

    def __init__(self, port: str | None = None, serial: SerialOptions | None = None, *,
                 retry_s: float = 1.0) -> None:
        self.port = port
        self.serial = serial or SerialOptions()
        self.retry_s = retry_s
        self._link: SuitLink | None = None
        self._state = "connecting"
        self._reason = ""
        self._battery: float | None = None
        self._count = 0
        self._discontinuity = True
        self._last_data = time.monotonic()
        self._next_attempt = 0.0
        self._old_resyncs = 0
        self._old_discarded = 0
        self.connections = 0
        self.links_lost = 0
        self._closed = False
        self._want_stream = True  # Start/Stop Data; applied by read() (the acquisition thread)

    @property
    def connected_port(self) -> str | None:
        return self._link.port if self._link is not None else None

    @property
    def reason(self) -> str:
        """Why the link is not streaming (empty while it is)."""
        return self._reason

    def connect(self) -> None:
        """Open the port (discovering it when none was given) and start the stream.
        Raises LinkError with a one-line reason."""
        timeout = self.serial.discovery_timeout_s
        port = self.port or discover_suit(None, timeout, self.serial.baud)
        if port is None:
            raise LinkError("no suit answered on any serial port (is it paired, switched on, "
                            "charged?)")
        link = SuitLink(port, self.serial.baud, self.serial.read_timeout_s, timeout)
        try:
            link.identify()
            try:
                self._battery = link.battery_volts()
            except LinkError as exc:
                log.info("battery not read: %s", exc)
            if self._want_stream:
                link.start()
        except LinkError:
            link.close()
            raise
        self._link = link
        self.connections += 1
        self._streaming_again("suit link on " + port)

    def _streaming_again(self, message: str) -> None:
        if self._state == "link lost":
            log.warning("%s: streaming again", message)
        self._state = "streaming" if self._want_stream else "stopped"
        self._reason = ""
        self._discontinuity = True
        self._last_data = time.monotonic()

    def _lost(self, reason: str) -> None:
        if self._state != "link lost":
            self.links_lost += 1
            log.warning("suit link lost: %s", reason)
        self._state = "link lost"
        self._reason = reason
        self._next_attempt = time.monotonic() + self.retry_s

    def _close_link(self) -> None:
        link, self._link = self._link, None
        if link is not None:
            self._old_resyncs += link.parser.stats.resyncs
            self._old_discarded += link.parser.stats.discarded_bytes
            link.close()

    def stop_stream(self) -> None:
        """Stop Data: the suit stops streaming (frames already sent still arrive); the link
        stays open and the watchdog rests. Safe from any thread."""
        self._want_stream = False

    def start_stream(self) -> None:
        """Start Data again: restart the stream (its stale first frame dropped)."""
        self._want_stream = True

    def _apply_stream_request(self, link: SuitLink) -> None:
        if self._want_stream and not link.streaming and self._state != "link lost":
            link.start()
            self._streaming_again("Start Data")
        elif not self._want_stream and link.streaming:
            link.send_stop()
            self._state = "stopped"

    def read(self, timeout: float = 0.1) -> list[FrameEvent]:
        if self._closed:
            return []
        now = time.monotonic()
        if self._link is None:
            if now < self._next_attempt or not self._want_stream:
                time.sleep(max(0.0, min(timeout, self._next_attempt - now)) or timeout)
                return []
            try:
                self.connect()
            except LinkError as exc:
                self._reason = str(exc)
                self._next_attempt = time.monotonic() + self.retry_s
                return []
        link = self._link
        assert link is not None
        try:
            self._apply_stream_request(link)
            frames = link.read_frames(timeout)
            now = time.monotonic()
            if not frames and self._want_stream:
                silent = now - self._last_data
                if self._state != "link lost" and silent > self.serial.link_lost_after_s:
                    self._lost(f"no data for {silent:.1f} s")
                elif self._state == "link lost" and now >= self._next_attempt:
                    self._next_attempt = now + self.retry_s
                    link.identify(keep_frames=True)  # LinkError while the suit is away
                    link.start()
                    self._streaming_again(f"suit on {link.port} answered")
        except LinkError as exc:
            if self._closed:  # closing the port under a read is not a lost link
                return []
            away = "did not answer" in str(exc) or "no frame" in str(exc)
            if self._state == "link lost" and away:
                self._reason = str(exc)  # still away (or back and streaming): keep listening
                return []
            self._lost(str(exc))
            self._close_link()
            return []
        if not frames:
            return []
        if self._state == "link lost":
            self._streaming_again(f"suit on {link.port} is back")
        self._last_data = now
        host_time = time.time()
        events = []
        for frame in frames:
            events.append(FrameEvent(host_time, frame, self._count, self._discontinuity))
            self._discontinuity = False
            self._count += 1
        return events

    def status(self) -> SourceStatus:
        link = self._link
        resyncs, discarded = self._old_resyncs, self._old_discarded
        if link is not None:
            resyncs += link.parser.stats.resyncs
            discarded += link.parser.stats.discarded_bytes
        where = link.port if link is not None else (self.port or "discovery")
        return SourceStatus(f"suit {where}", "closed" if self._closed else self._state,
                            battery_v=self._battery, resyncs=resyncs, discarded_bytes=discarded,
                            counters={"connections": self.connections,
                                      "links_lost": self.links_lost})

    def close(self) -> None:
        """Stop the stream (best effort) and close the port."""
        self._closed = True
        link, self._link = self._link, None
        if link is not None:
            with contextlib.suppress(LinkError):
                link.send_stop()
            link.close()
