"""Filter a raw recording chunk by chunk into the binary writers (:mod:`binary_out`): constant
memory for Parquet, one pass for several formats."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bpms.analysis.binary_out import ExportMeta, open_writer
from bpms.analysis.stamp import provenance, recording_utc_start
from bpms.filter.door import CHUNK_FRAMES
from bpms.io.options import Options


class NoUsableFramesError(Exception):
    """The recording has no frame with joint angles (no Reset Zero, every IMU failed): the
    outputs are removed; the message says why in one line."""


@dataclass
class ExportSummary:
    frames: int
    utc_start: str
    convention: str
    written: dict[str, Path] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)


@dataclass
class Opened:
    """A recording ready to filter chunk by chunk (see :func:`open_for_processing`).

    door: the :class:`bpms.filter.door.OpenedRecording`; meta: what every export states."""

    door: object  # OpenedRecording
    meta: ExportMeta

    @property
    def problems(self) -> list[str]:
        return self.door.problems

    def __len__(self) -> int:
        return self.door.n_frames

    def chunks(self, size: int = CHUNK_FRAMES) -> Iterator:
        """The filter results of consecutive chunks (one stream, the same numbers as one
        call over the whole recording)."""
        for chunk in self.door.chunks(chunk_frames=size):
            yield chunk.result


def open_for_processing(path: str | Path, calibration: str | Path | None = None,
                        options: str | Path | Options | None = None,
                        reset_zero=None) -> Opened:
    """Open a raw recording through the one door (:func:`bpms.filter.door.open_for_processing`:
    the given calibration / options, else the recording's, else the user's default, else
    factory). Raises RawFileError for an unreadable file or a filtered file."""
    from bpms.filter.door import heading_header
    from bpms.filter.door import open_for_processing as door_open
    from bpms.io.rawfile import RawFileError

    door = door_open(path, calibration, options, reset_zero=reset_zero)
    if not door.has_raw:
        raise RawFileError(f"{path}: a filtered file; give a raw recording")
    proc = door.processor
    start = recording_utc_start(door)
    meta = ExportMeta(start if math.isfinite(start) else 0.0, proc.options.joints.convention,
                      1.0 / proc.options.filter.dt, str(path),
                      extra={**heading_header(proc.options), **provenance(door)},
                      n_frames=door.n_frames)
    return Opened(door, meta)


def export_recording(path: str | Path, outputs: dict[str, str | Path],
                     calibration: str | Path | None = None,
                     options: str | Path | Options | None = None,
                     progress: Callable[[str, int, int], None] | None = None,
                     reset_zero=None) -> ExportSummary:
    """Filter ``path`` and write each ``outputs[kind] = target`` (kinds of
    :data:`bpms.analysis.binary_out.KINDS`). Raises RawFileError for an unreadable file,
    OSError when a target cannot be written."""
    opened = open_for_processing(path, calibration, options, reset_zero)
    meta = opened.meta
    writers = {kind: open_writer(kind, target, meta) for kind, target in outputs.items()}
    n = len(opened)
    done = usable = 0
    try:
        for result in opened.chunks():
            for writer in writers.values():
                writer.write(result)
            done += len(result)
            usable += int(np.isfinite(result.joint_angles).any(axis=1).sum())
            if progress:
                progress(f"exporting {Path(path).name}", done, n)
    finally:
        for writer in writers.values():
            writer.close()
    if done and not usable:
        for target in outputs.values():
            Path(target).unlink(missing_ok=True)
        raise NoUsableFramesError(f"{path}: no frame with joint angles to export ({done} frames, "
                             "none after a Reset Zero with its IMUs working: try --reset-zero "
                             "auto); nothing written")
    return ExportSummary(n, meta.utc_iso, meta.convention,
                         {k: Path(v) for k, v in outputs.items()},
                         list(opened.problems))
