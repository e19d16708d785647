"""The raw logger thread: writes raw records from an unbounded queue, honestly.

Raw data are never dropped in memory: every received frame is queued. The writer syncs to
the disk within ``flush_interval_s`` of a frame's arrival whatever the link does (the thread
wakes every :data:`POLL_S` even when no frame comes), so a crash during a silence loses no
frame received more than the interval before. A write error (disk full, folder gone, device
removed) stops the writing for good; the error stays in :class:`RecordingStatus`-like
``status.error`` until logging stops, later frames are counted as lost, and at the end
``status.raw_on_disk`` says what a reader will find in the file.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from typing import Any

from bpms.io.events import FrameEvent
from bpms.io.rawfile import RawWriter, RecordingError

STOP = object()
POLL_S = 0.05  # longest wait for a frame before checking whether a flush is due, s


class RawLogger(threading.Thread):
    """Writes raw records from :attr:`queue` until :data:`STOP` is put. ``status`` gets
    ``raw_received``, ``raw_records``, ``raw_on_disk``, ``raw_lost``, ``raw_bytes`` and
    ``error``; ``on_error(message)`` is called once, when the writing fails."""

    def __init__(self, writer: RawWriter, status: Any, on_error: Callable[[str], None]) -> None:
        super().__init__(name="bpms-raw-logger", daemon=True)
        self.writer = writer
        self.status = status
        self.on_error = on_error
        self.queue: queue.SimpleQueue[FrameEvent | object] = queue.SimpleQueue()

    def _failed(self, exc: Exception) -> None:
        self.status.error = str(exc)
        self.on_error(f"raw recording stopped: {exc}")

    def run(self) -> None:
        writer, status = self.writer, self.status
        try:
            while True:
                try:
                    item = self.queue.get(timeout=POLL_S)
                except queue.Empty:
                    item = None
                if item is STOP:
                    break
                if item is not None:
                    status.raw_received += 1
                if writer.failed:
                    continue
                try:
                    if item is not None:
                        assert isinstance(item, FrameEvent)
                        writer.write(item.host_time, item.frame)
                    else:
                        writer.flush_if_due()
                except RecordingError as exc:
                    self._failed(exc)
                status.raw_records = writer.records
                status.raw_bytes = writer.size_bytes
                status.raw_on_disk = writer.synced_records
        finally:
            try:
                writer.close()
            except (RecordingError, OSError) as exc:
                if status.error is None:
                    self._failed(exc)
            status.raw_on_disk = writer.records_on_disk()
            status.raw_lost = max(0, status.raw_received - status.raw_on_disk)
