"""A warning logged at most once per interval, with the count of those it held back."""

from __future__ import annotations

import logging
import math
import time


class RateLimitedLog:
    """Logs a warning to ``log`` at most once per ``interval_s``, with the count of suppressed
    ones."""

    def __init__(self, log: logging.Logger, interval_s: float = 1.0) -> None:
        self.log = log
        self.interval_s = interval_s
        self._last = -math.inf
        self._suppressed = 0

    def warn(self, message: str, *args: object) -> None:
        now = time.monotonic()
        if now - self._last < self.interval_s:
            self._suppressed += 1
            return
        extra = f" ({self._suppressed} more since the last message)" if self._suppressed else ""
        self.log.warning(message + extra, *args)
        self._last = now
        self._suppressed = 0
