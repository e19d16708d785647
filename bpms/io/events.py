"""What every frame source delivers: one :class:`FrameEvent` per accepted frame."""

from __future__ import annotations

from dataclasses import dataclass


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
    """

    host_time: float
    frame: bytes
    index: int = -1
    discontinuity: bool = False
    preroll: bytes = b""
