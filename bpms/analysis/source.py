"""Open a raw recording and filter it with the calibration and options stored in its header
(or given files), in chunks so that long recordings show progress on stderr."""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bpms.io.calib_file import CalibrationTable, load_calibration
from bpms.io.options import Options, load_options, options_from_dict
from bpms.io.rawfile import RawRecording
from bpms.io.recordings import open_recording

CHUNK_FRAMES = 15_000  # 5 min of recording per filter call
Progress = Callable[[str, int, int], None]


def stderr_progress(label: str, done: int, total: int) -> None:
    """Progress line on stderr (``label: 42% (n/N frames)``), for more than 30,000 frames."""
    if total <= 30_000:
        return
    from bpms.progress import write_progress  # \r only on a terminal

    write_progress(f"{label}: {100 * done // max(total, 1):3d}% ({done}/{total} frames)",
                   sys.stderr, final=done >= total)


def header_calibration(recording: RawRecording) -> CalibrationTable | None:
    """The calibration table stored in the recording's header, or None (factory)."""
    values = recording.header.get("calibration")
    if values is None:
        return None
    try:
        return CalibrationTable(np.asarray(values, dtype=np.float64),
                                source=f"{recording.path} header")
    except (ValueError, TypeError):
        return None


def header_options(recording: RawRecording) -> Options | None:
    """The options stored in the recording's header, or None (factory)."""
    stored = recording.header.get("options")
    if isinstance(stored, dict) and stored:
        return options_from_dict(stored, f"{recording.path} header")
    return None


@dataclass
class Processed:
    """A recording and its filter result (:class:`bpms.filter.processor.Result`).

    For a filtered CSV input ``recording``, ``raw`` and ``errors`` are None: the result is
    rebuilt from the file's Euler angles (see :func:`load_filtered`).
    """

    recording: RawRecording | None
    processor: object  # BodyPoseProcessor (imported lazily: numba)
    result: object  # Result
    raw: np.ndarray | None  # [N, 18, 9] int16 counts
    errors: np.ndarray | None  # [N, 18, 3] bool


def is_raw_recording(path: str | Path) -> bool:
    """True for a native raw recording or a legacy pickled raw file."""
    from bpms.io.legacy_raw import is_legacy_raw
    from bpms.io.rawfile import MAGIC

    try:
        with open(path, "rb") as f:
            if f.read(len(MAGIC)) == MAGIC:
                return True
    except OSError:
        return False
    return is_legacy_raw(path)


def load_filtered(path: str | Path, options: str | Path | Options | None = None,
                  zero_at_s: Sequence[float] = ()) -> Processed:
    """A filtered CSV file (:mod:`bpms.io.filtered_file`) as a filter result: ``R`` from the
    logged Euler angles (``Rz Ry Rx``, docs/filter.md), segment orientations ``C`` by the same
    Reset Zero as the processor (:class:`bpms.filter.pose.PoseCalibrator`), hence the joint
    angles and positions. Raises :class:`bpms.io.filtered_file.FilteredFileError`."""
    from bpms.filter.processor import BodyPoseProcessor, Result
    from bpms.filter.rotations import euler_to_dcm
    from bpms.io.filtered_file import read_filtered

    data = read_filtered(path)
    opts = options if isinstance(options, Options) else load_options(options)
    proc = BodyPoseProcessor(None, opts)
    R = euler_to_dcm(data.euler[..., 0], data.euler[..., 1], data.euler[..., 2])
    dt = proc.options.filter.dt
    C = proc.pose.apply(R, [round(t / dt) for t in zero_at_s])
    result = Result(t=data.t, R=R, euler=data.euler, C=C, body=proc.options.body,
                    zeros=list(proc.pose.captures), convention=proc.options.joints.convention)
    result.problems.extend(data.problems)
    return Processed(None, proc, result, None, None)


def process_recording(path: str | Path, calibration: str | Path | None = None,
                      options: str | Path | Options | None = None,
                      zero_at_s: Sequence[float] = (),
                      progress: Progress | None = stderr_progress,
                      algorithm: str | None = None, heading: str | None = None) -> Processed:
    """Filter a whole raw recording as one stream (the same numbers as
    ``BodyPoseProcessor.process_file``), chunk by chunk with progress.

    zero_at_s: extra Reset Zero captures, s since the stream started (fixed 50 Hz clock).
    algorithm: the attitude filter (``FilterOptions.algorithm``), overriding the options;
    heading: the Reset Zero heading reference (``PoseOptions.heading_reference``), likewise.
    Raises :class:`bpms.io.rawfile.RawFileError` for an unreadable file.
    """
    from bpms.filter.processor import BodyPoseProcessor, Result

    if str(path).lower().endswith((".csv", ".txt")) and not is_raw_recording(path):
        return load_filtered(path, options, zero_at_s)

    recording = open_recording(path)
    decoded = recording.decode()
    table = load_calibration(calibration) if calibration else header_calibration(recording)
    if isinstance(options, Options):
        opts: Options | None = options
    else:
        opts = load_options(options) if options else header_options(recording)
    if algorithm is not None or heading is not None:
        opts = opts or Options()
        opts.filter.algorithm = algorithm or opts.filter.algorithm
        opts.pose.heading_reference = heading or opts.pose.heading_reference
    proc = BodyPoseProcessor(table, opts)
    dt = proc.options.filter.dt
    zero_frames = sorted({round(t / dt) for t in zero_at_s})
    n = len(decoded.raw)
    parts = []
    label = f"filtering {Path(path).name}"
    for lo in range(0, max(n, 1), CHUNK_FRAMES):
        hi = min(n, lo + CHUNK_FRAMES)
        zeros = [k - lo for k in zero_frames if lo <= k < hi]
        parts.append(proc.process(decoded.raw[lo:hi], decoded.errors[lo:hi], zeros))
        if progress:
            progress(label, hi, n)
    if len(parts) == 1:
        result = parts[0]
    else:
        result = Result(t=np.concatenate([p.t for p in parts]),
                        R=np.concatenate([p.R for p in parts]),
                        euler=np.concatenate([p.euler for p in parts]),
                        C=np.concatenate([p.C for p in parts]), body=proc.options.body,
                        held_count=parts[-1].held_count,
                        zeros=[z for p in parts for z in p.zeros],
                        convention=proc.options.joints.convention)
    result.problems.extend([*proc.problems, *recording.problems])
    return Processed(recording, proc, result, decoded.raw, decoded.errors)
