"""The one reader of native raw recordings (``.bpmsraw``, docs/raw-format.md).

Every door reads a raw recording through :class:`RawFile`: ``bpms filter`` and the other
analysis commands chunk by chunk (:meth:`RawFile.chunks`), replay and GUI playback by slot
(:class:`RawFrames`), scripts and tests whole (:func:`read_raw`, the same code collected into
one :class:`RawRecording`). The file streams from disk a few MiB at a time, so memory stays flat
however long the recording.

Damage: after bytes that are neither a frame record nor an event record (corruption, bytes
lost or inserted), the reader resynchronises on the next record — a frame record confirmed by
the record after it, or an event record whose CRC holds. A damaged stretch keeps its slots:
it becomes ``round(bytes / 348)`` placeholder frames with every sensor flagged failed (none
for fewer than 174 bytes between two intact records: bytes inserted there), so every later
frame keeps its position, hence its time (index × 0.02 s). A damaged event record costs only
itself (no slot, even when its marker or length field was hit: :mod:`bpms.io.raw_events`), and
nothing when its copy beside it is intact; a lost one is handed on as a ``lost`` event naming
its kind and frame. A torn last record is ignored with a warning.

Events (format version 2) apply at the frame they name, whatever their place in the file: the
live session writes an event after the frames it processed, so :meth:`RawFile.chunks` holds a
chunk back until it has read :data:`LOOKAHEAD` frames beyond it.
"""

from __future__ import annotations

import bisect
import logging
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from bpms.io.frames import FRAME_DTYPE, N_IMUS, DecodedFrames, decode_frames, encode_frame
from bpms.io.paths import require_regular_input
from bpms.io.raw_events import (
    LOOKAHEAD,
    Copies,
    Counts,
    damaged_events,
    event_at,
    find_record,
    frame_in,
    kind_in,
    lost_event,
)
from bpms.io.raw_layout import (
    EVENT_END,
    EVENT_HEAD,
    EVENTS_VERSION,
    FRAME_END,
    FRAME_START,
    RECORD_DTYPE,
    RECORD_SIZE,
    RawFileError,
    event_size_at,
    read_preamble,
)
from bpms.io.session_events import SessionEvent

log = logging.getLogger(__name__)

#: Bytes read from the disk at a time.
BLOCK_BYTES = 1 << 22
#: Frame records checked in one vectorised step.
SCAN_RECORDS = 4096
#: Default frames per chunk of :meth:`RawFile.chunks`.
CHUNK_FRAMES = 5_000


@dataclass
class RawRecording:
    """A raw recording in memory: host receive times ``[N]`` s, frames ``[N]`` (structured,
    :data:`bpms.io.frames.FRAME_DTYPE`) and the events ``(slot, SessionEvent)`` in slot order
    (slots ≥ N: after the last frame)."""

    path: str
    header: dict[str, Any]
    times: np.ndarray
    frames: np.ndarray
    problems: list[str] = field(default_factory=list)
    damaged: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # slot indices
    skipped_bytes: int = 0  # bytes of damaged records (now placeholder slots)
    events: list[tuple[int, SessionEvent]] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.times)

    @property
    def valid_frames(self) -> int:
        """Slots holding a frame as recorded (not a placeholder for damage)."""
        return len(self) - len(self.damaged)

    def decode(self) -> DecodedFrames:
        """All frames as ``raw[N, 18, 9]`` and ``errors[N, 18, 3]``."""
        return decode_frames(self.frames.tobytes())

    def frame_bytes(self, index: int) -> bytes:
        """The 340 bytes of frame ``index``."""
        return self.frames[index].tobytes()

    def read(self, lo: int, hi: int) -> tuple[np.ndarray, bytes]:
        """(host times ``[n]`` s, the frames' bytes) of slots ``lo .. hi-1``."""
        return self.times[lo:hi], self.frames[lo:hi].tobytes()

    @property
    def duration_s(self) -> float:
        """Nominal duration at 50 Hz (the stream time of the frame after the last), s."""
        from bpms.io.timebase import stream_time

        return stream_time(len(self))


@dataclass
class RawChunk:
    """Consecutive slots of a recording: ``start`` (slot of the first), ``records`` (structured
    :data:`bpms.io.raw_layout.RECORD_DTYPE`, placeholders included), ``damaged`` (their slot
    indices), ``events`` ``(slot, SessionEvent)`` applying in this chunk, in slot order."""

    start: int
    records: np.ndarray
    damaged: np.ndarray
    events: list[tuple[int, SessionEvent]]

    def __len__(self) -> int:
        return len(self.records)

    @property
    def times(self) -> np.ndarray:
        return self.records["time"]

    def frame_bytes(self) -> bytes:
        return self.records["frame"].tobytes()


def join_records(parts: list[np.ndarray]) -> np.ndarray:
    """Records joined in the file's layout (``np.concatenate`` would make the big-endian
    frame fields native)."""
    records = np.empty(sum(len(c) for c in parts), RECORD_DTYPE)
    at = 0
    for c in parts:
        records[at:at + len(c)] = c
        at += len(c)
    return records


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


def _pieces(f: BinaryIO, offset: int, events: bool, counts: Counts, slot: int = 0,
            last_time: float = float("nan")) -> Iterator[tuple]:
    """The data part from ``offset`` in file order: ``("frames", slot, records, file offset,
    time before)``, ``("gap", slot, placeholder records)`` and ``("event", slot, event)``
    (``slot``: where the piece begins)."""
    f.seek(offset)
    copies = Copies(counts)
    buf = b""
    base = offset  # file offset of buf[0]
    p = 0
    eof = False

    def fill(need: int) -> None:
        nonlocal buf, base, p, eof
        if len(buf) - p >= need or eof:
            return
        parts = [buf[p:]]
        base += p
        p = 0
        have = len(parts[0])
        while have < need:
            data = f.read(max(BLOCK_BYTES, need - have))
            if not data:
                eof = True
                break
            parts.append(data)
            have += len(data)
        buf = b"".join(parts)

    while True:
        fill(2 * RECORD_SIZE)
        avail = len(buf) - p
        if avail <= 0:
            break
        if avail >= RECORD_SIZE:
            m = min(avail // RECORD_SIZE, SCAN_RECORDS)
            recs = np.frombuffer(buf, RECORD_DTYPE, m, p)
            good = (recs["frame"]["start"] == FRAME_START) & (recs["frame"]["end"] == FRAME_END)
            k = m if good.all() else int(np.argmin(good))
            if k:
                yield from copies.flush(slot)
                yield "frames", slot, recs[:k], base + p, last_time
                slot += k
                p += k * RECORD_SIZE
                last_time = float(recs["time"][k - 1])
                continue
        event_size = None  # a damaged event record begins here (its length is plausible)
        if events:
            state, size = event_at(buf, p, eof)
            while state == "more":
                fill(size)
                state, size = event_at(buf, p, eof)
            if state == "yes":
                yield from copies.intact(buf[p:p + size], slot)
                p += size
                continue
            event_size = event_size_at(buf, p)
            if event_size is not None:
                fill(event_size)
                if (len(buf) - p >= event_size
                        and buf[p + event_size - 2:p + event_size] == EVENT_END):
                    # a damaged event record whose length and end marker hold: it is skipped
                    # exactly (no slot), and lost unless its copy beside it is intact
                    copies.damaged(buf[p:p + event_size])
                    p += event_size
                    continue
            if (event_size is not None and p + event_size > len(buf)
                    and find_record(buf, p + 1, True, events)[0] is None):
                counts.torn = len(buf) - p  # a cut-off last event
                break
        if eof and avail < RECORD_SIZE and event_size is None:
            counts.torn = avail
            break
        last_intact = copies.last
        copy_head = last_intact is not None and last_intact[:EVENT_HEAD.size] == bytes(
            buf[p:p + EVENT_HEAD.size])
        yield from copies.flush(slot)
        lost_kind = "unknown" if event_size is None else kind_in(buf[p:p + event_size])
        lost_frame = slot if event_size is None else frame_in(buf[p:p + event_size], slot)
        gap_start = base + p
        search = p + 1
        while True:
            q, status = find_record(buf, search, eof, events)
            if status == "found" or (status == "none" and eof):
                break
            # keep only what may still begin a record; the rest of the gap is counted, not kept
            p = q if status == "more" and q is not None else max(search, len(buf) - 16)
            fill(len(buf) - p + BLOCK_BYTES)  # (buf now starts at the old buf[p])
            search = 0
        end = base + (len(buf) if q is None else q)
        gap = end - gap_start
        if q is None and event_size is None and gap < RECORD_SIZE:
            counts.torn = gap
            break
        head, hit = (damaged_events(buf[gap_start - base:q])
                     if events and q is not None and gap_start >= base else (gap, []))
        if hit and q is not None:  # damaged event records end the stretch: no slot for them
            count = round(head / RECORD_SIZE)
            if count:
                yield "gap", slot, _placeholders(count, last_time,
                                                 struct.unpack_from("<d", buf, q)[0])
                counts.damaged += count
                slot += count
            copies.last = None if count else last_intact
            for record in hit:
                copies.damaged(record)
            counts.skipped += gap
            p = q
            continue
        if event_size is not None and gap >= event_size - RECORD_SIZE // 2:
            # a damaged event record, and what follows it: lost, unless it begins as the
            # intact record just read (the same time written and length: its copy)
            if copy_head:
                counts.copies += 1
            else:
                counts.lost_events += 1
                counts.lost.append((lost_kind, lost_frame))
                yield "event", slot, lost_event(lost_kind, slot, lost_frame)
            count = max(0, round((gap - event_size) / RECORD_SIZE))
        else:  # (fewer than half a record between intact records: bytes inserted, no slot)
            count = round(gap / RECORD_SIZE)
        next_time = float("nan") if q is None else struct.unpack_from("<d", buf, q)[0]
        if count:
            yield "gap", slot, _placeholders(count, last_time, next_time)
            counts.damaged += count
            slot += count
        counts.skipped += gap
        if q is None:
            break
        p = q
    yield from copies.flush(slot)


class _ChunkQueue:
    """Slots read but not yet handed out, and the events waiting for their frames."""

    def __init__(self) -> None:
        self.parts: list[np.ndarray] = []
        self.held = 0  # slots held
        self.start = 0  # slot of the first held
        self.damaged: list[int] = []  # ascending
        self.events: list[tuple[int, SessionEvent]] = []
        self.late = 0

    def add(self, slot: int, records: np.ndarray, gap: bool) -> None:
        if gap:
            self.damaged.extend(range(slot, slot + len(records)))
        self.parts.append(records)
        self.held += len(records)

    def event(self, at: int, event: SessionEvent) -> None:
        """An event read at slot position ``at``; it applies at its own frame (``at`` when it
        names none)."""
        self.events.append((event.frame if event.frame >= 0 else at, event))

    def take(self, n: int) -> RawChunk:
        records = np.empty(n, RECORD_DTYPE)
        filled = 0
        while filled < n:
            part = self.parts[0]
            use = min(len(part), n - filled)
            records[filled:filled + use] = part[:use]
            filled += use
            if use == len(part):
                self.parts.pop(0)
            else:
                self.parts[0] = part[use:]
        lo, hi = self.start, self.start + n
        mine: list[tuple[int, SessionEvent]] = []
        rest: list[tuple[int, SessionEvent]] = []
        for slot, event in self.events:
            if slot >= hi:
                rest.append((slot, event))
            elif slot < lo:  # written later than the lookahead allows for
                self.late += 1
                mine.append((lo, event))
            else:
                mine.append((slot, event))
        self.events = rest
        mine.sort(key=lambda item: item[0])
        cut = bisect.bisect_left(self.damaged, hi)
        damaged, self.damaged = self.damaged[:cut], self.damaged[cut:]
        self.start, self.held = hi, self.held - n
        return RawChunk(lo, records, np.asarray(damaged, np.int64), mine)


class RawFile:
    """A native raw recording opened for reading (the header read, the data streamed).

    ``header``, ``version`` (format version), ``problems`` (filled while reading: damage,
    lost events, a torn end). Iterate :meth:`chunks` (analysis), or use :func:`read_raw` /
    :class:`RawFrames`. Raises RawFileError for a file that is not a raw recording.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.header, self.data_offset, self.version = read_preamble(self.path)
        self.problems: list[str] = []
        self.counts = Counts()
        self.frames_read = 0  # slots of the last complete pass

    @property
    def has_events(self) -> bool:
        """The file stores its session's events (format version 2 written by a live session,
        header key ``session_events``): every Reset Zero is in it, the automatic ones too."""
        return self.version >= EVENTS_VERSION and self.header.get("session_events") is True

    def pieces(self, offset: int | None = None, slot: int = 0,
               last_time: float = float("nan"), counts: Counts | None = None
               ) -> Iterator[tuple]:
        """The data part in file order (see :func:`_pieces`), from ``offset`` (a frame
        record's start met by an earlier pass, with its slot and the time before it)."""
        try:
            require_regular_input(self.path)
            with self.path.open("rb") as f:
                yield from _pieces(f, self.data_offset if offset is None else offset,
                                   self.version >= EVENTS_VERSION, counts or self.counts, slot,
                                   last_time)
        except OSError as exc:
            raise RawFileError(f"{self.path}: cannot be read ({exc.strerror or exc})") from exc

    def survey(self) -> tuple[int, int, float]:
        """(slots, valid frames, host time of the first valid frame or NaN) of the whole
        file: one pass, nothing decoded or kept."""
        slots = valid = 0
        first = float("nan")
        for piece in self.pieces(counts=Counts()):
            if piece[0] == "event":
                continue
            if piece[0] == "frames":
                if not valid:
                    first = float(piece[2]["time"][0])
                valid += len(piece[2])
            slots = piece[1] + len(piece[2])
        return slots, valid, first

    def chunks(self, chunk_frames: int = CHUNK_FRAMES, lookahead: int = LOOKAHEAD
               ) -> Iterator[RawChunk]:
        """The recording ``chunk_frames`` slots at a time, each with the events that apply in
        it (read up to ``lookahead`` frames beyond it). Problems are in :attr:`problems` at
        the end, the events after the last frame in :attr:`trailing_events`."""
        self.counts = Counts()
        self.problems = []
        self.trailing_events = []
        queue = _ChunkQueue()
        for piece in self.pieces():
            if piece[0] == "event":
                queue.event(piece[1], piece[2])
                continue
            queue.add(piece[1], piece[2].copy(), piece[0] == "gap")  # (a view of the buffer)
            while queue.held >= chunk_frames + lookahead:
                yield queue.take(chunk_frames)
        while queue.held:
            yield queue.take(min(chunk_frames, queue.held))
        self.frames_read = queue.start
        self.trailing_events = sorted(queue.events, key=lambda item: item[0])
        self._report(queue.late)

    def _report(self, late: int) -> None:
        c, path = self.counts, self.path
        if c.torn:
            self.problems.append(f"{path}: the last record is incomplete ({c.torn} bytes, the "
                                 "recording was cut off): ignored")
        if c.damaged:
            self.problems.append(
                f"{path}: {c.damaged} damaged record(s) ({c.skipped} bytes) without a valid "
                "record structure: their slots are kept as frames with every sensor flagged "
                "failed")
        elif c.skipped and not c.lost_events:
            self.problems.append(f"{path}: {c.skipped} byte(s) between intact records "
                                 "(inserted): skipped, no frame lost")
        if c.lost_events:
            where = ", ".join(f"{kind} at frame {slot}" for kind, slot in c.lost[:6])
            more = ", ..." if len(c.lost) > 6 else ""
            self.problems.append(f"{path}: {c.lost_events} damaged event record(s) lost "
                                 f"({where}{more})")
        if c.copies:
            self.problems.append(f"{path}: {c.copies} damaged event record(s) whose copy "
                                 "beside it is intact: nothing lost")
        if late:
            self.problems.append(f"{path}: {late} event(s) found more than {LOOKAHEAD} frames "
                                 "after their frame: applied from the first frame not yet "
                                 "read")
        for p in self.problems:
            log.warning("%s", p)

    def read_all(self) -> RawRecording:
        """The whole recording in memory (:func:`read_raw`)."""
        chunks = list(self.chunks())
        records = join_records([c.records for c in chunks])
        damaged = (np.concatenate([c.damaged for c in chunks]) if chunks
                   else np.zeros(0, np.int64))
        events = [e for c in chunks for e in c.events] + self.trailing_events
        return RawRecording(str(self.path), self.header, records["time"].copy(),
                            records["frame"].copy(), list(self.problems), damaged,
                            self.counts.skipped, events)


def no_frame_message(path: str | Path, slots: int) -> str:
    """The one-line error for a recording without a valid frame (``slots``: how many it has,
    all placeholders for damage)."""
    if not slots:
        return f"{path}: the recording holds no frames"
    return (f"{path}: holds no valid frame (its {slots} frame slot(s) are all damaged: no "
            "record with intact markers)")


def read_raw(path: str | Path) -> RawRecording:
    """Read a whole native raw recording (the same reader as :meth:`RawFile.chunks`): a torn
    last record is dropped with a warning; damaged records keep their slots as placeholder
    frames (every sensor flagged failed), counted and reported; events in slot order."""
    return RawFile(path).read_all()


@dataclass
class _Checkpoint:
    slot: int
    offset: int
    last_time: float


class RawFrames:
    """A native recording as slots read from disk on demand, for replay and GUI playback:
    ``len``, ``events``, ``damaged``, ``problems``, ``header`` and :meth:`read`. Opening scans
    the file once (memory: one event list and a checkpoint every :data:`SCAN_RECORDS` slots);
    reading in order continues one pass, a jump starts again from the nearest checkpoint."""

    def __init__(self, path: str | Path) -> None:
        self.file = RawFile(path)
        self.path = str(self.file.path)
        self.header = self.file.header
        self._checkpoints: list[_Checkpoint] = []
        damaged: list[int] = []
        events: list[tuple[int, SessionEvent]] = []
        slot = 0
        for piece in self.file.pieces():
            kind, at = piece[0], piece[1]
            if kind == "event":
                events.append((piece[2].frame if piece[2].frame >= 0 else at, piece[2]))
                continue
            if kind == "gap":
                damaged.extend(range(at, at + len(piece[2])))
            elif not self._checkpoints or at - self._checkpoints[-1].slot >= SCAN_RECORDS:
                self._checkpoints.append(_Checkpoint(at, piece[3], piece[4]))
            slot = at + len(piece[2])
        self._length = slot
        events.sort(key=lambda item: item[0])
        self.events = events
        self.damaged = np.asarray(damaged, np.int64)
        self.file._report(0)
        self.problems = list(self.file.problems)
        self.skipped_bytes = self.file.counts.skipped
        self._cursor: Iterator[tuple] | None = None
        self._buffer = np.zeros(0, RECORD_DTYPE)
        self._buffer_start = 0

    def __len__(self) -> int:
        return self._length

    @property
    def valid_frames(self) -> int:
        return len(self) - len(self.damaged)

    @property
    def duration_s(self) -> float:
        """Nominal duration at 50 Hz (the stream time of the frame after the last), s."""
        from bpms.io.timebase import stream_time

        return stream_time(len(self))

    def _restart(self, lo: int) -> None:
        k = bisect.bisect_right(self._checkpoints, lo, key=lambda cp: cp.slot)
        point = self._checkpoints[k - 1] if k else None
        if point is None:
            self._cursor = self.file.pieces(counts=Counts())
            self._buffer_start = 0
        else:
            self._cursor = self.file.pieces(point.offset, point.slot, point.last_time,
                                            Counts())
            self._buffer_start = point.slot
        self._buffer = np.zeros(0, RECORD_DTYPE)

    def read(self, lo: int, hi: int) -> tuple[np.ndarray, bytes]:
        """(host times ``[n]`` s, the frames' bytes) of slots ``lo .. hi-1``."""
        hi = min(hi, len(self))
        if hi <= lo:
            return np.zeros(0), b""
        end = self._buffer_start + len(self._buffer)
        if self._cursor is None or lo < self._buffer_start or lo > end + SCAN_RECORDS:
            self._restart(lo)
        while self._buffer_start + len(self._buffer) < hi:
            piece = None if self._cursor is None else next(self._cursor, None)
            if piece is None:
                break
            if piece[0] == "event":
                continue
            keep = self._buffer[max(0, lo - self._buffer_start):]
            self._buffer_start += len(self._buffer) - len(keep)
            self._buffer = join_records([keep, piece[2]])
        a = lo - self._buffer_start
        part = self._buffer[a:a + (hi - lo)]
        return part["time"].copy(), part["frame"].tobytes()


__all__ = ["CHUNK_FRAMES", "LOOKAHEAD", "RawChunk", "RawFile", "RawFrames", "RawRecording",
           "no_frame_message", "read_raw"]
