"""The kinds of session event, one small typed class each (docs/raw-format.md's table).

A :class:`bpms.io.session_events.SessionEvent` is the envelope a recording stores (kind,
frame, time and the kind's ``data`` as plain JSON); its :attr:`~bpms.io.session_events.
SessionEvent.change` is one of the classes here. Each class checks its own values when it is
made (a ValueError naming what is wrong), and is the one place that writes its kind's
``data`` (:meth:`to_data`) and the one that reads it (:meth:`from_data`). A live change is
made as one of them in the caller's thread (so a bad value is refused there) and applied by
:meth:`bpms.filter.processor.BodyPoseProcessor.apply_event`, the same function that applies a
recorded one on replay.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from bpms.io.frames import N_IMUS
from bpms.io.options import check_option

#: Where a Reset Zero came from. ``provisional``: one frame, the first where every IMU has
#: data; ``automatic``: the window after the filters settled, once the subject is still;
#: ``in force``: the zero already in force when logging started; ``network``: the sender's,
#: received over UDP; ``re-analysis``: asked for when a recording is filtered again;
#: ``posture`` / ``functional``: a pose calibration (docs/pose-calibration.md), adopted.
ZERO_SOURCES = ("manual", "automatic", "provisional", "3d-view", "network", "in force",
                "re-analysis", "posture", "functional")
#: Reset Zero sources whose recorded zero is adopted as it is (never captured again).
ADOPTED_SOURCES = ("network", "in force")


class Change:
    """What every kind has: its ``KIND`` name, whether it changes derived numbers, and the
    writer and reader of its ``data``."""

    KIND: ClassVar[str] = ""
    CHANGES_NUMBERS: ClassVar[bool] = False

    def to_data(self) -> dict[str, Any]:
        """The kind's ``data`` (plain values; numpy arrays become lists when written)."""
        raise NotImplementedError

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> Change:
        """The typed event of a ``data`` mapping; ValueError (or KeyError, TypeError) when
        a value is missing or wrong."""
        raise NotImplementedError


def _optional(data: Mapping[str, Any], key: str, kind: type) -> Any:
    value = data.get(key)
    return None if value is None else kind(value)


def _source(text: str | None) -> str | None:
    if text is not None and not isinstance(text, str):
        raise ValueError(f"source must be text, got {text!r}")
    return text


@dataclass(frozen=True, eq=False)
class ResetZero(Change):
    """A Reset Zero. Live, a request (``source`` only, ``window`` None: the options'
    window); recorded, the capture made: ``window`` frames averaged ending at the event's
    frame, the captured DCMs ``R0[18, 3, 3]`` (NaN: an IMU without data), the heading
    ``yaw0`` (rad) and where it came from (``heading``), the largest motion of one IMU during
    the window (``motion_deg``, ``motion_imu``; ``moved``: more than a still pose allows) and
    the frames the automatic capture ``waited`` for a still pose. ``adopt``: use ``R0`` and
    ``yaw0`` as they are; ``fallback``: a recorded capture lost to damage, the automatic one
    instead; ``sender_source``: a network zero's source at its sender; ``details``: what a
    pose calibration adds (``posture``, ``still``, ``moves``, ``quality``: docs/
    pose-calibration.md), kept as recorded."""

    KIND: ClassVar[str] = "reset_zero"
    CHANGES_NUMBERS: ClassVar[bool] = True
    source: str = "manual"
    window: int | None = None
    R0: np.ndarray | None = field(default=None, repr=False)
    yaw0: float | None = None
    heading: str | None = None
    motion_deg: float | None = None
    motion_imu: int | None = None
    moved: bool | None = None
    waited: int | None = None
    adopt: bool = False
    fallback: bool = False
    sender_source: str | None = None
    details: Mapping[str, Any] = field(default_factory=dict)

    #: The keys of :meth:`to_data` other than ``details``'.
    KEYS: ClassVar[tuple[str, ...]] = (
        "source", "adopt", "fallback", "sender_source", "window", "R0", "yaw0", "heading",
        "motion_deg", "motion_imu", "moved", "waited")

    def __post_init__(self) -> None:
        if self.source not in ZERO_SOURCES:
            raise ValueError(f"Reset Zero source '{self.source}' is not one of "
                             f"{', '.join(ZERO_SOURCES)}")
        if self.window is not None and (isinstance(self.window, bool) or self.window < 1):
            raise ValueError(f"Reset Zero window {self.window!r} is not a frame count ≥ 1")
        if self.R0 is not None:
            R0 = np.array(self.R0, dtype=np.float64)  # (null → NaN)
            if R0.shape != (N_IMUS, 3, 3):
                raise ValueError(f"Reset Zero R0 must be [{N_IMUS}, 3, 3], got {R0.shape}")
            object.__setattr__(self, "R0", R0)
        if self.yaw0 is not None and not math.isfinite(self.yaw0):
            raise ValueError("Reset Zero heading yaw0 must be finite")

    @property
    def zero(self) -> tuple[np.ndarray, float] | None:
        """(``R0``, ``yaw0``) stored with the event, or None when it holds no zero."""
        if self.R0 is None or self.yaw0 is None:
            return None
        return self.R0, self.yaw0

    @property
    def adopted(self) -> bool:
        """Its stored zero is used as it is (``adopt``, or a network or in-force zero)."""
        return self.adopt or self.source in ADOPTED_SOURCES

    def to_data(self) -> dict[str, Any]:
        data: dict[str, Any] = {"source": self.source}
        if self.adopt:
            data["adopt"] = True
        if self.fallback:
            data["fallback"] = True
        for key in self.KEYS[3:]:  # (after source, adopt and fallback)
            value = getattr(self, key)
            if value is not None:
                data[key] = value
        data.update((k, v) for k, v in self.details.items() if k not in self.KEYS)
        return data

    def merged(self, data: Mapping[str, Any]) -> ResetZero:
        """This capture with ``data``'s values in place of its own (e.g. ``adopt`` and a pose
        calibration's ``details``), checked again."""
        return ResetZero.from_data({**self.to_data(), **data})

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> ResetZero:
        R0 = data.get("R0")
        return cls(str(data.get("source", "manual")), _optional(data, "window", int),
                   None if R0 is None else np.array(R0, dtype=np.float64),
                   _optional(data, "yaw0", float), _optional(data, "heading", str),
                   _optional(data, "motion_deg", float), _optional(data, "motion_imu", int),
                   _optional(data, "moved", bool), _optional(data, "waited", int),
                   bool(data.get("adopt", False)), bool(data.get("fallback", False)),
                   _optional(data, "sender_source", str),
                   {k: v for k, v in data.items() if k not in cls.KEYS})


@dataclass(frozen=True)
class Alignment(Change):
    """Output angles corrected by Reset Zero (``on`` True: segment angles) or the sensor
    angles (False); live, None toggles (the original's ``v`` key). ``source``: ``in force``
    for the state written when logging started."""

    KIND: ClassVar[str] = "alignment"
    CHANGES_NUMBERS: ClassVar[bool] = True
    on: bool | None = None
    source: str | None = None

    def __post_init__(self) -> None:
        if self.on is not None and not isinstance(self.on, bool | np.bool_):
            raise ValueError(f"alignment must be on (true) or off (false), got {self.on!r}")
        _source(self.source)

    def to_data(self) -> dict[str, Any]:
        if self.on is None:
            raise ValueError("a toggle is resolved before it is recorded")
        return {"on": bool(self.on), **({"source": self.source} if self.source else {})}

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> Alignment:
        return cls(data["on"], data.get("source"))


@dataclass(frozen=True)
class FilterChoice(Change):
    """All 18 IMUs switched to the attitude filter ``algorithm`` (a ``[filter] algorithm``
    choice, checked)."""

    KIND: ClassVar[str] = "filter"
    CHANGES_NUMBERS: ClassVar[bool] = True
    algorithm: str = "mahony"
    source: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "algorithm", check_option("filter", "algorithm",
                                                           self.algorithm))
        _source(self.source)

    def to_data(self) -> dict[str, Any]:
        return {"algorithm": self.algorithm, **({"source": self.source} if self.source else {})}

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> FilterChoice:
        return cls(data["algorithm"], data.get("source"))


@dataclass(frozen=True)
class Gains(Change):
    """Filter settings changed, by their ``[filter]`` names (``kp_rollpitch``,
    ``observer_k_incl``, ``vqf_tau_acc_s``, ``dt`` s, ...): each checked against
    :data:`bpms.io.options.VALID_RANGES` when made (OptionRangeError, a ValueError naming the
    range); the filter itself is a :class:`FilterChoice`."""

    KIND: ClassVar[str] = "gains"
    CHANGES_NUMBERS: ClassVar[bool] = True
    values: Mapping[str, Any] = field(default_factory=dict)
    source: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.values, Mapping):
            raise ValueError(f"filter settings must be a table of names, got {self.values!r}")
        if "algorithm" in self.values:
            raise ValueError("use select_filter() to change the attitude filter")
        checked = {str(k): check_option("filter", str(k), v) for k, v in self.values.items()}
        object.__setattr__(self, "values", checked)
        _source(self.source)

    def to_data(self) -> dict[str, Any]:
        return {"values": dict(self.values),
                **({"source": self.source} if self.source else {})}

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> Gains:
        return cls(data["values"], data.get("source"))


@dataclass(frozen=True)
class Filters(Change):
    """The filters started again: ``restart`` (a new stream: the automatic Reset Zero runs
    again) or ``reinit`` (the stream resumed after a gap: Reset Zero kept); ``reason``."""

    KIND: ClassVar[str] = "filters"
    CHANGES_NUMBERS: ClassVar[bool] = True
    action: str = "reinit"
    reason: str = ""

    def __post_init__(self) -> None:
        if self.action not in ("restart", "reinit"):
            raise ValueError(f"filters action '{self.action}' is not restart or reinit")

    def to_data(self) -> dict[str, Any]:
        return {"action": self.action, "reason": self.reason}

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> Filters:
        return cls(str(data.get("action", "reinit")), str(data.get("reason") or ""))


@dataclass(frozen=True)
class Text(Change):
    """A line beside the data: a ``marker`` typed by the operator or a ``note`` (a warning
    of the session)."""

    KIND: ClassVar[str] = "marker"
    text: str = ""

    def to_data(self) -> dict[str, Any]:
        return {"text": self.text}

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> Text:
        return cls(str(data.get("text", "")))


@dataclass(frozen=True)
class Note(Text):
    KIND: ClassVar[str] = "note"


@dataclass(frozen=True)
class Logging(Change):
    """Logging ``start`` (with the ``raw`` and ``filtered`` file names) or ``stop``."""

    KIND: ClassVar[str] = "logging"
    action: str = "start"
    raw: str | None = None
    filtered: str | None = None

    def to_data(self) -> dict[str, Any]:
        if self.action != "start":
            return {"action": self.action}
        return {"action": self.action, "raw": self.raw, "filtered": self.filtered}

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> Logging:
        return cls(str(data.get("action", "?")), data.get("raw"), data.get("filtered"))


@dataclass(frozen=True)
class Lost(Change):
    """An event record too damaged to read (made by the reader, never written): the
    ``kind`` it was when its bytes still say (else ``unknown``) and its ``place``, the slot
    of the frame after it."""

    KIND: ClassVar[str] = "lost"
    kind: str = "unknown"
    place: int = -1

    def to_data(self) -> dict[str, Any]:
        return {"kind": self.kind, "place": int(self.place)}

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> Lost:
        return cls(str(data.get("kind", "unknown")), int(data.get("place", -1)))


#: Each kind's class, by its name.
CHANGES: dict[str, type[Change]] = {c.KIND: c for c in (
    ResetZero, Alignment, FilterChoice, Gains, Filters, Text, Note, Logging, Lost)}

__all__ = ["ADOPTED_SOURCES", "CHANGES", "ZERO_SOURCES", "Alignment", "Change", "FilterChoice",
           "Filters", "Gains", "Logging", "Lost", "Note", "ResetZero", "Text"]
