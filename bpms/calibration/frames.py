"""Raw readings from a frame source: :class:`bpms.io.events.FrameSource` events → raw counts."""

from __future__ import annotations

import numpy as np

from bpms.io.events import FrameSource
from bpms.io.frames import FRAME_SIZE, decode_frames


def poll_raw(source: FrameSource, timeout: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """The frames available now (waiting up to ``timeout`` s) as (raw ``int16 [n, 18, 9]``
    counts, errors ``bool [n, 18, 3]``); n may be 0."""
    events = source.read(timeout)
    data = b"".join(e.frame for e in events if len(e.frame) == FRAME_SIZE)
    if not data:
        return np.empty((0, 18, 9), np.int16), np.empty((0, 18, 3), bool)
    decoded = decode_frames(data)
    return decoded.raw, decoded.errors
