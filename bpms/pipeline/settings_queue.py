"""The one road for run-time settings into the processing thread.

The GUI, the CLI and the API change settings while frames are being filtered. Nobody writes
the processor's options directly: each change is checked in the caller's thread (a value
outside :data:`bpms.io.options.VALID_RANGES` raises :class:`bpms.io.options.OptionRangeError`
there, naming the range, and nothing is queued), then queued, and the processing thread applies
every queued change between two frames (:meth:`SettingsQueue.apply`), so it holds from the
next frame on. The processor keeps each filter's own values (``options.filter``), so switching
filter and back keeps run-time gains.
"""

from __future__ import annotations

import queue
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from bpms.io.options import check_option
from bpms.io.session_events import SessionEvent


@dataclass(frozen=True)
class Change:
    """One queued change: ``kind`` and its checked ``value``."""

    kind: str  # "gains", "filter", "reset_zero", "corrected_output"
    value: Any = None


class SettingsQueue:
    """Checked, queued settings changes for one processor (thread-safe)."""

    def __init__(self) -> None:
        self._queue: queue.SimpleQueue[Change] = queue.SimpleQueue()

    def set_gains(self, **gains: float) -> None:
        """Queue filter settings by their ``[filter]`` names (``kp_rollpitch``,
        ``observer_k_incl``, ``vqf_tau_acc_s``, ``dt``...). Raises OptionRangeError (a
        ValueError naming the range) for a value outside, queueing nothing."""
        checked = {name: check_option("filter", name, value) for name, value in gains.items()}
        if "algorithm" in checked:
            raise ValueError("use select_filter() to change the attitude filter")
        self._queue.put(Change("gains", checked))

    def select_filter(self, algorithm: str) -> None:
        """Queue a switch of all 18 IMUs' attitude filter (a ``[filter] algorithm`` choice;
        another name raises OptionRangeError)."""
        self._queue.put(Change("filter", check_option("filter", "algorithm", algorithm)))

    def reset_zero(self, source: str = "manual") -> None:
        """Queue a Reset Zero capture (``source``: who asked, e.g. ``3d-view``)."""
        self._queue.put(Change("reset_zero", source))

    def set_corrected_output(self, on: bool | None = None) -> None:
        """Queue the corrected-output switch: True (segment angles), False (sensor angles),
        None toggles (the original's ``v`` key)."""
        self._queue.put(Change("corrected_output", on))

    def apply(self, processor: Any, on_error: Callable[[str], None] | None = None
              ) -> list[SessionEvent]:
        """Apply every queued change to ``processor`` (a BodyPoseProcessor), in order; call
        from the processing thread between two frames. A change that fails (e.g. the vqf
        package missing) is reported through ``on_error`` and the others still apply.
        Returns the session events of the changes applied (no frame yet: they hold from the
        next frame; a Reset Zero becomes an event when it is captured)."""
        done: list[SessionEvent] = []
        while not self._queue.empty():  # (checked first: no exception per frame; one consumer)
            change = self._queue.get_nowait()
            try:
                if change.kind == "gains":
                    processor.set_gains(**change.value)
                    done.append(SessionEvent("gains", data={"values": dict(change.value)}))
                elif change.kind == "filter":
                    processor.select_filter(change.value)
                    done.append(SessionEvent("filter", data={"algorithm": change.value}))
                elif change.kind == "reset_zero":
                    processor.reset_zero(change.value or "manual")
                elif change.kind == "corrected_output":
                    on = processor.set_corrected_output(change.value)
                    done.append(SessionEvent("alignment", data={"on": bool(on)}))
            except Exception as exc:  # reported, never kills the processing thread
                if on_error is not None:
                    on_error(f"setting {change.kind} not applied: {exc}")
        return done


__all__ = ["Change", "SettingsQueue"]
