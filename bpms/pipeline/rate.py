"""Average reception rate over a sliding window of arrival times."""

from __future__ import annotations

import time
from collections import deque


class RateMeter:
    """Frames per second over the last ``window_s`` seconds of arrivals (host monotonic
    clock). Bluetooth delivers bursts, so a window of several seconds gives the steady rate."""

    def __init__(self, window_s: float = 5.0) -> None:
        self.window_s = window_s
        self._times: deque[float] = deque()

    def mark(self, count: int = 1, now: float | None = None) -> None:
        now = time.monotonic() if now is None else now
        self._times.extend([now] * count)
        self._trim(now)

    def _trim(self, now: float) -> None:
        while self._times and now - self._times[0] > self.window_s:
            self._times.popleft()

    def rate_hz(self, now: float | None = None) -> float:
        """Frames/s in the window (0 when fewer than two arrivals or silent)."""
        now = time.monotonic() if now is None else now
        self._trim(now)
        if len(self._times) < 2:
            return 0.0
        span = max(now - self._times[0], self._times[-1] - self._times[0])
        return (len(self._times) - 1) / span if span > 0 else 0.0
