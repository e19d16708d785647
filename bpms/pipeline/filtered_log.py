"""The filtered file of a live session (docs/pipeline.md "Recording"): :class:`FilteredLog`.

Processed rows are queued and written every :data:`FILTERED_BATCH` frames (and when the source
goes quiet or logging stops), so the per-write work is paid once per batch instead of once per
frame, in frame order with a marked row for every frame that skipped processing
(:mod:`bpms.pipeline.health`). When a raw recording is made beside it, the rows count from the
raw file's first frame (slot × dt, as ``bpms filter`` and replay of that file write them);
frames processed before the raw file's first frame are not written. Runs in the processing
thread only.
"""

from __future__ import annotations

import contextlib
import functools
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from bpms.io.events import FrameEvent
from bpms.io.filtered_file.writer import FilteredWriter
from bpms.pipeline.health import Hole, PipelineHealth, write_trailing_holes, write_with_holes

if TYPE_CHECKING:
    from bpms.filter.result import Result
    from bpms.pipeline.raw_logger import RawLogger

#: Processed frames queued before they are written to the filtered file (1 s at 50 Hz, the
#: flush interval's default): the rows' numbers and their text are made once per batch, whose
#: fixed cost would otherwise be a large part of each frame's.
FILTERED_BATCH = 50


class FilteredLog:
    """The filtered file being written (none while :attr:`writer` is None). ``dt``: the frame
    period in force (s, a callable: it may change at run time); ``note(text)``: the session's
    warning when the file stops."""

    def __init__(self, health: PipelineHealth, dt: Callable[[], float],
                 flush_interval_s: float, note: Callable[[str], None]) -> None:
        self.health = health
        self.dt = dt
        self.flush_interval_s = flush_interval_s
        self.note = note
        self.writer: FilteredWriter | None = None
        self._raw: RawLogger | None = None  # the raw recording made beside it
        self._holes: list[Hole] = []  # holes after the last processed frame, not yet written
        self._pending: list[tuple[list[FrameEvent], Result]] = []
        self._pending_frames = 0
        self._flushed = 0.0
        self._batch_bytes = 0  # bytes the last batch took: the next one is about as large

    @property
    def pending(self) -> bool:
        return bool(self._pending)

    def open(self, writer: FilteredWriter, raw: RawLogger | None) -> None:
        """Start writing to ``writer``; ``raw``: the raw logger of the recording beside it."""
        self.writer, self._raw = writer, raw
        self._batch_bytes = 0

    def log(self, events: list[FrameEvent], result: Result, recording: Any) -> None:
        """Queue the processed rows of ``events``; write them once a batch is full."""
        if self.writer is None:
            self._holes = []
            self.health.take_holes()
            return
        self._pending.append((events, result))
        self._pending_frames += len(events)
        if self._pending_frames >= FILTERED_BATCH:
            self.write(recording)

    def write(self, recording: Any) -> None:
        """Write the queued rows and a marked row for every frame that skipped processing,
        in frame order. ``recording``: the session's RecordingStatus (rows counted, the disk
        reserve's stop) or None."""
        pending, self._pending, self._pending_frames = self._pending, [], 0
        writer = self.writer
        holes = self._take_holes()
        if writer is None or not pending:
            self._holes = holes if writer is not None else []
            return
        events = [e for batch, _ in pending for e in batch]
        indices = np.array([e.index for e in events], dtype=np.int64)
        host_times = np.array([e.host_time for e in events])
        # the rows' numbers computed once for the whole batch (the same functions as per frame)
        concat, filtered_arrays = _filtered_rows()
        arrays = filtered_arrays(concat([r for _, r in pending]), writer.groups)
        origin = self._origin()
        end = self._end()
        if origin or end is not None:
            # rows on the raw file's clock (slot × dt): frames before its first and, once it
            # has ended, after its last are not in it
            keep = indices >= origin
            if end is not None:
                keep &= indices <= end
            if not keep.all():
                indices, host_times = indices[keep], host_times[keep]
                arrays = {g: v[keep] for g, v in arrays.items()}
            indices = indices - origin
            if not len(indices):
                self._holes = holes
                return
        try:
            if recording is not None and recording.filtered_stopped:
                raise OSError(recording.filtered_stopped)  # the raw file goes first
            reserve = self._raw.reserve if self._raw is not None else None
            if reserve is not None and reserve.low(about_to_write=self._batch_bytes):
                raise OSError(reserve.reason)  # a batch must not eat the raw file's reserve
            before = writer.bytes_written
            rows, marked, self._holes = write_with_holes(writer, indices, host_times, arrays,
                                                         holes, self.dt())
            self._batch_bytes = writer.bytes_written - before
            self.health.holes_marked += marked
            if recording is not None:
                recording.filtered_rows += rows
            now = time.monotonic()
            if now - self._flushed >= self.flush_interval_s:
                writer.flush()
                self._flushed = now
        except OSError as exc:
            self.writer = None
            with contextlib.suppress(OSError):
                writer.close()
            self.note(f"filtered recording stopped: {exc}")

    def close(self, recording: Any) -> None:
        """Write what is queued, the holes after the last frame, and close the file."""
        if self.writer is not None:
            self.write(recording)
        writer, self.writer = self.writer, None
        self._pending, self._pending_frames = [], 0
        if writer is not None:
            holes, self._holes = self._take_holes(), []
            try:
                self.health.holes_marked += write_trailing_holes(writer, holes, self.dt())
            finally:
                writer.close()
        self._raw = None

    def _take_holes(self) -> list[Hole]:
        """The holes waiting to be written: those kept from the last block and the new ones,
        on the filtered file's clock (:meth:`_origin`)."""
        origin = self._origin()
        new = self.health.take_holes()
        end = self._end()
        if end is not None:
            new = [h for h in new if h.index <= end]
        if origin:
            new = [Hole(h.index - origin, h.host_time) for h in new if h.index >= origin]
        return [*self._holes, *new]

    def _end(self) -> int | None:
        """The source frame index of the raw recording's last frame once it has ended (the
        session stopped handing it frames; −1 when it got none); None while it goes on or
        without one."""
        raw = self._raw
        if raw is None or not raw.fed_done:
            return None
        return -1 if raw.last_index is None else raw.last_index

    def _origin(self) -> int:
        """The source frame index of the raw recording's slot 0 when one is made beside it; 0
        without one (a played recording's slots, a UDP sender's frame numbers). Before the raw
        file's first frame: an index above every one processed (those frames are not in it)."""
        raw = self._raw
        if raw is None:
            return 0
        first = raw.first_index
        return (1 << 62) if first is None else first


@functools.cache
def _filtered_rows() -> tuple[Callable, Callable]:
    """(:meth:`bpms.filter.result.Result.concat`, :func:`bpms.filter.door.filtered_arrays`),
    imported at the first filtered row (the filter layer is loaded with the processor, not
    with the GUI's start-up window)."""
    from bpms.filter.door import filtered_arrays
    from bpms.filter.result import Result

    return Result.concat, filtered_arrays
