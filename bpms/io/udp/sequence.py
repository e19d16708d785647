"""Sequence tracking of one message type (docs/udp.md "Sequence numbers"): exact loss,
duplicate and reorder accounting across sessions and the 2**32 wrap."""

from __future__ import annotations

import bisect
from collections import deque
from enum import IntEnum

from bpms.io.udp.codec import SEQ_MOD

#: Reorder window in sequence numbers (~11 min at 50 Hz). See docs/udp.md "Sequence numbers".
REORDER_WINDOW = 1 << 15


class Verdict(IntEnum):
    NEW = 0  # in order (possibly after a gap), or the first of a session
    REORDERED = 1  # fills an earlier gap (arrived after a higher sequence number)
    DUPLICATE = 2  # this sequence number was already received in this session
    STALE = 3  # from a session that has since been replaced: dropped


def _signed(d: int) -> int:
    d %= SEQ_MOD
    return d - SEQ_MOD if d >= SEQ_MOD // 2 else d


class SequenceTracker:
    """Exact loss / duplicate / reorder accounting of one message type (docs/udp.md).

    Within a session, sequence numbers compare by serial-number arithmetic modulo 2**32, so
    the wrap 2**32−1 → 0 is seamless. A new session id, or a jump back by more than
    ``window``, starts a new session (a sender restart); gaps left open in the old session
    become final losses. Datagrams of a replaced session are STALE and dropped.

    Gaps are kept as ranges of unwrapped sequence numbers, so the cost of one datagram is
    O(log gaps) whatever the jump (a jump of 40,000 costs what a jump of 2 does).
    """

    def __init__(self, window: int = REORDER_WINDOW) -> None:
        self.window = window
        self.session: int | None = None
        self._first = 0  # unwrapped
        self._highest = 0  # unwrapped
        self._starts: list[int] = []  # open gaps [start, end), sorted, disjoint
        self._ends: list[int] = []
        self._open = 0  # sequence numbers inside the open gaps
        self._retired: deque[int] = deque(maxlen=8)
        self.unique = 0
        self.duplicated = 0
        self.reordered = 0
        self.stale = 0
        self.restarts = 0
        self.lost_final = 0

    @property
    def first(self) -> int:
        return self._first % SEQ_MOD

    @property
    def highest(self) -> int:
        return self._highest % SEQ_MOD

    @property
    def lost(self) -> int:
        """Sequence numbers not received: final losses plus gaps still open in the window."""
        return self.lost_final + self._open

    @property
    def pending(self) -> int:
        """Gaps still inside the reorder window (a late datagram may still fill them)."""
        return self._open

    def is_retired(self, session: int) -> bool:
        return session in self._retired

    def _start(self, session: int, seq: int) -> None:
        self.lost_final += self._open
        self._starts.clear()
        self._ends.clear()
        self._open = 0
        self.session = session
        self._first = self._highest = seq

    def _add_gap(self, start: int, end: int) -> None:
        """Open the gap [start, end) (unwrapped), kept to the window below the highest."""
        floor = self._highest - self.window
        if start < floor:
            self.lost_final += min(end, floor) - start
            start = floor
        if start >= end:
            return
        k = bisect.bisect_left(self._starts, start)
        self._starts.insert(k, start)
        self._ends.insert(k, end)
        self._open += end - start

    def _prune(self) -> None:
        """Gaps that left the window (more than ``window`` below the highest) are final."""
        floor = self._highest - self.window
        while self._starts and self._starts[0] < floor:
            start, end = self._starts[0], self._ends[0]
            cut = min(end, floor)
            self.lost_final += cut - start
            self._open -= cut - start
            if cut == end:
                del self._starts[0], self._ends[0]
            else:
                self._starts[0] = cut

    def _fill(self, u: int) -> bool:
        """Remove ``u`` from the open gaps; False when it was not missing."""
        k = bisect.bisect_right(self._starts, u) - 1
        if k < 0 or u >= self._ends[k]:
            return False
        start, end = self._starts[k], self._ends[k]
        self._open -= 1
        if start == u and end == u + 1:
            del self._starts[k], self._ends[k]
        elif start == u:
            self._starts[k] = u + 1
        elif end == u + 1:
            self._ends[k] = u
        else:
            self._ends[k] = u
            self._starts.insert(k + 1, u + 1)
            self._ends.insert(k + 1, end)
        return True

    def observe(self, session: int, seq: int) -> Verdict:
        """Account for one well-formed datagram; tell the caller what it was."""
        if self.session is None:
            self._start(session, seq)
            self.unique += 1
            return Verdict.NEW
        if session != self.session:
            if session in self._retired:
                self.stale += 1
                return Verdict.STALE
            self._retired.append(self.session)
            self.restarts += 1
            self._start(session, seq)
            self.unique += 1
            return Verdict.NEW
        d = _signed(seq - self._highest)
        u = self._highest + d
        if d > 0:
            old = self._highest
            self._highest = u
            self._prune()
            self._add_gap(old + 1, u)
            self.unique += 1
            return Verdict.NEW
        if d == 0:
            self.duplicated += 1
            return Verdict.DUPLICATE
        if d < -self.window:
            # Same session id yet far behind: a sender that restarted without a new session.
            self.restarts += 1
            self._start(session, seq)
            self.unique += 1
            return Verdict.NEW
        if u < self._first:
            # Earlier than anything seen so far in this session: extends the session backwards.
            self._add_gap(u + 1, self._first)
            self._first = u
            self.reordered += 1
            self.unique += 1
            return Verdict.REORDERED
        if self._fill(u):
            self.reordered += 1
            self.unique += 1
            return Verdict.REORDERED
        self.duplicated += 1
        return Verdict.DUPLICATE
