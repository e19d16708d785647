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
from bpms.io.raw_layout import parse_event
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


__all__ = ["COPY_DIFF_BYTES", "LOOKAHEAD", "Copies", "Counts", "frame_in", "kind_in",
           "lost_event"]
