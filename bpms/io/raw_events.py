"""Damaged event records in a raw recording (docs/raw-format.md), for the one reader
(:mod:`bpms.io.raw_reader`): an event that changes numbers is written twice in a row
(:meth:`bpms.io.rawfile.RawWriter.write_event`), so one intact copy stands for a damaged
one; a record lost anyway is handed on as a ``lost`` event naming its kind and frame when
what is left of its JSON still says them.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from bpms.io.event_types import Lost
from bpms.io.raw_layout import (
    EVENT_END,
    EVENT_OVERHEAD,
    EVENT_START,
    FRAME_START,
    MAX_EVENT_PAYLOAD,
    RECORD_SIZE,
    event_size_at,
    is_frame_record_at,
    parse_event,
)
from bpms.io.session_events import KINDS, SessionEvent

#: Frames a chunk waits for events that name it: a live session writes an event at most a
#: processing backlog (3,000 frames, docs/pipeline.md) plus a batch after its frame.
LOOKAHEAD = 8192


@dataclass
class Counts:
    damaged: int = 0
    skipped: int = 0
    torn: int = 0
    lost_events: int = 0
    lost: list[tuple[str, int]] = field(default_factory=list)  # (kind, frame) of each
    copies: int = 0  # damaged event records whose intact copy was read


#: Bytes by which a damaged event record may differ from an intact one beside it and still
#: be taken for its copy (a flipped bit changes one).
COPY_DIFF_BYTES = 4


def _differing(a: bytes, b: bytes) -> int:
    """Bytes in which ``a`` and ``b`` differ (their length when they differ in length)."""
    if len(a) != len(b):
        return max(len(a), len(b))
    return int(np.count_nonzero(np.frombuffer(a, np.uint8) != np.frombuffer(b, np.uint8)))


def kind_in(record: bytes) -> str:
    """The kind named in a damaged event record's JSON, when it can still be read there."""
    m = re.search(rb'"kind":"([a-z_]{1,20})"', record)
    kind = m.group(1).decode("ascii") if m else "unknown"
    return kind if kind in KINDS else "unknown"


def frame_in(record: bytes, slot: int) -> int:
    """The frame a damaged event record names, when its JSON still says and the frame is one
    a live writer could have written at this place (at most :data:`LOOKAHEAD` frames before
    it); else ``slot``, its place."""
    m = re.search(rb'"frame":(\d{1,12})[,}]', record)
    frame = int(m.group(1)) if m else -1
    return frame if slot - LOOKAHEAD <= frame <= slot else slot


def lost_event(kind: str, slot: int, frame: int | None = None) -> SessionEvent:
    """What the reader hands on for an event record it could not read: kind ``lost`` at
    ``frame`` (the frame its bytes still name, else its place between the frames: ``slot``,
    the slot of the next frame), ``data``: ``kind``, the kind it was (``unknown`` when its
    bytes do not say) and ``place`` (``slot``)."""
    return SessionEvent.of(Lost(kind, slot), slot if frame is None else frame)


class Copies:
    """The event records between two frame records: an event that changes numbers is written
    twice in a row (:meth:`bpms.io.rawfile.RawWriter.write_event`); one intact copy stands for
    both, and a damaged record is lost only when no intact copy of it is beside it."""

    def __init__(self, counts: Counts) -> None:
        self.counts = counts
        self.last: bytes | None = None  # the last intact record since the last frame
        self.pending: list[bytes] = []  # damaged records not yet matched with a copy

    def intact(self, record: bytes, slot: int) -> Iterator[tuple]:
        if record == self.last and not self.pending:
            return  # the second copy
        if self.pending and _differing(self.pending[-1], record) <= COPY_DIFF_BYTES:
            self.pending.pop()  # the damaged first copy of this one
            self.counts.copies += 1
        yield from self.flush(slot)
        event = parse_event(record, 0, len(record))
        assert event is not None
        self.last = record
        yield "event", slot, event

    def damaged(self, record: bytes) -> None:
        if self.last is not None and _differing(self.last, record) <= COPY_DIFF_BYTES:
            self.counts.copies += 1  # a damaged copy of the record read just before
        elif not self.pending or _differing(self.pending[-1], record) > COPY_DIFF_BYTES:
            self.pending.append(record)  # (else both copies of one record are damaged)

    def flush(self, slot: int) -> Iterator[tuple]:
        """The damaged records left without a copy, as lost events at ``slot``."""
        for record in self.pending:
            kind, frame = kind_in(record), frame_in(record, slot)
            self.counts.lost_events += 1
            self.counts.lost.append((kind, frame))
            yield "event", slot, lost_event(kind, slot, frame)
        self.pending = []
        self.last = None



def _event_start(gap: bytes) -> int | None:
    """Where a damaged event record ending ``gap`` (its ``E$`` the last bytes) begins: where
    its length field says (the start + 20 + length = the end), else at its ``$E`` marker;
    None when the gap does not end like an event record."""
    n = len(gap)
    if n < EVENT_OVERHEAD or not gap.endswith(EVENT_END):
        return None
    lo = max(0, n - EVENT_OVERHEAD - MAX_EVENT_PAYLOAD)
    b = np.frombuffer(gap, np.uint8).astype(np.int64)
    x = np.arange(lo, n - EVENT_OVERHEAD + 1)
    length = b[x + 10] | (b[x + 11] << 8) | (b[x + 12] << 16) | (b[x + 13] << 24)
    hit = np.flatnonzero(x + EVENT_OVERHEAD + length == n)
    if hit.size:
        return int(x[hit[0]])
    marker = gap.rfind(EVENT_START, lo + 8, n - EVENT_OVERHEAD + 9)
    return marker - 8 if marker >= 8 else None


def damaged_events(gap: bytes) -> tuple[int, list[bytes]]:
    """A damaged stretch read from its end: (bytes before its damaged event records, those
    records in file order). A record whose ``$E`` marker or length field was hit still ends
    with ``E$`` and says (by its length field, or its marker) where it began, so damage to it
    costs no frame slot."""
    records: list[bytes] = []
    end = len(gap)
    while (start := _event_start(gap[:end])) is not None and start < end:
        records.insert(0, gap[start:end])
        end = start
    return end, records



def event_at(buf: bytes, q: int, eof: bool) -> tuple[str, int]:
    """Is there an event record at ``q``? ("yes", size), ("no", 0) or ("more", size) when
    its bytes are not all in ``buf`` yet (never at the end of the file)."""
    if q + 14 > len(buf):
        return ("no", 0) if eof else ("more", 14)
    size = event_size_at(buf, q)
    if size is None:
        return "no", 0
    if q + size > len(buf):
        return ("no", 0) if eof else ("more", size)
    return ("yes", size) if parse_event(buf, q, size) is not None else ("no", 0)


def find_record(buf: bytes, start: int, eof: bool, events: bool) -> tuple[int | None, str]:
    """The first offset ≥ ``start`` where a record begins: a frame record confirmed by the
    next record (or the end of the file), or an intact event record. (offset, "found"),
    (None, "none"), or (offset, "more") when deciding needs bytes beyond ``buf``."""
    n = len(buf)
    s = start + 8
    a = buf.find(FRAME_START, s)
    b = buf.find(EVENT_START, s) if events else -1
    while a >= 0 or b >= 0:
        if a >= 0 and (b < 0 or a < b):
            q = a - 8
            if q + RECORD_SIZE > n:
                if not eof:
                    return q, "more"
            elif is_frame_record_at(buf, q):
                nxt = q + RECORD_SIZE
                if nxt + RECORD_SIZE <= n and is_frame_record_at(buf, nxt):
                    return q, "found"
                state = event_at(buf, nxt, eof) if events else ("no", 0)
                if state[0] == "yes":
                    return q, "found"
                if nxt + RECORD_SIZE > n:
                    if eof:
                        return q, "found"  # no room for a confirming record: the end
                    return q, "more"
                if state[0] == "more":
                    return q, "more"
            a = buf.find(FRAME_START, a + 1)
        else:
            q = b - 8
            state = event_at(buf, q, eof)
            if state[0] == "yes":
                return q, "found"
            if state[0] == "more":
                return q, "more"
            b = buf.find(EVENT_START, b + 1)
    return None, "none"

__all__ = ["COPY_DIFF_BYTES", "LOOKAHEAD", "Copies", "Counts", "damaged_events", "event_at",
           "find_record", "frame_in", "kind_in", "lost_event"]
