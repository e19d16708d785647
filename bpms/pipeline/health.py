"""Live-path health: what the pipeline could not do, counted and shown (docs/pipeline.md).

Two different losses, never mixed:

- **frames not filtered**: frames received (and recorded raw) that the processing thread never
  saw, because its queue was full (a source faster than the filters, e.g. after a stall). They
  are holes in the filtered file and the pose stream; each is marked in the filtered file by a
  row with ``hole = 1`` at its place. Shown prominently whenever non-zero.
- **display samples skipped**: processed samples a slow consumer (the GUI, a plot) did not take
  from its bounded mailbox. Nothing is missing from any file.

The acquisition thread calls :meth:`PipelineHealth.not_filtered_frame`; the processing thread
takes the pending holes (:meth:`PipelineHealth.take_holes`) and writes them in frame order with
the processed rows (:func:`merge_holes`).
"""

from __future__ import annotations

import queue
from dataclasses import dataclass

import numpy as np

#: Frames the processing queue holds before a live source's frames skip processing
#: (60 s at 50 Hz).
MAX_BACKLOG_FRAMES = 3000


@dataclass(frozen=True, slots=True)
class Hole:
    """A frame received but not filtered: its index in the source and host time (s since
    the epoch)."""

    index: int
    host_time: float


class PipelineHealth:
    """Counters of the live path. ``not_filtered`` is written by the acquisition thread only;
    ``holes_marked`` by the processing thread only (no lock needed)."""

    def __init__(self) -> None:
        self.not_filtered = 0
        self.holes_marked = 0
        self._holes: queue.SimpleQueue[Hole] = queue.SimpleQueue()

    def not_filtered_frame(self, index: int, host_time: float) -> None:
        """A frame that skips processing (acquisition thread)."""
        self.not_filtered += 1
        self._holes.put(Hole(index, host_time))

    def take_holes(self) -> list[Hole]:
        """The holes noted since the last call, in arrival order (processing thread)."""
        out = []
        while not self._holes.empty():  # (one consumer: what it sees waiting stays there)
            out.append(self._holes.get_nowait())
        return out


def merge_holes(indices: np.ndarray, holes: list[Hole]) -> tuple[np.ndarray, np.ndarray,
                                                                  np.ndarray, list[Hole]]:
    """Place ``holes`` among processed frames of source ``indices[N]`` (ascending).

    Returns (order, hole_index, hole_host, later): ``order[M]`` the row order of the merged
    block as positions, non-negative ``k`` = processed frame ``k``, negative ``-1 - j`` =
    hole ``j`` of (hole_index, hole_host); ``later``: holes after the last processed frame
    (kept for the next block)."""
    last = int(indices[-1]) if len(indices) else -1
    now = [h for h in holes if h.index <= last]
    later = [h for h in holes if h.index > last]
    hole_index = np.array([h.index for h in now], dtype=np.int64)
    hole_host = np.array([h.host_time for h in now], dtype=np.float64)
    keys = np.concatenate([np.asarray(indices, dtype=np.int64), hole_index])
    ids = np.concatenate([np.arange(len(indices)), -1 - np.arange(len(now))])
    order = ids[np.argsort(keys, kind="stable")]
    return order, hole_index, hole_host, later


def health_text(not_filtered: int, backlog: int, display_skipped: int) -> str:
    """The status line's health part: frames not filtered first and in capitals when
    non-zero, then the backlog and the display samples skipped."""
    lost = (f"NOT FILTERED {not_filtered} frames" if not_filtered
            else "not filtered 0")
    return f"{lost}  backlog {backlog}  display skipped {display_skipped}"


def write_with_holes(writer, indices: np.ndarray, host_times: np.ndarray,
                     arrays: dict[str, np.ndarray], holes: list[Hole], dt: float
                     ) -> tuple[int, int, list[Hole]]:
    """Write processed frames (source ``indices[N]``, ``host_times[N]`` s since the epoch,
    per-group ``arrays`` of :meth:`bpms.io.filtered_file.writer.FilteredWriter.write_block`) with a
    marked NaN row (``hole`` = 1) for each hole among them, in frame order. Returns (rows
    written, holes marked, holes after the last frame: pass them with the next block)."""
    from bpms.io.timebase import stream_time_of

    later: list[Hole] = []
    if holes:  # (the usual case, none: nothing to merge)
        order, hole_index, hole_host, later = merge_holes(indices, holes)
    if not holes or not len(hole_index):
        writer.write_block(stream_time_of(indices, dt), host_time=host_times, **arrays)
        return len(indices), 0, later
    is_hole = order < 0
    pick = np.where(is_hole, 0, order)
    hole_pick = np.where(is_hole, -1 - order, 0)
    index = np.where(is_hole, hole_index[hole_pick], np.asarray(indices)[pick])
    host = np.where(is_hole, hole_host[hole_pick], np.asarray(host_times)[pick])
    merged = {}
    for name, values in arrays.items():
        m = np.asarray(values, dtype=np.float64)[pick]
        m[is_hole] = np.nan
        merged[name] = m
    writer.write_block(stream_time_of(index, dt), host_time=host, hole=is_hole, **merged)
    return len(order), int(is_hole.sum()), later


def write_trailing_holes(writer, holes: list[Hole], dt: float) -> int:
    """Marked rows for holes after the last processed frame (when a recording stops)."""
    from bpms.io.timebase import stream_time_of

    if not holes:
        return 0
    holes = sorted(holes, key=lambda h: h.index)
    writer.write_holes(stream_time_of(np.array([h.index for h in holes]), dt),
                       np.array([h.host_time for h in holes]))
    return len(holes)
