"""What happened during a session, at which frame: :class:`SessionEvent` (docs/raw-format.md).

A session event is anything that changes a derived number from a given frame on (a Reset
Zero, the alignment switched, the filter or a gain changed, the filters re-initialised), or
that an investigator wants beside the data (a marker note, logging started, a warning). Live,
:mod:`bpms.pipeline.events` makes them; the raw recording stores them between its frame
records (:mod:`bpms.io.raw_layout`), so that replay and re-analysis apply them at their frames
and the GUI's event log and the LSL event stream show the same lines.

``frame`` is the first frame the event affects: in a recording, the slot index of that frame
in the file (frame k at stream time k × 0.02 s); in a live session, the source's frame index
(the session converts it when it writes the file). ``data`` holds the kind's values, plain
JSON (numbers, strings, booleans, lists; NaN is written as null). Each kind is a small typed
class of :mod:`bpms.io.event_types` that checks its values and is the one writer
(:meth:`SessionEvent.of`) and the one reader (:attr:`SessionEvent.change`) of its ``data``.

Kinds and their ``data``:

- ``reset_zero``: ``source`` (:data:`ZERO_SOURCES`), ``window`` (frames averaged, ending at
  ``frame``), ``R0`` (18 × 3 × 3 captured DCMs, null for an IMU with no data), ``yaw0`` (rad,
  the heading ψ0), ``heading`` (``hip``/``mean``), ``motion_deg`` and ``motion_imu`` (the
  largest rotation of one IMU during the window and which IMU), ``moved`` (that rotation is
  more than a still pose allows, 5°), ``waited`` (automatic: frames it waited for a still pose
  after its nominal frame);
- ``alignment``: ``on`` (output angles corrected by Reset Zero, the original's ``v`` key);
- ``filter``: ``algorithm``; ``gains``: ``values`` (``[filter]`` option names → numbers);
- ``filters``: ``action`` (``restart``: a new stream, the automatic Reset Zero runs again;
  ``reinit``: the filters re-initialise, Reset Zero kept) and ``reason``;
- ``marker``: ``text``; ``logging``: ``action`` (``start``/``stop``); ``note``: ``text``;
- ``lost`` (made by the reader, never written): an event record too damaged to read, at its
  place between the frames (``frame``: the slot of the frame after it); ``kind``: the kind it
  was when its bytes still say, else ``unknown``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from bpms.io.event_types import CHANGES, ZERO_SOURCES, Change, ResetZero
from bpms.io.timebase import stream_time

#: Kinds whose events change derived numbers (re-analysis applies them at their frames).
CHANGE_KINDS = frozenset(k for k, c in CHANGES.items() if c.CHANGES_NUMBERS)
#: The kinds a recording stores (``lost`` is the reader's, never written).
KINDS = (*sorted(CHANGE_KINDS), "marker", "logging", "note")


@dataclass(frozen=True)
class SessionEvent:
    """One event: ``kind`` (:data:`KINDS`), ``frame`` (the first frame it affects; -1: none),
    ``time`` (host time s since the epoch when it happened; NaN unknown) and ``data``."""

    kind: str
    frame: int = -1
    time: float = float("nan")
    data: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def of(cls, change: Change, frame: int = -1, time: float = float("nan")) -> SessionEvent:
        """The event of a typed change (:mod:`bpms.io.event_types`): its kind's one writer."""
        return cls(change.KIND, int(frame), time, change.to_data())

    @property
    def change(self) -> Change:
        """The typed change (:mod:`bpms.io.event_types`): its kind's one reader. Raises
        ValueError (or KeyError, TypeError) for an unknown kind or a wrong value."""
        kind = CHANGES.get(self.kind)
        if kind is None:
            raise ValueError(f"unknown event kind '{self.kind}'")
        return kind.from_data(self.data)

    @property
    def changes_numbers(self) -> bool:
        return self.kind in CHANGE_KINDS

    def at(self, frame: int) -> SessionEvent:
        """The same event at another frame index."""
        return replace(self, frame=int(frame))

    def to_json(self) -> bytes:
        """The event as one UTF-8 JSON object (NaN → null)."""
        body = {"kind": self.kind, "frame": int(self.frame),
                "time": _plain(self.time), "data": _plain(dict(self.data))}
        return json.dumps(body, separators=(",", ":"), allow_nan=False).encode("utf-8")

    @classmethod
    def from_json(cls, text: bytes | str) -> SessionEvent:
        """Parse :meth:`to_json`'s output. Raises ValueError for anything else."""
        try:
            body = json.loads(text)
        except (RecursionError, UnicodeDecodeError) as exc:
            raise ValueError(f"not an event ({type(exc).__name__})") from None
        if not isinstance(body, dict) or not isinstance(body.get("kind"), str):
            raise ValueError("not an event (no kind)")
        frame = body.get("frame", -1)
        when = body.get("time")
        data = body.get("data", {})
        if (not isinstance(frame, int) or isinstance(frame, bool)
                or not isinstance(data, dict)
                or not (when is None or isinstance(when, int | float))):
            raise ValueError("not an event (bad frame, time or data)")
        try:
            seconds = float("nan") if when is None else float(when)
        except OverflowError:  # an integer no float holds: no clock's time (the reader
            seconds = float("inf")  # checks times as it checks frame indices)
        return cls(body["kind"], frame, seconds, data)

    def describe(self, dt: float = 0.02) -> str:
        """One line for the event log, the record command and the LSL marker text."""
        at = f" at {stream_time(self.frame, dt):.2f} s" if self.frame >= 0 else ""
        d = self.data
        if self.kind == "reset_zero":
            try:
                change = self.change
            except (KeyError, TypeError, ValueError):
                return f"Reset Zero ({d.get('source', '?')}){at}"
            assert isinstance(change, ResetZero)
            return _describe_zero(change, at, dt)
        if self.kind == "alignment":
            state = "on (segment angles)" if d.get("on") else "off (sensor angles)"
            force = " in force" if d.get("source") == "in force" else ""
            return f"alignment {state}{force}{at}"
        if self.kind == "filter":
            force = " in force" if d.get("source") == "in force" else ""
            return f"filter {d.get('algorithm')}{force} on all 18 IMUs{at}"
        if self.kind == "gains" and d.get("source") == "in force":
            return f"filter settings in force{at}"
        if self.kind == "gains":
            values = d.get("values", {})
            text = ", ".join(f"{k} {v:g}" if isinstance(v, int | float) else f"{k} {v}"
                             for k, v in (values.items() if isinstance(values, dict) else ()))
            return f"filter settings {text}{at}"
        if self.kind == "filters":
            what = ("filters restarted" if d.get("action") == "restart"
                    else "filters re-initialised")
            reason = d.get("reason")
            return what + (f" ({reason})" if reason else "") + at
        if self.kind == "marker":
            return f"marker{at}: {d.get('text', '')}" if at else f"marker: {d.get('text')}"
        if self.kind == "lost":
            return f"a damaged {d.get('kind', 'unknown')} event record lost{at}"
        if self.kind == "logging":
            return f"logging {d.get('action', '?')}"
        return str(d.get("text", self.kind))


def _describe_zero(z: ResetZero, at: str, dt: float) -> str:
    line = f"Reset Zero ({z.source}){at}"
    if z.window is not None and z.window > 1:
        line += f", window {z.window * dt:.2f} s"
        if z.motion_deg is not None and z.motion_imu is not None and z.motion_imu >= 0:
            line += f", moved {z.motion_deg:.1f}° (IMU {z.motion_imu})"
        if z.moved and z.source in ("manual", "3d-view"):
            line += (": the subject moved during its window; stand still in the "
                     "calibration pose and press again")
    if z.waited is not None and z.waited > 0:
        line += f", after waiting {z.waited * dt:.2f} s for a still pose"
    return line


def _plain(value: Any) -> Any:
    """JSON-ready: NaN/inf → None, numpy numbers and arrays → Python numbers and lists."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if hasattr(value, "tolist"):  # numpy array or scalar
        return _plain(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


__all__ = ["CHANGE_KINDS", "KINDS", "ZERO_SOURCES", "SessionEvent"]
