"""Which Reset Zero a recording is filtered with: ``--reset-zero events|auto|at SECONDS|none``
(docs/opening-recordings.md), for every door (the analysis commands, the Python API, GUI
playback and ``bpms replay``).

- ``events`` (the default): the Reset Zero captures recorded in the file, at their frames (the
  numbers the investigator saw live); a recording without events (format version 1, a legacy
  file, a filtered file) gets the automatic ones, and so does a recording from the frame of a
  capture whose record was lost to damage on (:func:`fallback_zero`);
- ``auto``: the recorded captures are ignored; the provisional capture and the automatic one
  (once the subject is still, docs/body-model.md) are made again;
- ``at T[,T2...]``: the provisional capture, then captures at these stream times (s) only;
- ``none``: no Reset Zero: each segment orientation is its IMU's own attitude (R0 = identity,
  heading 0).

Only Reset Zero is chosen here: the other recorded events (alignment, filter, gains, filters
re-initialised) always apply, except that an explicit filter or options file overrides the
recorded filter and gain changes.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bpms.io.event_types import ResetZero
from bpms.io.frames import N_IMUS
from bpms.io.session_events import SessionEvent
from bpms.io.timebase import LONGEST_S

MODES = ("events", "auto", "at", "none")


@dataclass(frozen=True)
class ResetZeroChoice:
    """``mode`` (:data:`MODES`) and, for ``at``, the stream ``times`` (s)."""

    mode: str = "events"
    times: tuple[float, ...] = ()

    @classmethod
    def parse(cls, text: str | ResetZeroChoice | None) -> ResetZeroChoice:
        """``events``, ``auto``, ``none``, ``at 12.5`` or ``at 12.5,30`` (None: events).
        Raises ValueError naming the choices."""
        if text is None:
            return cls()
        if isinstance(text, ResetZeroChoice):
            return text
        words = str(text).replace("=", " ").split(None, 1)
        mode = words[0].lower() if words else ""
        if mode in ("events", "auto", "none") and len(words) == 1:
            return cls(mode)
        if mode == "at" and len(words) == 2:
            try:
                times = tuple(float(t) for t in words[1].replace(",", " ").split())
            except ValueError:
                times = ()
            if times and all(np.isfinite(t) and 0 <= t <= LONGEST_S for t in times):
                return cls("at", times)
        raise ValueError(f"--reset-zero: '{text}' is not one of events, auto, none, "
                         "'at SECONDS' (e.g. 'at 12.5' or 'at 12.5,30')")

    def automatic(self, has_events: bool) -> bool:
        """Whether the processor makes its own provisional and automatic captures."""
        return self.mode == "auto" or (self.mode == "events" and not has_events)

    def provisional(self, has_events: bool) -> bool:
        """Whether the processor makes its provisional capture (``at`` keeps it)."""
        return self.automatic(has_events) or self.mode == "at"

    def keeps(self, event: SessionEvent) -> bool:
        """Whether a recorded event applies under this choice."""
        return event.kind != "reset_zero" or self.mode == "events"

    def frames(self, dt: float) -> list[int]:
        """The capture frames of ``at``."""
        return sorted({round(t / dt) for t in self.times}) if self.mode == "at" else []

    def describe(self) -> str:
        if self.mode == "at":
            return "Reset Zero at " + ", ".join(f"{t:g} s" for t in self.times)
        return {"events": "Reset Zero as recorded", "auto": "automatic Reset Zero",
                "none": "no Reset Zero"}[self.mode]


def identity_zero(frame: int = 0) -> SessionEvent:
    """The ``none`` choice as an event: R0 = identity, heading 0, adopted at ``frame``."""
    return SessionEvent.of(ResetZero("re-analysis", 1, np.tile(np.eye(3), (N_IMUS, 1, 1)),
                                     0.0, adopt=True), frame)


def capture_at(frame: int) -> SessionEvent:
    """A re-analysis capture at ``frame`` (the options' window)."""
    return SessionEvent.of(ResetZero("re-analysis"), frame)


def fallback_zero(frame: int) -> SessionEvent:
    """Instead of a recorded capture lost to damage at ``frame``: the automatic Reset Zero
    from there (:meth:`bpms.filter.pose.PoseCalibrator.fall_back`)."""
    return SessionEvent.of(ResetZero("automatic", fallback=True), frame)


class Planned(list):
    """The events a door applies, ``(slot, event)``, and what it says about them."""

    skipped = 0  # recorded filter/gain changes left out

    def __init__(self) -> None:
        super().__init__()
        self.fallbacks: list[int] = []  # frames of lost Reset Zero records (automatic instead)


def fallback_line(path: Path, frames: Sequence[int]) -> str:
    """The one line a door says when recorded Reset Zero captures were lost to damage."""
    shown = ", ".join(str(k) for k in frames[:6]) + (", ..." if len(frames) > 6 else "")
    return (f"{path}: {len(frames)} recorded Reset Zero capture(s) lost to damage (frame "
            f"{shown}): the automatic Reset Zero is used from there")


def planned_events(recorded: Iterable[tuple[int, SessionEvent]], choice: ResetZeroChoice,
                   settings_given: bool, extra: Sequence[int] = (), start: bool = False
                   ) -> Planned:
    """The events a door applies, ``(slot, event)`` in slot order: the recorded ones ``choice``
    keeps (filter and gain changes only when no filter or options file was given), the
    ``none`` choice's identity zero at the start (``start``) and after each restart, a
    re-analysis capture at each ``extra`` frame, and the automatic Reset Zero
    (:func:`bpms.filter.zero_choice.fallback_zero`) where a recorded one was lost to damage."""
    out = Planned()
    none = choice.mode == "none"
    if none and start:
        out.append((0, identity_zero()))
    for slot, event in recorded:
        if (event.kind == "lost" and choice.mode == "events"
                and event.data.get("kind") in ("reset_zero", "unknown")):
            out.append((slot, fallback_zero(slot)))  # (a lost record of unknown kind may be one)
            out.fallbacks.append(slot)
            continue
        if settings_given and event.kind in ("filter", "gains"):
            out.skipped += 1
            continue
        if choice.keeps(event):
            out.append((slot, event))
            if none and event.kind == "filters" and event.data.get("action") == "restart":
                out.append((slot, identity_zero(slot)))
    out.extend((k, capture_at(k)) for k in extra)
    out.sort(key=lambda item: item[0])
    return out


__all__ = ["MODES", "Planned", "ResetZeroChoice", "capture_at", "fallback_line", "fallback_zero",
           "identity_zero", "planned_events"]
