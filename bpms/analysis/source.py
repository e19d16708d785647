"""Compatibility names for the analysis commands; the door itself is
:func:`bpms.filter.door.open_for_processing` (streaming, precedence, sources)."""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bpms.filter.door import CHUNK_FRAMES, is_raw_recording, open_for_processing
from bpms.io.options import Options

Progress = Callable[[str, int, int], None]

__all__ = ["CHUNK_FRAMES", "Processed", "is_raw_recording", "process_recording",
           "stderr_progress"]


def stderr_progress(label: str, done: int, total: int) -> None:
    """Progress on stderr (``label: 42% (n/N frames)``) for more than 30,000 frames: in place
    on a terminal, else a plain line every 10 % or 5 s (:mod:`bpms.progress`)."""
    if total <= 30_000:
        return
    from bpms.progress import report

    report(label, done, total, sys.stderr)


@dataclass
class Processed:
    """A whole recording and its filter result (memory grows with the recording: the
    commands stream :meth:`bpms.filter.door.OpenedRecording.chunks` instead)."""

    recording: object  # OpenedRecording
    processor: object  # BodyPoseProcessor
    result: object  # Result
    raw: np.ndarray | None  # [N, 18, 9] int16 counts (None for a filtered file)
    errors: np.ndarray | None  # [N, 18, 3] bool


def process_recording(path: str | Path, calibration: str | Path | None = None,
                      options: str | Path | Options | None = None,
                      zero_at_s: Sequence[float] = (),
                      progress: Progress | None = stderr_progress,
                      algorithm: str | None = None, heading: str | None = None,
                      reset_zero=None) -> Processed:
    """A whole recording through the door, joined into one Result (for small recordings and
    the Python API); ``reset_zero``: :mod:`bpms.filter.zero_choice`."""
    opened = open_for_processing(path, calibration, options, algorithm, heading, reset_zero)
    chunks = list(opened.chunks(zero_at_s, progress))
    from bpms.filter.result import Result

    options = opened.processor.options
    result = (Result.concat([c.result for c in chunks]) if chunks
              else Result.empty(options.body, options.joints.convention))
    result.problems.extend(opened.problems)
    result.calibration_source = opened.calibration_source
    result.options_source = opened.options_source
    raw = np.concatenate([c.raw for c in chunks]) if opened.has_raw and chunks else None
    errors = np.concatenate([c.errors for c in chunks]) if opened.has_raw and chunks else None
    return Processed(opened, opened.processor, result, raw, errors)
