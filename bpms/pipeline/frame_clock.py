"""A de-jittered frame clock: the suit's fixed sampling period anchored to receive times.

The suit samples every ``period`` s (20 ms), but Bluetooth delivers frames late and in bursts
(up to ~300 ms). A frame can arrive late, never early, so ``arrival_k - k * period`` is the
clock offset plus a non-negative delay: its lower envelope is the offset. The clock keeps

- a running minimum of ``arrival_k - k * period``, lowered at once by an earlier-than-expected
  frame (slewed so that stamps stay strictly increasing), and
- a block minimum over the last ``block`` frames: when every frame of a block arrived later
  than the envelope (frames lost on the link, the suit's crystal slower than nominal), the
  envelope moves up to that block's minimum;
- a gap: when ``late_frames`` frames in a row arrive more than ``late_s`` after the envelope
  (longer than any Bluetooth delay: the link was silent and the count of accepted frames went
  on), the envelope jumps to the smallest of them at once.

``stamp(k) = offset + k * period - link_delay``: the estimated sampling time of frame ``k`` on
the receive clock (seconds, whatever clock the arrival times are on, e.g. LSL's
``local_clock``). A discontinuity (new stream, reconnection, seek) re-anchors the clock.
"""

from __future__ import annotations

import math


class FrameClock:
    """Stamps frames ``(index, arrival)`` with de-jittered sampling times, seconds.

    period: the suit's frame period, s (replay at speed ``s``: ``period / s``);
    link_delay: the configured constant delay suit → host, s, subtracted from every stamp;
    block: frames per block for the upward envelope correction;
    min_step: the smallest step between two consecutive stamps, as a fraction of the period.
    """

    def __init__(self, period: float = 0.02, link_delay: float = 0.0, block: int = 100,
                 min_step: float = 0.5, late_s: float = 0.5, late_frames: int = 5) -> None:
        if period <= 0:
            raise ValueError("period must be positive")
        self.period = float(period)
        self.link_delay = float(link_delay)
        self.block = max(1, int(block))
        self.min_step = float(min_step)
        self.late_s = float(late_s)
        self.late_frames = max(1, int(late_frames))
        self.reset()

    def reset(self) -> None:
        """Forget the anchor: the next frame starts a new stream."""
        self._offset = math.nan
        self._block_min = math.inf
        self._block_count = 0
        self._last_index: int | None = None
        self._last_stamp = -math.inf
        self._late: list[float] = []
        self.reanchors = 0

    def stamp(self, index: int, arrival: float, discontinuity: bool = False) -> float:
        """The de-jittered time of frame ``index`` that arrived at ``arrival`` (s)."""
        if self._last_index is not None and (discontinuity or index <= self._last_index):
            self._reanchor()
        residual = arrival - index * self.period
        if math.isnan(self._offset) or residual < self._offset:
            self._offset = residual
        if residual - self._offset > self.late_s:
            self._late.append(residual)
            if len(self._late) >= self.late_frames:  # a gap, not jitter: move up now
                self._offset = min(self._late)
                self._late.clear()
                self._block_min, self._block_count = math.inf, 0
        else:
            self._late.clear()
        self._block_min = min(self._block_min, residual)
        self._block_count += 1
        if self._block_count >= self.block:
            if self._block_min > self._offset:
                self._offset = self._block_min
            self._block_min = math.inf
            self._block_count = 0
        t = self._offset + index * self.period - self.link_delay
        # an earlier frame lowered the envelope (or a new stream began): slew instead of
        # stepping back in time
        steps = 1 if self._last_index is None else max(1, index - self._last_index)
        t = max(t, self._last_stamp + self.min_step * self.period * steps)
        self._last_index = index
        self._last_stamp = t
        return t

    def _reanchor(self) -> None:
        last = self._last_stamp
        self.reset()
        self._last_stamp = last  # stamps stay increasing across a re-anchor
        self.reanchors += 1

    def stamp_many(self, indices, arrivals, discontinuity: bool = False) -> list[float]:
        """:meth:`stamp` for a run of frames (the first may carry ``discontinuity``)."""
        return [self.stamp(int(i), float(a), discontinuity and k == 0)
                for k, (i, a) in enumerate(zip(indices, arrivals, strict=True))]
