"""Filter a raw recording chunk by chunk into the binary writers (:mod:`binary_out`): constant
memory for Parquet, one pass for several formats."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from bpms.analysis.binary_out import ExportMeta, open_writer
from bpms.analysis.source import CHUNK_FRAMES, header_calibration, header_options
from bpms.io.calib_file import load_calibration
from bpms.io.options import Options, load_options
from bpms.io.recordings import open_recording


@dataclass
class ExportSummary:
    frames: int
    utc_start: str
    convention: str
    written: dict[str, Path] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)


def recording_utc_start(recording) -> float:
    """UTC start (s since 1970) of a recording: the receive time of its first frame, else the
    header's start time."""
    if len(recording.times):
        return float(recording.times[0])
    return float(recording.header.get("start_time", 0.0))


@dataclass
class Opened:
    """A recording ready to filter chunk by chunk (see :func:`open_for_processing`)."""

    recording: object  # RawRecording
    decoded: object  # DecodedFrames
    processor: object  # BodyPoseProcessor
    meta: ExportMeta

    def __len__(self) -> int:
        return len(self.decoded.raw)

    def chunks(self, size: int = CHUNK_FRAMES) -> Iterator:
        """The filter results of consecutive chunks (one stream, the same numbers as one
        call over the whole recording)."""
        raw, errors = self.decoded.raw, self.decoded.errors
        for lo in range(0, len(raw), size):
            yield self.processor.process(raw[lo:lo + size], errors[lo:lo + size])


def open_for_processing(path: str | Path, calibration: str | Path | None = None,
                        options: str | Path | Options | None = None) -> Opened:
    """Open a raw recording with its stored calibration and options (or the given ones).
    Raises RawFileError for an unreadable file."""
    from bpms.filter.processor import BodyPoseProcessor

    # one door: open the recording (and build its processor) through the single entry point
    recording = open_recording(path)
    decoded = recording.decode()
    table = load_calibration(calibration) if calibration else header_calibration(recording)
    if isinstance(options, Options):
        opts = options
    else:
        opts = load_options(options) if options else (header_options(recording) or Options())
    proc = BodyPoseProcessor(table, opts)
    meta = ExportMeta(recording_utc_start(recording), proc.options.joints.convention,
                      1.0 / proc.options.filter.dt, str(path), n_frames=len(decoded.raw))
    return Opened(recording, decoded, proc, meta)


def export_recording(path: str | Path, outputs: dict[str, str | Path],
                     calibration: str | Path | None = None,
                     options: str | Path | Options | None = None,
                     progress: Callable[[str, int, int], None] | None = None) -> ExportSummary:
    """Filter ``path`` and write each ``outputs[kind] = target`` (kinds of
    :data:`bpms.analysis.binary_out.KINDS`). Raises RawFileError for an unreadable file,
    OSError when a target cannot be written."""
    opened = open_for_processing(path, calibration, options)
    meta = opened.meta
    writers = {kind: open_writer(kind, target, meta) for kind, target in outputs.items()}
    n = len(opened)
    done = 0
    try:
        for result in opened.chunks():
            for writer in writers.values():
                writer.write(result)
            done += len(result)
            if progress:
                progress(f"exporting {Path(path).name}", done, n)
    finally:
        for writer in writers.values():
            writer.close()
    return ExportSummary(n, meta.utc_iso, meta.convention,
                         {k: Path(v) for k, v in outputs.items()},
                         [*opened.processor.problems, *opened.recording.problems])
