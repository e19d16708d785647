"""The subject's profile (docs/subject.md): id, height, mass and measured segment lengths,
stored in a recording's header (``"subject"``) and used by the body model.

Segment lengths not measured are scaled from the height with the anthropometric proportions
of Drillis and Contini (1966) as given by D. A. Winter, *Biomechanics and Motor Control of
Human Movement*, 4th ed., Wiley 2009, Figure 4.1 (:data:`LENGTH_FRACTIONS`):

- upper arm 0.186 H, forearm 0.146 H, hand 0.108 H, thigh 0.245 H, leg 0.246 H, foot
  0.152 H, shoulder width 0.259 H, hip width 0.191 H;
- heights of the shoulder 0.818 H, the chin 0.870 H and the hip (greater trochanter) 0.530 H.

Mapped onto the body model's segments (docs/body-model.md): ``shoulder`` and ``hip`` are half
the widths; the trunk from the hip to the shoulder (0.288 H) is split between ``low_spine`` and
``mid_spine`` as the dissertation's Table 2.4 splits it (0.21 : 0.27); ``neck`` runs from the
shoulder's height to the chin's (0.052 H), ``head`` from the chin to the top (0.130 H).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bpms.io.options import BodyOptions

SEGMENTS: tuple[str, ...] = ("low_spine", "mid_spine", "neck", "head", "shoulder", "arm",
                             "forearm", "hand", "hip", "thigh", "shank", "foot")
_TRUNK = 0.818 - 0.530
#: Each segment's length as a fraction of the height (Drillis and Contini 1966, via Winter 2009,
#: Figure 4.1; see the module docstring for the mapping).
LENGTH_FRACTIONS: dict[str, float] = {
    "low_spine": _TRUNK * 0.21 / 0.48, "mid_spine": _TRUNK * 0.27 / 0.48,
    "neck": 0.870 - 0.818, "head": 1.0 - 0.870, "shoulder": 0.259 / 2, "arm": 0.186,
    "forearm": 0.146, "hand": 0.108, "hip": 0.191 / 2, "thigh": 0.245, "shank": 0.246,
    "foot": 0.152,
}
HEIGHT_RANGE = (0.5, 2.5)  # m
MASS_RANGE = (2.0, 400.0)  # kg
SEGMENT_RANGE = (0.01, 1.5)  # m


@dataclass(frozen=True)
class SubjectProfile:
    """``subject_id`` (a name or code), ``height`` m, ``mass`` kg (None: not given),
    ``segments``: measured lengths, m, by :data:`SEGMENTS` name."""

    subject_id: str
    height: float
    mass: float | None = None
    segments: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not str(self.subject_id).strip():
            raise ValueError("subject: an id is needed (a name or a code)")
        _check("height", self.height, HEIGHT_RANGE, "m")
        if self.mass is not None:
            _check("mass", self.mass, MASS_RANGE, "kg")
        unknown = sorted(set(self.segments) - set(SEGMENTS))
        if unknown:
            raise ValueError(f"subject: unknown segment(s) {', '.join(unknown)} "
                             f"(known: {', '.join(SEGMENTS)})")
        for name, value in self.segments.items():
            _check(name, value, SEGMENT_RANGE, "m")

    def lengths(self) -> dict[str, float]:
        """Every segment's length, m: measured, else :data:`LENGTH_FRACTIONS` × height."""
        return {name: float(self.segments.get(name, LENGTH_FRACTIONS[name] * self.height))
                for name in SEGMENTS}

    def scaled(self) -> list[str]:
        """The segments whose length comes from the table (not measured)."""
        return [name for name in SEGMENTS if name not in self.segments]

    def body_options(self) -> BodyOptions:
        """The body model's lengths for this subject."""
        return BodyOptions(**self.lengths(), height=float(self.height))

    def to_header(self) -> dict[str, Any]:
        """What a recording's header stores (``header["subject"]``)."""
        return {"id": str(self.subject_id), "height_m": float(self.height),
                "mass_kg": None if self.mass is None else float(self.mass),
                "segments_m": {k: float(v) for k, v in self.segments.items()},
                "scaled_from": "Drillis & Contini 1966 via Winter 2009, Fig. 4.1",
                "lengths_m": self.lengths()}

    @classmethod
    def from_header(cls, data: Any) -> SubjectProfile:
        """The profile a header stores. Raises ValueError when it is malformed."""
        if not isinstance(data, dict):
            raise ValueError("subject: not a table")
        try:
            mass = data.get("mass_kg")
            return cls(str(data["id"]), float(data["height_m"]),
                       None if mass is None else float(mass),
                       {str(k): float(v) for k, v in dict(data.get("segments_m") or {}).items()})
        except (KeyError, TypeError) as exc:
            raise ValueError(f"subject: {exc} missing or malformed") from None

    @classmethod
    def parse(cls, text: str) -> SubjectProfile:
        """``"id=S01,height=1.80,mass=75,thigh=0.46"`` or the path of a TOML file with the same
        keys (``id``, ``height`` m, ``mass`` kg, segment names m). Raises ValueError."""
        path = Path(text)
        try:  # a long KEY=VALUE text is no file name the system takes (ENAMETOOLONG)
            is_file = path.suffix.lower() == ".toml" or path.is_file()
        except (OSError, ValueError):
            is_file = False
        if is_file:
            import tomllib

            try:
                items = tomllib.loads(path.read_text(encoding="utf-8"))
            except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
                raise ValueError(f"subject file {path}: {exc}") from None
            items = dict(items.get("subject", items))
        else:
            items = {}
            for part in text.split(","):
                key, sep, value = part.partition("=")
                if not sep:
                    raise ValueError(f"subject: '{part.strip()}' is not KEY=VALUE "
                                     "(e.g. 'id=S01,height=1.80,mass=75,thigh=0.46')")
                items[key.strip()] = value.strip()
        try:
            ident = str(items.pop("id"))
            height = float(items.pop("height"))
            mass = items.pop("mass", None)
            return cls(ident, height, None if mass is None else float(mass),
                       {str(k): float(v) for k, v in items.items()})
        except KeyError as exc:
            raise ValueError(f"subject: {exc.args[0]} is needed") from None
        except (TypeError, ValueError) as exc:
            if "subject" in str(exc):
                raise
            raise ValueError(f"subject: {exc}") from None


def _check(name: str, value: float, bounds: tuple[float, float], unit: str) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value)
            and bounds[0] <= value <= bounds[1]):
        raise ValueError(f"subject: {name} {value!r} is outside {bounds[0]:g} .. "
                         f"{bounds[1]:g} {unit}")


def header_subject(header: dict | None) -> tuple[SubjectProfile | None, str | None]:
    """(profile, problem) of a recording's header: (None, None) when it stores none."""
    if not header or header.get("subject") is None:
        return None, None
    try:
        return SubjectProfile.from_header(header["subject"]), None
    except ValueError as exc:
        return None, f"{exc}; the options' segment lengths are used"
