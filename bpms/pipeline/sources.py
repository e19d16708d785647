"""Frame sources for the pipeline, besides :class:`bpms.io.replay.ReplaySource`:
the UDP client (:class:`UdpFrameSource`) and the suit link (:class:`SuitFrameSource`)."""

from __future__ import annotations

from bpms.io.events import FrameEvent, SourceStatus
from bpms.io.udp import UdpSource


class UdpFrameSource:
    """Raw frames received from a BPMS UDP forwarder (SPEC §9 UDP client mode).

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
