"""Open any raw recording the suite can replay: the native format or a legacy pickle."""

from __future__ import annotations

from pathlib import Path

from bpms.io.rawfile import MAGIC, RawFileError, RawRecording, read_raw


def open_recording(path: str | Path) -> RawRecording:
    """Read a native ``.bpmsraw`` recording or a legacy pickled raw file (read-only, through
    the restricted unpickler). Raises :class:`RawFileError` with a one-line reason."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            head = f.read(len(MAGIC))
    except OSError as exc:
        raise RawFileError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if head == MAGIC:
        return read_raw(path)
    from bpms.io.legacy_raw import is_legacy_raw, read_legacy_raw

    if is_legacy_raw(path):
        return read_legacy_raw(path)
    raise RawFileError(f"{path}: not a BPMS raw recording (neither the native format nor a "
                       "legacy pickled raw file)")
