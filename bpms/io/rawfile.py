"""The native raw recording format (``.bpmsraw``), documented in ``docs/raw-format.md``.

::

    offset        size   content
    0             8      magic b"BPMSRAW\\0"
    8             2      format version, little-endian uint16 (currently 1)
    10            4      header length H, little-endian uint32
    14            H      header: UTF-8 JSON (start time, calibration, options, notes, ...)
    14+H          pad    spaces up to the next multiple of 16 (part of the header text)
    D = 14+H+pad  348·N  records: host receive time (float64 LE, s since the Unix epoch)
                         followed by the 340-byte frame exactly as received

Fixed-size records make frame k reachable at ``D + 348·k`` and the whole file decodable in
one ``numpy.frombuffer`` call. The writer flushes to the disk (``fsync``) at least once per
flush interval, so after a crash every record before the last flush reads back; a torn last
record is ignored with a warning.

Damaged files: the reader resynchronises on the record structure (``$#`` at offset 8 and
``#$`` at offset 346 of a record, confirmed by the next record) after damaged bytes. A
damaged stretch keeps its slots: it becomes ``round(bytes / 348)`` (at least one)
placeholder frames with every sensor flagged failed, so that every later frame keeps its
position, hence its time (index × 0.02 s). Skipped bytes and placeholder slots are counted
in :attr:`RawRecording.problems`, :attr:`RawRecording.damaged` and
:attr:`RawRecording.skipped_bytes`.
"""

from __future__ import annotations

import json
import logging
import os
import struct
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bpms.io.bounded import MAX_HEADER_BYTES, BoundError, check_size, loads_json
from bpms.io.frames import (
    FRAME_DTYPE,
    FRAME_SIZE,
    N_IMUS,
    DecodedFrames,
    decode_frames,
    encode_frame,
)

log = logging.getLogger(__name__)

MAGIC = b"BPMSRAW\0"
FORMAT_VERSION = 1
EXTENSION = ".bpmsraw"
_PREAMBLE = struct.Struct("<8sHI")
RECORD_DTYPE = np.dtype([("time", "<f8"), ("frame", FRAME_DTYPE)])
RECORD_SIZE = RECORD_DTYPE.itemsize
assert RECORD_SIZE == 8 + FRAME_SIZE


class RawFileError(Exception):
    """A file that cannot be read as a BPMS raw recording (message says why)."""


class RecordingError(Exception):
    """Writing a recording failed (disk full, folder not writable): recording must stop."""


@dataclass
class RawRecording:
    """A raw recording in memory: host receive times ``[N]`` s and frames ``[N]`` (structured,
    :data:`bpms.io.frames.FRAME_DTYPE`)."""

    path: str
    header: dict[str, Any]
    times: np.ndarray
    frames: np.ndarray
    problems: list[str] = field(default_factory=list)
    damaged: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # slot indices
    skipped_bytes: int = 0  # bytes of damaged records (now placeholder slots)

    def __len__(self) -> int:
        return len(self.times)

    def decode(self) -> DecodedFrames:
        """All frames as ``raw[N, 18, 9]`` and ``errors[N, 18, 3]``."""
        return decode_frames(self.frames.tobytes())

    def frame_bytes(self, index: int) -> bytes:
        """The 340 bytes of frame ``index``."""
        return self.frames[index].tobytes()

    @property
    def duration_s(self) -> float:
        """Nominal duration at 50 Hz (the stream time of the frame after the last), s."""
        from bpms.io.timebase import stream_time

        return stream_time(len(self))


def _header_bytes(header: dict[str, Any]) -> bytes:
    text = json.dumps(header, indent=1, sort_keys=True).encode("utf-8")
    pad = (-(_PREAMBLE.size + len(text))) % 16
    return text + b" " * pad


def read_header(path: str | Path) -> tuple[dict[str, Any], int]:
    """(header dict, offset of the first record). Raises RawFileError."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            preamble = f.read(_PREAMBLE.size)
            if len(preamble) < _PREAMBLE.size or not preamble.startswith(MAGIC):
                raise RawFileError(f"{path}: not a BPMS raw recording (no BPMSRAW signature)")
            _, version, length = _PREAMBLE.unpack(preamble)
            if version > FORMAT_VERSION:
                raise RawFileError(
                    f"{path}: raw format version {version} is newer than this software "
                    f"({FORMAT_VERSION}); update BPMS Suite")
            try:  # bounded before anything is read or parsed (bpms/io/bounded.py)
                check_size(length, MAX_HEADER_BYTES, "the header")
            except BoundError as exc:
                raise RawFileError(f"{path}: {exc}") from None
            text = f.read(length)
    except OSError as exc:
        raise RawFileError(f"{path}: cannot be read ({exc.strerror or exc})") from exc
    if len(text) < length:
        raise RawFileError(f"{path}: the header is cut short ({len(text)} of {length} bytes)")
    try:
        header = loads_json(text.decode("utf-8"), "the header")
    except BoundError as exc:
        raise RawFileError(f"{path}: {exc}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RawFileError(f"{path}: the header is damaged ({exc})") from exc
    if not isinstance(header, dict):
        raise RawFileError(f"{path}: the header is not a JSON object")
    return header, _PREAMBLE.size + length


def read_raw(path: str | Path) -> RawRecording:
    """Read a whole native raw recording. A torn last record is dropped with a warning;
    damaged records (disk corruption, lost or inserted bytes) keep their slots as
    placeholder frames (every sensor flagged failed), counted and reported."""
    path = Path(path)
    header, offset = read_header(path)
    try:
        data = path.read_bytes()[offset:]
    except OSError as exc:
        raise RawFileError(f"{path}: cannot be read ({exc.strerror or exc})") from exc
    problems: list[str] = []
    records, damaged, skipped, torn = _scan_records(data)
    if torn:
        problems.append(f"{path}: the last record is incomplete ({torn} of {RECORD_SIZE} bytes, "
                        "the recording was cut off): ignored")
    if len(damaged):
        problems.append(f"{path}: {len(damaged)} damaged record(s) ({skipped} bytes) without "
                        "a valid record structure: their slots are kept as frames with every "
                        "sensor flagged failed")
    for p in problems:
        log.warning("%s", p)
    return RawRecording(str(path), header, records["time"].copy(), records["frame"].copy(),
                        problems, damaged, skipped)


#: Records checked at once before the scan looks for damage (bounds the cost per damage).
_SCAN_BLOCK = 4096


def _is_record_at(data: bytes, q: int) -> bool:
    return data[q + 8 : q + 10] == b"$#" and data[q + 346 : q + 348] == b"#$"


def _next_record(data: bytes, start: int) -> int | None:
    """The first offset >= ``start`` where a record (confirmed by the next one, when there is
    room for it) begins; None when there is none."""
    n = len(data)
    s = data.find(b"$#", start + 8)
    while s >= 0 and s - 8 + RECORD_SIZE <= n:
        q = s - 8
        if _is_record_at(data, q):
            nxt = q + RECORD_SIZE
            if nxt + RECORD_SIZE > n or _is_record_at(data, nxt):
                return q
        s = data.find(b"$#", s + 1)
    return None


def _placeholders(count: int, t0: float, t1: float) -> np.ndarray:
    """``count`` records whose frames flag every sensor failed, times spread in (t0, t1)."""
    recs = np.zeros(count, dtype=RECORD_DTYPE)
    frame = encode_frame(np.zeros((N_IMUS, 9), np.int16), np.ones((N_IMUS, 3), bool))
    recs["frame"] = np.frombuffer(frame, dtype=FRAME_DTYPE)[0]
    if not (np.isfinite(t0) and np.isfinite(t1)) or t1 < t0:
        t1 = t0 + 0.02 * (count + 1) if np.isfinite(t0) else 0.0
        t0 = t0 if np.isfinite(t0) else 0.0
    recs["time"] = t0 + (t1 - t0) * np.arange(1, count + 1) / (count + 1)
    return recs


def _scan_records(data: bytes) -> tuple[np.ndarray, np.ndarray, int, int]:
    """(records, slot indices of placeholders, damaged bytes, torn tail bytes). Linear in
    the size: intact stretches are checked in blocks, damage costs one forward search."""
    n = len(data)
    chunks: list[np.ndarray] = []
    damaged: list[int] = []
    slots = skipped = 0
    p = 0
    last_time = float("nan")
    while n - p >= RECORD_SIZE:
        m = min((n - p) // RECORD_SIZE, _SCAN_BLOCK)
        recs = np.frombuffer(data, RECORD_DTYPE, m, p)
        good = (recs["frame"]["start"] == b"$#") & (recs["frame"]["end"] == b"#$")
        k = m if good.all() else int(np.argmin(good))
        if k:
            chunks.append(recs[:k])
            slots += k
            p += k * RECORD_SIZE
            last_time = float(recs["time"][k - 1])
        if k == m:
            continue
        q = _next_record(data, p + 1)
        end = n if q is None else q
        gap = end - p
        if q is None and gap < RECORD_SIZE:
            break  # a torn tail, not damage
        count = max(1, round(gap / RECORD_SIZE))
        next_time = float("nan") if q is None else struct.unpack_from("<d", data, q)[0]
        chunks.append(_placeholders(count, last_time, next_time))
        damaged.extend(range(slots, slots + count))
        slots += count
        skipped += gap
        p = end
    torn = n - p
    # (np.concatenate would make the big-endian fields native: copy into the file's layout)
    records = np.empty(sum(len(c) for c in chunks), RECORD_DTYPE)
    at = 0
    for c in chunks:
        records[at : at + len(c)] = c
        at += len(c)
    return records, np.asarray(damaged, np.int64), skipped, torn


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


class RawWriter:
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
        self.records = 0  # records handed to the file
        self.synced_records = 0  # records known to be on the disk (last successful flush)
        self.failed = False
        header_bytes = _header_bytes(header)
        self._data_offset = _PREAMBLE.size + len(header_bytes)
        try:
            # "x": never overwrite an existing recording.
            self._file = self.path.open("xb")
            self._file.write(_PREAMBLE.pack(MAGIC, FORMAT_VERSION, len(header_bytes)))
            self._file.write(header_bytes)
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
        if self._first_unsynced is None:
            self._first_unsynced = time.monotonic()
        self.flush_if_due()

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
        return max(0, min(self.records, (st.st_size - self._data_offset) // RECORD_SIZE))

    @property
    def size_bytes(self) -> int:
        return self._data_offset + self.records * RECORD_SIZE

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

    def __enter__(self) -> RawWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_raw(path: str | Path, times: np.ndarray, frames: bytes, header: dict[str, Any]) -> None:
    """Write a whole recording at once: ``times[N]`` s and N concatenated 340-byte frames."""
    times = np.asarray(times, dtype="<f8")
    if len(frames) != len(times) * FRAME_SIZE:
        raise ValueError("frames must hold exactly one 340-byte frame per time")
    records = np.empty(len(times), dtype=RECORD_DTYPE)
    records["time"] = times
    records["frame"] = np.frombuffer(frames, dtype=FRAME_DTYPE)
    with RawWriter(path, header) as writer:
        try:
            writer._file.write(records.tobytes())
            writer.records = len(records)
        except OSError as exc:
            raise RecordingError(f"writing {path} failed: {exc.strerror or exc}") from exc
