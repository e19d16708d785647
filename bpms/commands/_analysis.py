"""Shared by the analysis commands (not a command: the leading underscore): open a recording
through the one door (:func:`bpms.filter.door.open_for_processing`) and stream it, with CLI
error handling."""

from __future__ import annotations

import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager

from bpms.commands import CliError
from bpms.commands._shared import warn

__all__ = ["open_recording_for", "stream"]


@contextmanager
def _read_errors(path: str, *kinds: type[Exception]) -> Iterator[None]:
    """An exception of ``kinds`` as a CliError of its text, an OSError as ``PATH: reason``."""
    try:
        yield
    except kinds as exc:
        raise CliError(str(exc)) from exc
    except OSError as exc:
        raise CliError(f"{path}: {exc.strerror or exc}") from exc


def open_recording_for(command: str, path: str, calibration: str | None = None,
                       options: str | None = None, algorithm: str | None = None,
                       heading: str | None = None, reset_zero=None,
                       pose_calibration: str | None = None, posture: str | None = None):
    """The door, with one-line errors; prints ``calibration: …; options: …`` and the
    warnings so far on stderr. Returns the :class:`bpms.filter.door.OpenedRecording`."""
    from bpms.filter.door import open_for_processing
    from bpms.filter.vqf_filter import VqfMissingError
    from bpms.io.filtered_file.reader import FilteredFileError
    from bpms.io.rawfile import RawFileError

    with _read_errors(path, RawFileError, FilteredFileError, VqfMissingError):
        opened = open_for_processing(path, calibration, options, algorithm, heading,
                                     reset_zero)
    print(f"bpms {command}: {opened.sources_line()}", file=sys.stderr)
    warn(command, opened.problems)
    if opened.n_frames == 0:
        raise CliError(f"{path}: the recording holds no frames")
    if pose_calibration not in (None, "reset-zero") or posture is not None:
        with _read_errors(path, ValueError):
            what = opened.use_pose_calibration(pose_calibration, posture)
        print(f"bpms {command}: pose calibration: {what}", file=sys.stderr)
        report = opened.pose_report
        for line in report.lines() if report is not None else []:
            print(f"bpms {command}:   {line}", file=sys.stderr)
    return opened  # its problems stay: the door adds only new ones as it reads


def stream(command: str, opened, zero_at_s: Sequence[float] = ()) -> Iterator:
    """The recording's chunks (:class:`bpms.filter.door.Chunk`) with progress on stderr;
    warnings met on the way are printed at the end. Raises CliError for a read error."""
    from bpms.io.filtered_file.reader import FilteredFileError
    from bpms.progress import stderr_progress

    shown = set(opened.problems)  # printed already (each warning once)
    with _read_errors(opened.path, FilteredFileError):
        yield from opened.chunks(zero_at_s, stderr_progress)
    warn(command, [p for p in opened.problems if p not in shown])
