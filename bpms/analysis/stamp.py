"""What every export states about its recording (issue 16.5) and where it came from (issue
43.5): the UTC start time, the joint-angle convention of the angles written, the heading
reference, and the provenance computed here once for every format (:func:`provenance`):

- ``bpms_version``: the version, with the commit (and ``+dirty`` for uncommitted changes)
  when bpms runs from a git checkout;
- ``filter``: the attitude filter and its settings in force (``FilterOptions``: the
  algorithm's own gains, the time step, the heading reference);
- ``reset_zero``: which Reset Zero the angles rest on (``--reset-zero``, extra ``--reset-at``
  captures);
- ``recording``: the input recording's file name.

- UTC start: the host receive time of the recording's first frame (s since 1970-01-01 UTC), else
  the raw header's ``start_time``; for a filtered file its first row's ``host_time_s``;
  unknown (NaN) when the file has none.
- Convention: ``Options.joints.convention`` of the processor that computed the angles, in
  words (:data:`bpms.filter.joints.CONVENTION_TEXT`).
"""

from __future__ import annotations

import functools
import math
import subprocess
from dataclasses import dataclass
from pathlib import Path

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
    #: :func:`provenance` pairs
    origin: tuple[tuple[str, str], ...] = ()

    @property
    def utc_text(self) -> str:
        """``2026-11-30T08:12:41.250Z`` or ``unknown``."""
        return utc_iso(self.utc_start) if math.isfinite(self.utc_start) else "unknown"

    @property
    def convention_text(self) -> str:
        return CONVENTION_TEXT.get(self.convention, self.convention)

    def items(self) -> list[tuple[str, str]]:
        """``[("utc_start", ...), ("joint_angle_convention", ...), ("heading", ...)]`` and the
        :func:`provenance` pairs, for header lines."""
        items = [("utc_start", self.utc_text), ("joint_angle_convention", self.convention_text)]
        return items + ([("heading", self.heading)] if self.heading else []) + list(self.origin)

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


def recording_stamp(opened, zero_at_s=()) -> Stamp:
    """The :class:`Stamp` of a recording opened by :func:`bpms.filter.door.
    open_for_processing`; ``zero_at_s``: extra Reset Zero captures (s) of the command."""
    from bpms.filter.door import heading_header

    options = opened.processor.options
    return Stamp(recording_utc_start(opened), options.joints.convention,
                 heading_header(options)["heading"],
                 tuple(provenance(opened, zero_at_s).items()))


@functools.lru_cache(maxsize=1)
def bpms_version() -> str:
    """``0.2.0``, or ``0.2.0 (commit 1a2b3c4d5e6f)`` (``+dirty`` with uncommitted changes)
    when bpms runs from a git checkout and git answers within 5 s."""
    import bpms

    version = bpms.__version__
    root = Path(bpms.__file__).resolve().parent.parent
    if not (root / ".git").exists():
        return version
    try:
        def git(*words: str) -> str:
            return subprocess.run(["git", "-C", str(root), *words], capture_output=True,
                                  text=True, timeout=5, check=True).stdout.strip()

        commit = git("rev-parse", "--short=12", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.SubprocessError):
        return version
    return f"{version} (commit {commit}{'+dirty' if dirty else ''})" if commit else version


#: FilterOptions prefixes of one algorithm's own settings.
_ALGORITHM_PREFIXES = ("observer_", "vqf_", "adaptive_")


def filter_text(options) -> str:
    """``mahony (kp_rollpitch 0.02, ki_rollpitch 2e-05, ..., dt 0.02, heading magnetic)``:
    the algorithm of ``options`` (an :class:`bpms.io.options.Options`) and the settings it
    uses."""
    from dataclasses import fields

    f = options.filter
    own = {"observer": ("observer_",), "vqf": ("vqf_",),
           "adaptive": ("adaptive_", "observer_k_bias", "observer_tau_acc_s",
                        "observer_mag_new_time_s")}.get(f.algorithm, ("kp_", "ki_"))
    parts = []
    for field in fields(f):
        name = field.name
        if name == "algorithm":
            continue
        shared = not name.startswith((*_ALGORITHM_PREFIXES, "kp_", "ki_"))
        if shared or name.startswith(own):
            value = getattr(f, name)
            parts.append(f"{name} {value:g}" if isinstance(value, float) else f"{name} {value}")
    return f"{f.algorithm} ({', '.join(parts)})"


def provenance(opened, zero_at_s=()) -> dict[str, str]:
    """Where an output of ``opened`` (:func:`bpms.filter.door.open_for_processing`) comes
    from: ``bpms_version``, ``filter``, ``reset_zero``, ``recording`` (see the module)."""
    choice = opened.reset_zero
    reset = choice.describe()
    if choice.mode == "events" and not opened.has_events:
        reset = "automatic Reset Zero (the recording holds no Reset Zero events)"
    if len(zero_at_s):
        reset += "; extra captures at " + ", ".join(f"{float(t):g} s" for t in zero_at_s)
    return {"bpms_version": bpms_version(), "filter": filter_text(opened.processor.options),
            "reset_zero": reset, "recording": Path(opened.path).name}
