"""Writing native raw recordings (``.bpmsraw``, docs/raw-format.md); the layout is in
:mod:`bpms.io.raw_layout`, the one reader in :mod:`bpms.io.raw_reader` (both re-exported
here).

The writer flushes to the disk (``fsync``) at least once per flush interval, so after a crash
every record before the last flush reads back; a torn last record is ignored with a warning.
Event records (:class:`bpms.io.session_events.SessionEvent`) go between the frame records as
they happen, written and flushed with them; one that changes numbers is written twice.
"""

from __future__ import annotations

import os
import struct
import time
from pathlib import Path
from typing import Any

import numpy as np

from bpms.io.closing import Closing
from bpms.io.frames import FRAME_DTYPE, FRAME_SIZE
from bpms.io.raw_layout import (
    EXTENSION,
    FORMAT_VERSION,
    MAGIC,
    PREAMBLE,
    RECORD_DTYPE,
    RECORD_SIZE,
    RawFileError,
    RecordingError,
    event_record,
    header_bytes,
    read_header,
)
from bpms.io.raw_reader import RawFile, RawFrames, RawRecording, read_raw
from bpms.io.session_events import SessionEvent

__all__ = ["EXTENSION", "FORMAT_VERSION", "MAGIC", "RECORD_DTYPE", "RECORD_SIZE", "RawFile",
           "RawFileError", "RawFrames", "RawRecording", "RawWriter", "RecordingError",
           "new_header", "read_header", "read_raw", "write_raw"]


def new_header(*, calibration: np.ndarray | None = None, options: dict[str, Any] | None = None,
               notes: str = "", source: str = "", extra: dict[str, Any] | None = None,
               ) -> dict[str, Any]:
    """The header of a new recording: start time, calibration and options in force, notes."""
    from bpms import __version__

    now = time.time()
    header: dict[str, Any] = {
        "format": "BPMS raw recording",
        "format_version": FORMAT_VERSION,
        "software": f"bpms {__version__}",
        "start_time": now,
        "start_time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(now)),
        "frame_size": FRAME_SIZE,
        "record_size": RECORD_SIZE,
        "frame_rate_hz": 50.0,
        "source": source,
        "notes": notes,
        "calibration": None if calibration is None else np.asarray(calibration).tolist(),
        "options": options or {},
    }
    header.update(extra or {})
    return header


class RawWriter(Closing):
    """Appends records to a new raw file; data reach the disk at least every ``flush_interval_s``.

    Raises :class:`RecordingError` on any OS error (disk full, folder not writable, device
    removed) and when the file has vanished under it (its folder was removed: the file can
    no longer be reached, whatever is written to it is lost). The file keeps every record
    written before the last successful flush; :meth:`records_on_disk` says how many a reader
    will find. Call :meth:`flush_if_due` regularly (also when no frame comes) so that every
    record reaches the disk within ``flush_interval_s``.
    """

    def __init__(self, path: str | Path, header: dict[str, Any],
                 flush_interval_s: float = 1.0) -> None:
        self.path = Path(path)
        self.flush_interval_s = flush_interval_s
        self.records = 0  # frame records handed to the file
        self.events = 0  # event records handed to the file
        self.synced_records = 0  # records known to be on the disk (last successful flush)
        self.failed = False
        text = header_bytes(header)
        self._data_offset = PREAMBLE.size + len(text)
        self._bytes = self._data_offset  # bytes handed to the file
        self._event_marks: list[tuple[int, int]] = []  # (file offset after an event, frames)
        try:
            # "x": never overwrite an existing recording.
            self._file = self.path.open("xb")
            self._file.write(PREAMBLE.pack(MAGIC, FORMAT_VERSION, len(text)))
            self._file.write(text)
            self._sync()
            st = os.fstat(self._file.fileno())
        except OSError as exc:
            raise RecordingError(f"cannot create {self.path}: {exc.strerror or exc}") from exc
        self._identity = (st.st_dev, st.st_ino)
        self._last_flush = time.monotonic()
        self._first_unsynced: float | None = None
        self._record = bytearray(RECORD_SIZE)

    def _sync(self) -> None:
        self._file.flush()
        os.fsync(self._file.fileno())

    def _fail(self, exc: OSError | None, what: str) -> RecordingError:
        self.failed = True
        why = (exc.strerror or str(exc)) if exc is not None else what
        return RecordingError(f"writing {self.path} failed: {why}")

    def write(self, host_time: float, frame: bytes) -> None:
        """Append one record (host receive time in s since the epoch, 340-byte frame)."""
        if len(frame) != FRAME_SIZE:
            raise ValueError(f"a frame is {FRAME_SIZE} bytes, got {len(frame)}")
        if self.failed:
            raise RecordingError(f"writing {self.path} failed earlier: recording stopped")
        struct.pack_into("<d", self._record, 0, host_time)
        self._record[8:] = frame
        try:
            self._file.write(self._record)
        except OSError as exc:
            raise self._fail(exc, "") from exc
        self.records += 1
        self._bytes += RECORD_SIZE
        if self._first_unsynced is None:
            self._first_unsynced = time.monotonic()
        self.flush_if_due()

    def write_event(self, event: SessionEvent, host_time: float | None = None) -> None:
        """Append one event record after the frames written so far (``event.frame``: the slot
        of the first frame it affects; ``host_time``: s since the epoch, default now). An
        event that changes numbers is written as two identical records in a row (the reader
        keeps one), so that damage to one copy does not lose it."""
        if self.failed:
            raise RecordingError(f"writing {self.path} failed earlier: recording stopped")
        data = event_record(event, time.time() if host_time is None else host_time)
        if event.changes_numbers:  # two identical records: one damaged copy is not the only one
            data += data
        try:
            self._file.write(data)
        except OSError as exc:
            raise self._fail(exc, "") from exc
        self._bytes += len(data)
        self.events += 1
        self._event_marks.append((self._bytes, self.records))
        if self._first_unsynced is None:
            self._first_unsynced = time.monotonic()

    def flush_if_due(self) -> None:
        """Flush when the oldest record not yet on the disk is ``0.8·flush_interval_s`` old
        (so that, with a caller polling every 0.1 s, none waits longer than the interval)."""
        first = self._first_unsynced
        if first is not None and time.monotonic() - first >= 0.8 * self.flush_interval_s:
            self.flush()

    def flush(self) -> None:
        """Push everything written so far to the disk; check the file is still reachable."""
        if self.failed:
            raise RecordingError(f"writing {self.path} failed earlier: recording stopped")
        try:
            self._sync()
            gone = os.fstat(self._file.fileno()).st_nlink == 0
        except OSError as exc:
            raise self._fail(exc, "") from exc
        if gone:
            raise self._fail(None, "the file was removed (was its folder deleted?)")
        self.synced_records = self.records
        self._last_flush = time.monotonic()
        self._first_unsynced = None

    def records_on_disk(self) -> int:
        """Whole records a reader finds in the file now (0 when the file is gone)."""
        try:
            st = os.stat(self.path)
        except OSError:
            return 0
        if (st.st_dev, st.st_ino) != self._identity:
            return 0
        offset, frames = self._data_offset, 0
        for end, before in self._event_marks:  # the last event wholly on the disk
            if end > st.st_size:
                break
            offset, frames = end, before
        return max(0, min(self.records, frames + (st.st_size - offset) // RECORD_SIZE))

    @property
    def size_bytes(self) -> int:
        return self._bytes

    def close(self) -> None:
        """Flush and close. Raises RecordingError when the last flush fails (the file is
        closed all the same)."""
        if self._file.closed:
            return
        try:
            if not self.failed:
                self.flush()
        finally:
            try:
                self._file.close()
            except OSError as exc:  # a buffered tail that cannot be written
                if not self.failed:
                    raise self._fail(exc, "") from exc


def write_raw(path: str | Path, times: np.ndarray, frames: bytes, header: dict[str, Any],
              events: list[SessionEvent] | tuple[SessionEvent, ...] = ()) -> None:
    """Write a whole recording at once: ``times[N]`` s and N concatenated 340-byte frames;
    each of ``events`` (``frame``: its slot) goes just before its frame's record (after the
    last one when its frame is beyond)."""
    times = np.asarray(times, dtype="<f8")
    if len(frames) != len(times) * FRAME_SIZE:
        raise ValueError("frames must hold exactly one 340-byte frame per time")
    records = np.empty(len(times), dtype=RECORD_DTYPE)
    records["time"] = times
    records["frame"] = np.frombuffer(frames, dtype=FRAME_DTYPE)
    ordered = sorted(events, key=lambda e: e.frame)
    if ordered:
        header = {"session_events": True, **header}
    with RawWriter(path, header) as writer:
        try:
            at = 0
            for event in [*ordered, None]:
                upto = len(records) if event is None else min(max(event.frame, 0), len(records))
                if upto > at:
                    writer._file.write(records[at:upto].tobytes())
                    writer.records += upto - at
                    writer._bytes += (upto - at) * RECORD_SIZE
                    at = upto
                if event is not None:
                    host = float(times[min(at, len(times) - 1)]) if len(times) else 0.0
                    writer.write_event(event, host)
        except OSError as exc:
            raise RecordingError(f"writing {path} failed: {exc.strerror or exc}") from exc
