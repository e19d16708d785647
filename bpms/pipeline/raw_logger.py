"""The raw logger thread: writes raw records from an unbounded queue, honestly.

Raw data are never dropped in memory: every received frame is queued. The thread wakes
every :data:`BATCH_S` (or a fifth of the flush interval, when shorter) whatever the link does,
writes everything queued since, and syncs to the disk within ``flush_interval_s`` of a frame's
arrival, so a crash during a silence loses no frame received more than the interval before.
Waking a few times a second instead of once per frame keeps this thread off the live path (one
thread switch per frame less). Session events (:mod:`bpms.pipeline.events`) come through the
same queue, after the frames queued before them, and are written between the frame records
at the slot of the frame they name (:class:`SlotMap`: source frame index → slot in the file).
A write error (disk full, folder gone, device removed) stops the writing for good; the error
stays in :class:`RecordingStatus`-like ``status.error`` until logging stops, later frames are
counted as lost, and at the end ``status.raw_on_disk`` says what a reader will find in the
file.

Disk space goes to the raw file first: with a reserve (seconds of raw data,
:class:`bpms.pipeline.disk_reserve.DiskReserve`) the logger checks the free space five times
a second, and when it falls below the reserve it sets ``status.filtered_stopped``: the session
then stops the filtered file; the raw file goes on until the disk is full.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from typing import Any

from bpms.io.events import FrameEvent
from bpms.io.rawfile import RawWriter, RecordingError
from bpms.io.session_events import SessionEvent
from bpms.pipeline.disk_reserve import DiskReserve

STOP = object()
BATCH_S = 0.1  # longest wait between two batches of records, s


class SlotMap:
    """Which slot of the file each source frame index went to: runs of consecutive indices
    (one comparison per frame), the older ones forgotten once far behind."""

    #: Slots behind the newest for which an event may still arrive (the processing backlog
    #: and a batch, docs/pipeline.md, with margin).
    KEEP_SLOTS = 20_000

    def __init__(self) -> None:
        self.runs: list[list[int]] = []  # [first index, first slot, count]
        self.slots = 0
        self._next_index: int | None = None

    def add(self, index: int) -> None:
        if index == self._next_index:
            self.runs[-1][2] += 1
        else:
            self.runs.append([index, self.slots, 1])
            if len(self.runs) > 512:
                self.runs = [r for r in self.runs
                             if r[1] + r[2] > self.slots - self.KEEP_SLOTS] or self.runs[-1:]
        self._next_index = index + 1
        self.slots += 1

    def slot_of(self, index: int) -> int:
        """The slot of source frame ``index`` (the next frame written after it when it was
        not written; 0 when it came before the recording started)."""
        for first, slot, count in reversed(self.runs):
            if index >= first:
                return slot + min(index - first, count)
        return self.runs[0][1] if self.runs else 0


class RawLogger(threading.Thread):
    """Writes raw records from :attr:`queue` until :meth:`stop` (or :data:`STOP` is put and
    the next batch is due). ``status`` gets ``raw_received``, ``raw_records``,
    ``raw_on_disk``, ``raw_lost``, ``raw_bytes``, ``error`` and ``filtered_stopped``;
    ``on_error(message)`` is called once, when the writing fails. With ``reserve_s`` (seconds
    of raw data, :class:`DiskReserve`), ``filtered_stopped`` is set (to the reason) once the
    free space falls below it."""

    def __init__(self, writer: RawWriter, status: Any, on_error: Callable[[str], None],
                 reserve_s: float = 0.0) -> None:
        super().__init__(name="bpms-raw-logger", daemon=True)
        self.writer = writer
        self.status = status
        self.on_error = on_error
        self.reserve = DiskReserve(writer.path.parent, reserve_s) if reserve_s > 0 else None
        self.queue: queue.SimpleQueue[FrameEvent | SessionEvent | object] = queue.SimpleQueue()
        self.slots = SlotMap()
        #: the source frame index of the file's first frame (set by the acquisition thread)
        self.first_index: int | None = None
        #: the source frame index of the last frame handed to the file (acquisition thread)
        self.last_index: int | None = None
        #: True once no more frames are handed to it (the session stopped logging): the
        #: file ends at :attr:`last_index`
        self.fed_done = False
        self._wake = threading.Event()
        # a fifth of the flush interval at most: flush_if_due flushes at 0.8 of it
        self.batch_s = min(BATCH_S, writer.flush_interval_s / 5)

    def stop(self) -> None:
        """Write what is queued, close the file and end the thread (see :meth:`join`)."""
        self.queue.put(STOP)
        self._wake.set()

    def _failed(self, exc: Exception) -> None:
        self.status.error = str(exc)
        self.on_error(f"raw recording stopped: {exc}")

    def _write(self, item: FrameEvent) -> None:
        self.status.raw_received += 1
        self.slots.add(item.index)
        if self.writer.failed:
            return
        try:
            self.writer.write(item.host_time, item.frame)
        except RecordingError as exc:
            self._failed(exc)

    def _write_event(self, event: SessionEvent) -> None:
        if self.writer.failed:
            return
        if event.frame >= 0:
            event = event.at(self.slots.slot_of(event.frame))
        try:
            self.writer.write_event(event, event.time if event.time == event.time else None)
        except (RecordingError, ValueError) as exc:
            if isinstance(exc, RecordingError):
                self._failed(exc)

    def _check_space(self) -> None:
        reserve = self.reserve
        if reserve is None or self.status.filtered_stopped or not reserve.low():
            return
        self.status.filtered_stopped = reserve.reason

    def run(self) -> None:
        writer, status, items = self.writer, self.status, self.queue
        try:
            stopping = False
            while not stopping:
                self._wake.wait(self.batch_s)
                while True:
                    try:
                        item = items.get_nowait()
                    except queue.Empty:
                        break
                    if item is STOP:
                        stopping = True
                        break
                    if isinstance(item, SessionEvent):
                        self._write_event(item)
                    else:
                        assert isinstance(item, FrameEvent)
                        self._write(item)
                if not writer.failed:
                    try:
                        writer.flush_if_due()
                    except RecordingError as exc:
                        self._failed(exc)
                status.raw_records = writer.records
                status.raw_bytes = writer.size_bytes
                status.raw_on_disk = writer.synced_records
                self._check_space()
        finally:
            try:
                writer.close()
            except (RecordingError, OSError) as exc:
                if status.error is None:
                    self._failed(exc)
            status.raw_on_disk = writer.records_on_disk()
            status.raw_lost = max(0, status.raw_received - status.raw_on_disk)
