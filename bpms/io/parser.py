"""Streaming frame parser: arbitrary byte chunks in, whole 340-byte frames out.

The frame has no sequence number and no checksum (docs/frame-format.md); its payload may contain the
marker bytes ``$#`` / ``#$`` by chance. The parser therefore accepts a *candidate* only when a
``$#`` is followed, exactly 338 bytes later, by ``#$``; anything else is discarded byte range
by byte range and the parser resynchronises on the next ``$#``.

Two candidates overlapping by two bytes or more cannot both be frames. A candidate followed
back to back by another whole candidate (the next frame) is an intact frame, whatever marker
bytes its payload holds: it wins, so that a chance ``$#`` in its payload with a chance ``#$``
338 bytes later (in the next frame) cannot drop it. Otherwise the later one wins: a frame cut
short followed by an intact frame makes a false candidate that borrows the intact frame's
first bytes. The check costs one ``find`` per frame and delays a frame only when its payload
holds a ``$#`` (when a rival shows up, until the next frame arrives).
A one-byte overlap is allowed: the final ``$`` of a frame may also be the first byte of the
next frame when that frame lost its own (or the frame lost its last byte), so both come out.

Limitation (inherent to the protocol): such chance alignments can still make a false frame or
drop a true one, about once per 65,536 resynchronisations or marker-bearing payloads.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from bpms.io.frames import END, END_OFFSET, FRAME_SIZE, START

log = logging.getLogger(__name__)


@dataclass
class ParserStats:
    """Counters of a :class:`FrameParser` since creation (or the last ``reset_stats``)."""

    frames: int = 0
    bytes_in: int = 0
    discarded_bytes: int = 0
    resyncs: int = 0  # number of discarded byte ranges

    def snapshot(self) -> ParserStats:
        return ParserStats(self.frames, self.bytes_in, self.discarded_bytes, self.resyncs)


class FrameParser:
    """Incremental parser. ``feed(chunk)`` returns the frames completed by that chunk, in order.

    Chunks may be any size, from one byte to megabytes. ``flush()`` at the end of a stream
    returns any frame still held back and counts the leftover bytes as discarded.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self._shared_dollar = False  # buf[0] is the last accepted frame's final '$'

        self._in_discard = False  # inside a discarded byte range (counts one resync per range)
        self.stats = ParserStats()

    def _discard(self, n: int) -> None:
        if n <= 0:
            return
        self.stats.discarded_bytes += n
        if not self._in_discard:
            self.stats.resyncs += 1
            self._in_discard = True
            log.debug("discarding bytes: resynchronising on the next $#")

    def feed(self, chunk: bytes | bytearray | memoryview) -> list[bytes]:
        """Append ``chunk`` and return every frame it completes."""
        self.stats.bytes_in += len(chunk)
        self._buf += chunk
        return self._scan(final=False)

    def flush(self) -> list[bytes]:
        """End of stream: return any frame still held back for an overlap check, and count
        the remaining bytes (an incomplete frame) as discarded."""
        out = self._scan(final=True)
        held = len(self._buf) - (1 if self._shared_dollar else 0)
        self._discard(held)
        self._buf.clear()
        self._shared_dollar = False
        self._in_discard = False
        return out

    def _scan(self, final: bool) -> list[bytes]:
        buf = self._buf
        out: list[bytes] = []
        n = len(buf)
        pos = 0
        # When ``shared``, buf[pos] is the last accepted frame's final '$': it may also be the
        # first byte of the next frame (if that frame lost its own), but is never discarded.
        shared = self._shared_dollar
        while True:
            start = buf.find(START, pos)
            if start < 0:
                # Keep a trailing '$': it may be the first half of the next start marker.
                keep = n - 1 if n > pos and buf[n - 1] == START[0] else n
                if shared and keep > pos:
                    pos, shared = pos + 1, False
                self._discard(keep - pos)
                pos = keep
                break
            if shared and start > pos:
                pos, shared = pos + 1, False
            self._discard(start - pos)
            pos = start
            if n - start < FRAME_SIZE:
                break
            if buf[start + END_OFFSET : start + FRAME_SIZE] != END:
                # A start marker without its end marker: drop the '$' and look further.
                if not shared:
                    self._discard(1)
                pos, shared = start + 1, False
                continue
            rival = self._overlapping_candidate(buf, start, final)
            if rival is None:  # a rival candidate needs more bytes to decide
                break
            if rival > start:
                chained = self._chained(buf, start, final)
                if chained is None:  # the next frame decides: wait for it
                    break
                if chained:  # an intact frame whose payload holds markers by chance
                    rival = start
            if rival > start:
                self._discard(rival - start - (1 if shared else 0))
                pos, shared = rival, False
                continue
            out.append(bytes(buf[start : start + FRAME_SIZE]))
            self._in_discard = False
            pos, shared = start + FRAME_SIZE - 1, True
        if pos:
            del buf[:pos]
        self._shared_dollar = shared
        self.stats.frames += len(out)
        return out

    @staticmethod
    def _overlapping_candidate(buf: bytearray, start: int, final: bool) -> int | None:
        """Position of a later candidate overlapping the one at ``start`` by two bytes or more
        (the later one wins), ``start`` itself when there is none, or None when more bytes are
        needed to decide. A one-byte overlap is allowed: see ``shared`` in ``_scan``."""
        n = len(buf)
        limit = min(n, start + FRAME_SIZE)
        q = buf.find(START, start + 1, limit)
        while q >= 0:
            if n < q + FRAME_SIZE:
                return start if final else None
            if buf[q + END_OFFSET : q + FRAME_SIZE] == END:
                return q
            q = buf.find(START, q + 1, limit)
        return start

    @staticmethod
    def _chained(buf: bytearray, start: int, final: bool) -> bool | None:
        """True when a whole candidate follows the one at ``start`` back to back (at
        ``start + 340``, or at ``start + 339`` sharing its final ``$``): then that candidate is
        an intact frame, whatever marker bytes its payload holds. None: more bytes needed."""
        n = len(buf)
        for nxt in (start + FRAME_SIZE, start + FRAME_SIZE - 1):
            if n < nxt + FRAME_SIZE:
                if n >= nxt + 2 and buf[nxt : nxt + 2] != START:
                    continue  # no start marker there: not chained at this offset
                return False if final else None
            if buf[nxt : nxt + 2] == START and buf[nxt + END_OFFSET : nxt + FRAME_SIZE] == END:
                return True
        return False

    @property
    def pending(self) -> int:
        """Bytes held back waiting for the rest of a frame."""
        return len(self._buf)
