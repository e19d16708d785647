"""What every frame source delivers: one :class:`FrameEvent` per accepted frame."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Protocol


@dataclass(frozen=True, slots=True)
class FrameEvent:
    """One 340-byte frame as it entered the host.

    host_time: s since the Unix epoch, when it was received (or, on replay, recorded).
    index: position in the source (replay: frame index in the file; live: running count of
        accepted frames since the source opened).
    discontinuity: True on the first frame after a gap the filters must not bridge (stream
        start, seek, reconnection): the filters re-initialise on it.
    preroll: on replay after a seek, the frames just before the seek point (concatenated), to
        run the filters through without output so the pose is right at once.
    arrival: ``time.perf_counter()`` when the host took the frame in (latency measurements).
    marks: session events to apply just before this frame
        (:class:`bpms.io.session_events.SessionEvent`: a recording's events on replay, the
        sender's Reset Zero from a UDP stream).
    """

    host_time: float
    frame: bytes
    index: int = -1
    discontinuity: bool = False
    preroll: bytes = b""
    arrival: float = field(default_factory=time.perf_counter)
    marks: tuple = ()


@dataclass
class SourceStatus:
    """What a source says about itself (shown in the status line and the GUI)."""

    description: str
    # suit: connecting, streaming, silent, gone, reopening, stopped, closed
    # (bpms.io.link_states); UDP: connecting, streaming, silent, closed; replay: paused, ended
    state: str = "streaming"
    battery_v: float | None = None
    resyncs: int = 0
    discarded_bytes: int = 0
    position: int | None = None  # replay: next frame index
    length: int | None = None  # replay: frames in the file
    counters: dict[str, int] = field(default_factory=dict)  # source-specific (UDP lost, ...)
    reason: str = ""  # why the source is not streaming (empty while it is)
    simulated: bool = False  # the simulated suit: every status line must say SIMULATED
    warning: str = ""  # a condition to show prominently (UDP: another sender on the port)


class FrameSource(Protocol):
    """Anything the pipeline can read frames from (suit link, UDP client, raw-file replay)."""

    def read(self, timeout: float = 0.1) -> list[FrameEvent]:
        """Frames available now, waiting up to ``timeout`` s; [] when none."""
        ...

    def status(self) -> SourceStatus:
        ...

    def close(self) -> None:
        ...
