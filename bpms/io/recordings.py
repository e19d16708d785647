"""Open any raw recording the suite can replay: the native format or a legacy pickle."""

from __future__ import annotations

from pathlib import Path

from bpms.io.paths import require_regular_input
from bpms.io.raw_reader import RawFrames, no_frame_message
from bpms.io.rawfile import MAGIC, RawFileError, RawRecording, read_raw


def read_head(path: Path) -> bytes:
    """The first bytes of ``path``, as many as the native format's magic. Raises
    :class:`RawFileError` with a one-line reason when the file cannot be read."""
    try:
        require_regular_input(path)  # a named pipe would block the open for ever
        with path.open("rb") as f:
            return f.read(len(MAGIC))
    except OSError as exc:
        raise RawFileError(f"{path}: cannot be read ({exc.strerror or exc})") from None


def open_recording(path: str | Path) -> RawRecording:
    """Read a native ``.bpmsraw`` recording or a legacy pickled raw file (read-only, through
    the restricted unpickler). Raises :class:`RawFileError` with a one-line reason."""
    path = Path(path)
    if read_head(path) == MAGIC:
        return read_raw(path)
    from bpms.io.legacy_raw import is_legacy_raw, read_legacy_raw

    if is_legacy_raw(path):
        return read_legacy_raw(path)
    raise RawFileError(f"{path}: not a BPMS raw recording (neither the native format nor a "
                       "legacy pickled raw file)")


def open_replay(path: str | Path) -> RawFrames | RawRecording:
    """A recording to play (``bpms replay``, GUI playback): a native one read from disk as it
    plays (:class:`bpms.io.raw_reader.RawFrames`: memory flat however long), a legacy one in
    memory. Raises :class:`RawFileError` with a one-line reason, also when the recording holds
    no valid frame."""
    path = Path(path)
    recording = RawFrames(path) if read_head(path) == MAGIC else open_recording(path)
    if recording.valid_frames == 0:
        raise RawFileError(no_frame_message(path, len(recording)))
    return recording
