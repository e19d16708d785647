"""Sequence tracking of one message type (docs/udp.md "Sequence numbers"): exact loss,
duplicate and reorder accounting across sessions and the 2**32 wrap; implausible jumps held
back; datagrams that contradict the session (another sender on it) counted."""

from __future__ import annotations

import bisect
from collections import deque
from enum import IntEnum

from bpms.io.udp.codec import SEQ_MOD, SeqRun

#: Reorder window in sequence numbers (~11 min at 50 Hz). See docs/udp.md "Sequence numbers".
REORDER_WINDOW = 1 << 15
#: A jump forward by up to this many numbers is a plausible gap (a minute at 50 Hz): the
#: numbers skipped count as lost. A longer jump, or one back by more than the window, is held.
MAX_PLAUSIBLE_GAP = 3000
#: Consecutive datagrams after a held jump that make the tracker follow it (a sender whose
#: numbers really jumped, e.g. after a long outage); the numbers skipped are not counted lost.
JUMP_CONFIRM = 25
#: Frames remembered by sequence number, to tell a true duplicate from a contradicting one.
DIGESTS_KEPT = 1024
#: A frame arriving this many numbers late is evidence of another sender on the session.
FAR_LATE = 256
#: With a shared key, the reorder window (numbers): anything older, or before the first number
#: followed, is refused as replayed (docs/udp.md "Freshness"). 5 s at 50 Hz.
KEYED_WINDOW = 256


class Verdict(IntEnum):
    NEW = 0  # in order (possibly after a gap), or the first of a session
    REORDERED = 1  # fills an earlier gap (arrived after a higher sequence number)
    DUPLICATE = 2  # this sequence number was already received in this session
    STALE = 3  # from a session that has since been replaced: dropped
    IMPLAUSIBLE = 4  # jumped implausibly far: dropped (held until JUMP_CONFIRM follow it)
    CONFLICT = 5  # received before with a different frame: dropped (another sender)
    RESYNC = 6  # a held jump confirmed: delivered, the numbers start anew from here
    REPLAYED = 7  # keyed: older than the keyed window, or before the session's first: refused


def _signed(d: int) -> int:
    d %= SEQ_MOD
    return d - SEQ_MOD if d >= SEQ_MOD // 2 else d


class SequenceTracker:
    """Exact loss / duplicate / reorder accounting of one message type (docs/udp.md).

    Within a session, sequence numbers compare by serial-number arithmetic modulo 2**32, so
    the wrap 2**32−1 → 0 is seamless. A new session id starts a new session (a sender
    restart); gaps left open in the old session become final losses. Datagrams of a replaced
    session are STALE and dropped. A jump forward by more than :data:`MAX_PLAUSIBLE_GAP` or
    back by more than ``window`` is IMPLAUSIBLE (dropped, not counted lost) until
    :data:`JUMP_CONFIRM` consecutive numbers follow it: then the session goes on from there
    (RESYNC: ``jumps`` forward, ``restarts`` back, for senders that restart without a new id).

    ``digest`` (e.g. a CRC of the frame): a number received again with another digest is a
    CONFLICT, and so is a frame more than :data:`FAR_LATE` numbers late: both count in
    ``conflicts``, the evidence of a second sender on the same session.

    Gaps are kept as ranges of unwrapped sequence numbers, so the cost of one datagram is
    O(log gaps) whatever the jump (a jump of 40,000 costs what a jump of 2 does).

    ``keyed`` (the datagrams are authenticated): freshness is complete. The window shrinks to
    :data:`KEYED_WINDOW`; a number more than that behind the highest, or before the first
    number of the session followed, is REPLAYED (refused, never held, never a jump back), so
    no number is ever accepted twice, however old and whenever the receiver joined.
    """

    def __init__(self, window: int = REORDER_WINDOW, keyed: bool = False) -> None:
        self.keyed = keyed
        self.window = min(window, KEYED_WINDOW) if keyed else window
        self.replayed = 0
        self.session: object | None = None
        self._first = 0  # unwrapped
        self._highest = 0  # unwrapped
        self._starts: list[int] = []  # open gaps [start, end), sorted, disjoint
        self._ends: list[int] = []
        self._open = 0  # sequence numbers inside the open gaps
        self._retired: deque[object] = deque(maxlen=8)
        self.unique = 0
        self.duplicated = 0
        self.reordered = 0
        self.stale = 0
        self.restarts = 0
        self.lost_final = 0
        self.implausible = 0
        self.jumps = 0
        self.conflicts = 0
        self._jump: SeqRun | None = None  # a held jump and the consecutive numbers after it
        self._digests: dict[int, int] = {}  # unwrapped number -> digest, the latest kept
        self._digest_order: deque[int] = deque()

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

    def _start(self, session: object, seq: int, digest: int | None) -> None:
        """A session starts (anew) at number ``seq`` (unwrapped), received: the gaps left
        open are final losses."""
        self.lost_final += self._open
        self._starts.clear()
        self._ends.clear()
        self._open = 0
        self.session = session
        self._first = self._highest = seq
        self._jump = None
        self._digests.clear()
        self._digest_order.clear()
        self._remember(seq, digest)
        self.unique += 1

    def _remember(self, u: int, digest: int | None) -> None:
        if digest is None:
            return
        if u not in self._digests:
            self._digest_order.append(u)
            if len(self._digest_order) > DIGESTS_KEPT:
                self._digests.pop(self._digest_order.popleft(), None)
        self._digests[u] = digest

    def _again(self, u: int, digest: int | None) -> Verdict:
        """Number ``u`` was received before: a duplicate, or a CONFLICT when its frame
        differs."""
        self.duplicated += 1
        known = self._digests.get(u)
        if digest is not None and known is not None and known != digest:
            self.conflicts += 1
            return Verdict.CONFLICT
        return Verdict.DUPLICATE

    def _held(self, seq: int, d: int, digest: int | None) -> Verdict:
        """An implausible jump: held until :data:`JUMP_CONFIRM` consecutive numbers follow."""
        run = self._jump
        if run is None or not run.extend(seq):
            run = self._jump = SeqRun(seq)
        if run.count < JUMP_CONFIRM:
            self.implausible += 1
            return Verdict.IMPLAUSIBLE
        if d < 0:
            self.restarts += 1
        else:
            self.jumps += 1
        self._start(self.session, self._highest + d, digest)
        return Verdict.RESYNC

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

    def observe(self, session: object, seq: int, digest: int | None = None,
                switch: bool = False) -> Verdict:
        """Account for one well-formed datagram of ``session`` (any hashable identity) with
        number ``seq`` and, optionally, a ``digest`` of its contents; tell the caller what it
        was. ``switch``: the caller decided to follow ``session`` from this datagram on (a
        replaced session coming back included)."""
        if self.session is None or session != self.session:
            if self.session is not None:
                if session in self._retired:
                    if not switch:
                        self.stale += 1
                        return Verdict.STALE
                    self._retired.remove(session)
                self._retired.append(self.session)
                self.restarts += 1
            self._start(session, seq, digest)
            return Verdict.NEW
        d = _signed(seq - self._highest)
        u = self._highest + d
        if self.keyed and (d < -self.window or u < self._first):
            self.replayed += 1  # no network delays a datagram this long: a replay
            return Verdict.REPLAYED
        if d > MAX_PLAUSIBLE_GAP or d < -self.window:
            return self._held(seq, d, digest)
        self._jump = None  # the stream goes on where it was: a held jump is forgotten
        if d > 0:
            old = self._highest
            self._highest = u
            self._prune()
            self._add_gap(old + 1, u)
            self._remember(u, digest)
            self.unique += 1
            return Verdict.NEW
        if d == 0:
            return self._again(u, digest)
        if u < self._first:
            # Earlier than anything seen so far in this session: extends the session backwards.
            self._add_gap(u + 1, self._first)
            self._first = u
        elif not self._fill(u):
            return self._again(u, digest)
        if d < -FAR_LATE:
            self.conflicts += 1  # no network reorders this far: another sender's numbers
        self._remember(u, digest)
        self.reordered += 1
        self.unique += 1
        return Verdict.REORDERED
