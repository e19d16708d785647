"""The one owner of a recording's time column.

Every frame of a stream has two times:

- **stream time**, s since the stream started, on the fixed filter clock: frame index × dt
  (dt = ``Options.filter.dt``, 0.02 s at 50 Hz). Filter results, exports and the filtered
  file's ``time_s`` column all come from :func:`stream_times`.
- **host time**, s since the epoch (UTC), when the host received the frame: the raw
  recording's ``time`` field, written beside stream time as ``host_time_s``.
"""

from __future__ import annotations

import math

import numpy as np

from bpms.io.frames import FRAME_PERIOD_S


def stream_times(first_index: int, n: int, dt: float) -> np.ndarray:
    """``[n]`` s: stream time of frames ``first_index .. first_index + n - 1``."""
    if n == 1:  # a live frame: the same number, without building a range
        return np.array([float(int(first_index)) * float(dt)])
    return (int(first_index) + np.arange(n, dtype=np.float64)) * float(dt)


def stream_time_of(indices: np.ndarray, dt: float) -> np.ndarray:
    """Stream time (s) of the given frame indices (negative indices count as 0)."""
    return np.maximum(np.asarray(indices, dtype=np.float64), 0.0) * float(dt)


def stream_time(index: int, dt: float = FRAME_PERIOD_S) -> float:
    """Stream time (s) of frame ``index`` (a negative index counts as 0)."""
    return max(int(index), 0) * float(dt)


def frame_at(seconds: float, dt: float = FRAME_PERIOD_S) -> int:
    """The frame index whose stream time is nearest ``seconds``."""
    return round(float(seconds) / float(dt))


#: The longest time an option or a recording may name, s (116 days: 5 × 10^8 frames at
#: 50 Hz). A time beyond it (``--from 1e308``) is refused, not turned into an infinite frame
#: index.
LONGEST_S = 1e7

#: The host times a clock can give, s since the epoch: 1970 up to 2^37 s (the year 6325).
#: Anything else in a file (1e308, a negative time) is damage or forgery, not a time.
LATEST_HOST_TIME = float(2 ** 37)


def plausible_host_time(seconds: float) -> bool:
    """Whether ``seconds`` (s since the epoch) is a time a host clock can have given."""
    try:
        return math.isfinite(seconds) and 0.0 <= seconds <= LATEST_HOST_TIME
    except TypeError:
        return False
