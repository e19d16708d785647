"""The raw recording's priority on disk space (docs/pipeline.md, "Recording").

While a raw file is written, the free space of its disk is checked five times a second. When it
falls below the reserve (option ``logging.disk_reserve_s``: seconds of raw data, 17.4 kB per
second), the filtered file stops first, with a note and a status field saying why; the raw
file goes on until the disk is truly full. The filtered file can always be made again from
the raw one (``bpms filter``); lost raw frames cannot.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable
from pathlib import Path

from bpms.io.frames import FRAME_PERIOD_S
from bpms.io.rawfile import RECORD_SIZE

#: Raw data per second of recording, bytes (50 records of 348 bytes).
RAW_BYTES_PER_S = RECORD_SIZE / FRAME_PERIOD_S


def _mb(n: float) -> str:
    return f"{n / 1e6:.2f} MB"


class DiskReserve:
    """Tells when the free space where ``folder`` lives drops below ``seconds`` of raw data.

    :meth:`low` asks the file system at most every ``check_every_s`` (cheap: one ``statvfs``);
    ``reason`` then says, in one line, how much is free and what the reserve is."""

    def __init__(self, folder: str | Path, seconds: float, check_every_s: float = 0.2,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.folder = Path(folder)
        self.reserve_bytes = max(0.0, seconds) * RAW_BYTES_PER_S
        self.check_every_s = check_every_s
        self._clock = clock
        self._next = -float("inf")
        self.free_bytes: int | None = None
        self.reason = ""

    def low(self, about_to_write: float = 0.0) -> bool:
        """True once the free space has been seen below the reserve (then for good).
        ``about_to_write``: bytes a writer other than the raw file is about to take; with it,
        the file system is asked now (not at the cadence) whether the reserve would still be
        free after them."""
        if self.reason or self.reserve_bytes <= 0:
            return bool(self.reason)
        now = self._clock()
        if now < self._next and not about_to_write:
            return False
        self._next = now + self.check_every_s
        try:
            self.free_bytes = shutil.disk_usage(self.folder).free
        except OSError:
            return False  # the raw writer reports a folder that has gone
        if self.free_bytes - about_to_write >= self.reserve_bytes:
            return False
        self.reason = (f"free disk space {_mb(self.free_bytes)} is below the "
                       f"{_mb(self.reserve_bytes)} kept for the raw recording "
                       f"(logging.disk_reserve_s = {self.reserve_bytes / RAW_BYTES_PER_S:g} s)")
        return True
