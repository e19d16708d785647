"""What every export states about its recording (issue 16.5): the UTC start time and the
joint-angle convention of the angles written.

- UTC start: the host receive time of the recording's first frame (s since 1970-01-01 UTC), else
  the raw header's ``start_time``; for a filtered file its first row's ``host_time_s``;
  unknown (NaN) when the file has none.
- Convention: ``Options.joints.convention`` of the processor that computed the angles, in
  words (:data:`bpms.filter.joints.CONVENTION_TEXT`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bpms.analysis.binary_out import utc_iso
from bpms.filter.joints import CONVENTION_TEXT


@dataclass(frozen=True)
class Stamp:
    """utc_start: s since 1970 (UTC) of frame 0, NaN unknown; convention: ``isb`` or
    ``original``."""

    utc_start: float
    convention: str
    #: the heading reference's header text (``FilterOptions.heading``; 6D: ``relative``)
    heading: str = ""

    @property
    def utc_text(self) -> str:
        """``2026-11-30T08:12:41.250Z`` or ``unknown``."""
        return utc_iso(self.utc_start) if math.isfinite(self.utc_start) else "unknown"

    @property
    def convention_text(self) -> str:
        return CONVENTION_TEXT.get(self.convention, self.convention)

    def items(self) -> list[tuple[str, str]]:
        """``[("utc_start", ...), ("joint_angle_convention", ...), ("heading", ...)]`` for
        header lines."""
        items = [("utc_start", self.utc_text), ("joint_angle_convention", self.convention_text)]
        return items + ([("heading", self.heading)] if self.heading else [])

    def line(self) -> str:
        """One sentence for stderr."""
        return f"recording started {self.utc_text} UTC; joint angles: {self.convention_text}"


def recording_utc_start(recording) -> float:
    """UTC start (s since 1970) of a recording: a :class:`~bpms.io.rawfile.RawRecording` or a
    recording opened by :func:`bpms.filter.door.open_for_processing` (only its first record or
    row is read). NaN when unknown."""
    rec = getattr(recording, "recording", recording)
    if rec is not None and hasattr(rec, "times"):
        if len(rec.times) and np.isfinite(rec.times[0]):
            return float(rec.times[0])
        return float(rec.header.get("start_time", math.nan))
    kind = getattr(recording, "kind", "")
    if kind == "raw":  # the one reader found it when the recording was opened
        if math.isfinite(recording.first_host_time):
            return float(recording.first_host_time)
    elif kind == "filtered":
        from bpms.io.filtered_file.reader import FilteredReader

        with FilteredReader(recording.path) as reader:
            for block in reader.blocks(1):
                return float(block.host_time[0]) if len(block) else math.nan
        return math.nan
    return float(recording.header.get("start_time", math.nan))


def recording_stamp(opened) -> Stamp:
    """The :class:`Stamp` of a recording opened by :func:`bpms.filter.door.
    open_for_processing`."""
    from bpms.filter.door import heading_header

    options = opened.processor.options
    return Stamp(recording_utc_start(opened), options.joints.convention,
                 heading_header(options)["heading"])
