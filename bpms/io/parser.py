"""Streaming frame parser: arbitrary byte chunks in, whole 340-byte frames out.

The frame has no sequence number and no checksum (SPEC §2), and its payload may contain the
marker bytes ``$#`` / ``#$`` by chance. The parser therefore accepts a frame only when a
``$#`` is followed, exactly 338 bytes later, by ``#$``; anything else is discarded byte range
by byte range and the parser resynchronises on the next ``$#``.

Limitation (inherent to the protocol): a truncated frame whose chance ``$#`` lines up with a
chance ``#$`` 338 bytes later can assemble a false frame. The odds are about 1 in 65,536 per
resynchronisation attempt; downstream plausibility checks (error bits, magnitudes) catch it.
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
    counts the leftover bytes as discarded.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
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
        buf = self._buf
        buf += chunk
        out: list[bytes] = []
        pos = 0
        n = len(buf)
        while True:
            start = buf.find(START, pos)
            if start < 0:
                # Keep a trailing '$': it may be the first half of the next start marker.
                keep = 1 if n > pos and buf[n - 1] == START[0] else 0
                self._discard(n - keep - pos)
                pos = n - keep
                break
            if start > pos:
                self._discard(start - pos)
            if n - start < FRAME_SIZE:
                pos = start
                break
            if buf[start + END_OFFSET : start + FRAME_SIZE] == END:
                out.append(bytes(buf[start : start + FRAME_SIZE]))
                self._in_discard = False
                pos = start + FRAME_SIZE
            else:
                # A start marker without its end marker: drop the '$' and look further.
                self._discard(1)
                pos = start + 1
        if pos:
            del buf[:pos]
        self.stats.frames += len(out)
        return out

    @property
    def pending(self) -> int:
        """Bytes held back waiting for the rest of a frame."""
        return len(self._buf)

    def flush(self) -> None:
        """End of stream: whatever is still buffered is an incomplete frame; count it."""
        self._discard(len(self._buf))
        self._buf.clear()
        self._in_discard = False
