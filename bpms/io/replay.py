"""A raw recording played back as a frame source (raw-file playback, docs/gui.md).

Pacing uses the suit's nominal period (20 ms per frame) divided by the speed, not the
recorded host times: those carry the Bluetooth jitter and bursts of the live session, while
the frames themselves were sampled every 20 ms. ``speed=None`` plays as fast as possible.

The recording's events (:class:`bpms.io.session_events.SessionEvent`: Reset Zero, alignment,
filter and gain changes, filters re-initialised, markers) ride on the frames they apply at
(``FrameEvent.marks``), so the session applies them where the live session did.

Seeking re-initialises the filters: the first frame after a seek carries
``discontinuity=True`` and, as ``preroll``, up to ``preroll_s`` seconds of the frames before
the seek point, which the processor runs through (without output) so the filters have
converged and the pose is right from the first displayed frame. It also carries the state the
recording's events left in force at the seek point: the last Reset Zero (its recorded zero,
adopted), the alignment, the filter and its gains.

The frames are read from the recording as they are played (:class:`bpms.io.raw_reader.
RawFrames` streams them from disk; a :class:`bpms.io.raw_reader.RawRecording` is in memory).

All controls are thread-safe; :meth:`read` wakes up at once when a control changes the state.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from bpms.io.event_types import Gains, ResetZero
from bpms.io.events import FrameEvent, SourceStatus
from bpms.io.frames import FRAME_PERIOD_S, FRAME_SIZE
from bpms.io.session_events import SessionEvent
from bpms.io.timebase import frame_at, stream_time


class Slots(Protocol):
    """What replay reads: ``len``, ``path``, ``events`` ``(slot, SessionEvent)`` and
    ``read(lo, hi)`` → (host times, frame bytes)."""

    path: str
    events: list[tuple[int, SessionEvent]]

    def __len__(self) -> int: ...

    def read(self, lo: int, hi: int) -> tuple[np.ndarray, bytes]: ...

SPEEDS = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, None)  # None: as fast as possible


class ReplaySource:
    """Plays ``recording`` from frame 0; starts paused unless ``autoplay``."""

    #: A file can wait: the pipeline applies back-pressure instead of dropping frames.
    can_wait = True

    def __init__(self, recording: Slots, speed: float | None = 1.0, *,
                 autoplay: bool = True, preroll_s: float = 5.0, batch: int = 256,
                 events: Sequence[tuple[int, SessionEvent]] | None = None) -> None:
        """``events``: the events to apply, ``(slot, event)`` (default: the recording's)."""
        self.recording = recording
        self._length = len(recording)
        self._carried: tuple[SessionEvent, ...] = ()
        self.set_events(recording.events if events is None else events)
        self._cond = threading.Condition()
        self._speed = speed
        self._playing = autoplay
        self._pos = 0
        self._anchor = (time.monotonic(), 0)  # (monotonic time, frame index) of the pacing origin
        self._steps = 0
        self._discontinuity = True
        self._preroll_frames = frame_at(preroll_s)
        self._batch = batch
        self._closed = False

    # -- state ------------------------------------------------------------------------
    def __len__(self) -> int:
        return self._length

    @property
    def position(self) -> int:
        """Index of the next frame to be delivered."""
        return self._pos

    @property
    def position_s(self) -> float:
        return stream_time(self._pos)

    @property
    def playing(self) -> bool:
        return self._playing and not self.ended

    @property
    def ended(self) -> bool:
        return self._pos >= len(self)

    @property
    def speed(self) -> float | None:
        return self._speed

    def status(self) -> SourceStatus:
        state = ("closed" if self._closed else "ended" if self.ended
                 else "streaming" if self._playing else "paused")
        return SourceStatus(f"file {self.recording.path}", state, position=self._pos,
                            length=len(self))

    def set_events(self, events: Sequence[tuple[int, SessionEvent]]) -> None:
        """The events to apply from now on, ``(slot, event)`` (a new Reset Zero choice)."""
        ordered = sorted(events, key=lambda item: item[0])
        marks: dict[int, tuple[SessionEvent, ...]] = {}
        for slot, event in ordered:
            if 0 <= slot < self._length:
                marks[slot] = (*marks.get(slot, ()), event)
        self.events, self._marks = ordered, marks

    # -- controls ---------------------------------------------------------------------
    def _reanchor(self) -> None:
        self._anchor = (time.monotonic(), self._pos)

    def play(self) -> None:
        with self._cond:
            self._playing = True
            self._reanchor()
            self._cond.notify_all()

    def pause(self) -> None:
        with self._cond:
            self._playing = False
            self._cond.notify_all()

    def step(self, n: int = 1) -> None:
        """While paused, deliver the next ``n`` frames at the next read."""
        with self._cond:
            self._steps += n
            self._cond.notify_all()

    def set_speed(self, speed: float | None) -> None:
        if speed is not None and speed <= 0:
            raise ValueError("speed must be positive (or None for as fast as possible)")
        with self._cond:
            self._speed = speed
            self._reanchor()
            self._cond.notify_all()

    def seek(self, index: int | None = None, *, seconds: float | None = None) -> None:
        """Jump to frame ``index`` (or ``seconds`` into the file), clamped to the file."""
        if seconds is not None:
            index = frame_at(seconds)
        with self._cond:
            self._pos = max(0, min(int(index or 0), len(self)))
            self._carried = state_before(self.events, self._pos)
            self._discontinuity = True
            self._steps = 0
            self._reanchor()
            self._cond.notify_all()

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    # -- delivery ---------------------------------------------------------------------
    def _take(self, count: int) -> list[FrameEvent]:
        lo = self._pos
        hi = min(len(self), lo + count)
        if hi <= lo:
            return []
        times, frames = self.recording.read(lo, hi)
        out = []
        for j, k in enumerate(range(lo, hi)):
            preroll = b""
            marks = self._marks.get(k, ())
            if self._discontinuity and k > 0:
                first = max(0, k - self._preroll_frames)
                preroll = self.recording.read(first, k)[1]
                marks = (*self._carried, *marks)
            frame = frames[j * FRAME_SIZE:(j + 1) * FRAME_SIZE]
            out.append(FrameEvent(float(times[j]), frame, k, self._discontinuity, preroll,
                                  marks=marks))
            self._discontinuity = False
            self._carried = ()
        self._pos = hi
        return out

    def read(self, timeout: float = 0.1) -> list[FrameEvent]:
        """The frames due now (waits up to ``timeout`` s for the next one)."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while not self._closed:
                if self._steps and not self.ended:
                    n, self._steps = self._steps, 0
                    return self._take(n)
                if self._playing and not self.ended:
                    if self._speed is None:
                        return self._take(self._batch)
                    t0, k0 = self._anchor
                    period = FRAME_PERIOD_S / self._speed
                    due = int((time.monotonic() - t0) / period) + k0 + 1 - self._pos
                    if due > 0:
                        return self._take(min(due, self._batch))
                    wake = t0 + (self._pos - k0) * period
                else:
                    wake = deadline
                now = time.monotonic()
                if now >= deadline:
                    return []
                self._cond.wait(min(wake, deadline) - now)
            return []


def state_before(events: Sequence[tuple[int, SessionEvent]], slot: int
                 ) -> tuple[SessionEvent, ...]:
    """The state the ``events`` (slot order) left in force before ``slot``, as events to apply
    there: the filter, its gains (merged), the alignment and the last Reset Zero (its recorded
    zero, adopted)."""
    last: dict[str, SessionEvent] = {}
    gains: dict = {}
    for at, event in events:
        if at >= slot:
            break
        if event.kind == "gains" and isinstance(event.data.get("values"), dict):
            gains.update(event.data["values"])
        elif event.kind in ("filter", "alignment", "reset_zero"):
            last[event.kind] = event
        elif event.kind == "filters" and event.data.get("action") == "restart":
            last.pop("reset_zero", None)
    out = [last[k].at(slot) for k in ("filter", "alignment") if k in last]
    if gains:
        try:
            out.append(SessionEvent.of(Gains(gains), slot))
        except (TypeError, ValueError):  # a recorded value out of range: applying says so
            out.append(SessionEvent("gains", slot, data={"values": gains}))
    if "reset_zero" in last:
        zero = last["reset_zero"]
        try:
            change = zero.change
        except (KeyError, TypeError, ValueError):  # unreadable: applying it says so
            out.append(SessionEvent("reset_zero", slot, zero.time, {**zero.data, "adopt": True}))
        else:
            if isinstance(change, ResetZero):  # its recorded zero, adopted
                change = dataclasses.replace(change, adopt=True)
            out.append(SessionEvent.of(change, slot, zero.time))
    return tuple(out)
