"""Which sender the receiver listens to (docs/udp.md "One sender at a time" and "Freshness").

A receiver follows one *session* at a time (a session is one sender's run: its session id,
sender id and epoch). The gate decides, for every well-formed datagram, whether it belongs to
the active session, starts the first one, takes over, or is dropped:

- **no takeover of a live session**: another session's datagrams are *foreign* while the
  active session has sent within ``takeover_after_s`` (5 s by default). A newcomer takes over
  only once the active session has been silent that long *and* the newcomer has sent
  ``takeover_datagrams`` (25) consecutive well-formed datagrams (sequence numbers one after
  the other). One forged or replayed datagram during a pause changes nothing.
- **freshness, with a shared key** (version 3 datagrams carry the sender id and the epoch in
  the signed header): per sender id the gate keeps the newest epoch it has followed; a
  datagram with an older epoch is *replayed* (a recording of an earlier run) and refused,
  whatever the silence. An authenticated newer epoch of the sender being followed (the same
  computer started a new run) takes over at once: the old run's datagrams are older from
  then on. Without a key the sender id and epoch are not authenticated and are not used.
- **no lockout**: the session replaced by a takeover after its silence (the *incumbent*: the
  suit that paused, the sender a stranger replaced) takes the receiver back with its first
  datagram that continues its own numbering when the newcomer has been quiet for
  :data:`RETURN_QUIET_S`, and otherwise once it has sent ``return_datagrams`` (10) such
  datagrams in a row, whatever the newcomer does. Until then, and for every other replaced
  session, its datagrams are *stale*: dropped and counted. Another replaced session may come
  back only by the takeover rule.
- **freshness within a session, with a key**: a known session (followed now or before) never
  has a number accepted again: a datagram of a replaced session numbered at or below the
  highest one followed from it is *replayed* (the followed session's own numbers are the
  sequence tracker's, which refuses anything older than its small keyed window).

Pure bookkeeping (no sockets, no clock of its own): the receiver passes the time.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from enum import IntEnum

from bpms.io.udp.codec import SeqRun

#: An active session keeps the receiver until it has been silent this long, s.
TAKEOVER_AFTER_S = 5.0
#: Consecutive well-formed datagrams a newcomer must send before it may take over.
TAKEOVER_DATAGRAMS = 25
#: Newcomers followed at once (the oldest is forgotten first).
MAX_CANDIDATES = 8
#: Replaced sessions remembered (their late datagrams are stale).
MAX_RETIRED = 8
#: Consecutive datagrams, continuing its own numbers, with which the session replaced after
#: its silence (the incumbent) takes the receiver back (0.2 s at 50 Hz).
RETURN_DATAGRAMS = 10
#: How far (sequence numbers) past the last one followed the incumbent's return may start.
RETURN_GAP = 3000
#: The incumbent returns at its first datagram when the session followed has been silent
#: this long (s): the newcomer has gone quiet (no live sender pauses 12 frames at 50 Hz).
RETURN_QUIET_S = 0.25
_MOD = 1 << 32


def _ahead(seq: int, top: int) -> int:
    """Signed serial distance ``seq − top`` (RFC 1982, modulo 2**32)."""
    d = (seq - top) % _MOD
    return d - _MOD if d >= _MOD // 2 else d


@dataclass(frozen=True)
class SessionKey:
    """One sender's run: session id, sender id and epoch (µs; both 0 before version 3)."""

    session: int
    sender: int = 0
    epoch: int = 0

    def __str__(self) -> str:
        return f"{self.session:08x}"


class Admission(IntEnum):
    ACTIVE = 0  # a datagram of the session being followed
    FIRST = 1  # the first session: followed from this datagram on
    TAKEOVER = 2  # a newcomer replaces the active session from this datagram on
    FOREIGN = 3  # another session while the active one is live, or not yet 25 in a row
    STALE = 4  # a session that was replaced
    REPLAYED = 5  # keyed: older than the newest epoch followed for its sender, or a number
    #              of a replaced session at or below the highest followed from it
    RETURN = 6  # the incumbent (replaced after its silence) takes the receiver back


@dataclass(frozen=True)
class Takeover:
    """A takeover, for the log and the status: who replaced whom after how much silence."""

    old: SessionKey
    new: SessionKey
    silent_s: float
    at: float  # the receiver's monotonic time
    newer_run: bool = False  # keyed: the same sender's newer epoch (no silence needed)
    returned: bool = False  # the incumbent came back (no silence of the newcomer needed)


class SessionGate:
    """The takeover and freshness rules above. ``keyed``: datagrams are authenticated (the
    receiver has a shared key), so sender ids and epochs can be trusted."""

    def __init__(self, takeover_after_s: float = TAKEOVER_AFTER_S,
                 takeover_datagrams: int = TAKEOVER_DATAGRAMS, keyed: bool = False,
                 return_datagrams: int = RETURN_DATAGRAMS) -> None:
        self.takeover_after_s = takeover_after_s
        self.takeover_datagrams = takeover_datagrams
        self.return_datagrams = return_datagrams
        self.keyed = keyed
        #: the session replaced after its silence, and its next number: it may come back
        self.incumbent: SessionKey | None = None
        self._incumbent_run: SeqRun | None = None
        #: per session (followed now or before): the highest number followed, plausible steps
        self._top: OrderedDict[SessionKey, int] = OrderedDict()
        self.active: SessionKey | None = None
        self.last_active = -float("inf")  # the active session's last datagram, monotonic s
        self.last_takeover: Takeover | None = None
        self.takeovers = 0
        self._candidates: OrderedDict[SessionKey, SeqRun] = OrderedDict()
        self._retired: OrderedDict[SessionKey, None] = OrderedDict()
        self._newest_epoch: dict[int, int] = {}  # keyed: sender id -> newest epoch followed

    def _follow(self, key: SessionKey, now: float, seq: int) -> None:
        if self.active is not None:
            self._retired[self.active] = None
            while len(self._retired) > MAX_RETIRED:
                self._retired.popitem(last=False)
        self._retired.pop(key, None)
        self.active = key
        self.last_active = now
        self._candidates.pop(key, None)
        self._incumbent_run = None
        self._top[key] = seq
        self._top.move_to_end(key)
        while len(self._top) > MAX_RETIRED + 1:
            self._top.popitem(last=False)
        if self.keyed:
            self._newest_epoch[key.sender] = max(key.epoch,
                                                 self._newest_epoch.get(key.sender, 0))

    def followed_to(self, key: SessionKey, seq: int) -> None:
        """The session followed went on from number ``seq`` (a jump its tracker confirmed):
        its highest number followed is that one."""
        if key == self.active:
            self._top[key] = seq

    def _switch(self, key: SessionKey, seq: int, now: float, newer_run: bool = False,
                returned: bool = False) -> None:
        old = self.active
        assert old is not None
        self.last_takeover = Takeover(old, key, now - self.last_active, now, newer_run,
                                      returned)
        self.takeovers += 1
        # the session replaced because it fell silent may take the receiver back at once
        self.incumbent = None if (newer_run or returned) else old
        self._follow(key, now, seq)

    def _returning(self, key: SessionKey, seq: int, now: float) -> bool:
        """The incumbent's datagram: True when it continues its own numbering (the run's
        first just past its last followed) and the newcomer has been quiet
        :data:`RETURN_QUIET_S`, or once :attr:`return_datagrams` such datagrams came in a
        row."""
        run = self._incumbent_run
        if run is None or not run.extend(seq):
            if not 0 < _ahead(seq, self._top.get(key, seq - 1)) <= RETURN_GAP:
                return False
            self._incumbent_run = run = SeqRun(seq)
        return (run.count >= self.return_datagrams
                or now - self.last_active >= RETURN_QUIET_S)

    def admit(self, key: SessionKey, seq: int, now: float) -> Admission:
        """The verdict on one well-formed datagram of ``key`` with sequence number ``seq``
        at monotonic time ``now`` (s)."""
        if self.keyed and key.epoch < self._newest_epoch.get(key.sender, -1):
            return Admission.REPLAYED
        active = self.active
        if active is None:
            self._follow(key, now, seq)
            return Admission.FIRST
        if key == active:
            self.last_active = now
            if 0 < _ahead(seq, self._top[key]) <= RETURN_GAP:
                self._top[key] = seq
            return Admission.ACTIVE
        if key in self._retired:
            if self.keyed and _ahead(seq, self._top.get(key, seq - 1)) <= 0:
                return Admission.REPLAYED  # a number already followed: never again
            if key == self.incumbent and self._returning(key, seq, now):
                self._switch(key, seq, now, returned=True)
                return Admission.RETURN
            if key != self.incumbent and self._newcomer(key, seq, now):
                return Admission.TAKEOVER
            return Admission.STALE
        newer_run = (self.keyed and key.sender == active.sender and key.epoch > active.epoch)
        if newer_run:
            self._switch(key, seq, now, newer_run=True)
            return Admission.TAKEOVER
        return Admission.TAKEOVER if self._newcomer(key, seq, now) else Admission.FOREIGN

    def _newcomer(self, key: SessionKey, seq: int, now: float) -> bool:
        """Count a datagram of a session not followed; True when it has taken over (the
        followed session silent ``takeover_after_s``, this one ``takeover_datagrams`` in a
        row)."""
        run = self._candidates.get(key)
        if run is not None and run.extend(seq):
            self._candidates.move_to_end(key)
        else:
            run = self._candidates[key] = SeqRun(seq)
            self._candidates.move_to_end(key)
            while len(self._candidates) > MAX_CANDIDATES:
                self._candidates.popitem(last=False)
        if now - self.last_active >= self.takeover_after_s and run.count >= self.takeover_datagrams:
            self._switch(key, seq, now)
            return True
        return False
