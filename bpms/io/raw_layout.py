"""The bytes of a native raw recording (``.bpmsraw``, docs/raw-format.md): preamble, header,
frame records and (version 2) event records.

::

    offset        size   content
    0             8      magic b"BPMSRAW\\0"
    8             2      format version, little-endian uint16 (currently 2)
    10            4      header length H, little-endian uint32
    14            H      header: UTF-8 JSON (start time, calibration, options, notes, ...),
                         padded with spaces so the records start on a 16-byte boundary
    D = 14+H      ...    records, in the order they were written:

    frame record (348 bytes): host receive time (float64 LE, s since the epoch), then the
        340-byte frame exactly as received ("$#" at record offset 8, "#$" at offset 346)
    event record (version 2, 20 + L bytes, L ≤ 65,536): time (float64 LE), "$E", L (uint32
        LE), L bytes of UTF-8 JSON (:meth:`bpms.io.session_events.SessionEvent.to_json`),
        CRC-32 (uint32 LE) of the record's bytes before it, "E$"

An event record takes no frame slot: frame k is the k-th frame record, whatever the events
between. Its markers differ from a frame's at the same offset (``$E`` where a frame has
``$#``), so a reader tells the two apart at once, and its CRC makes a damaged event lose only
itself.
"""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from bpms.io.bounded import MAX_HEADER_BYTES, BoundError, check_size, loads_json
from bpms.io.frames import FRAME_DTYPE, FRAME_SIZE
from bpms.io.paths import require_regular_input
from bpms.io.session_events import SessionEvent
from bpms.io.timebase import plausible_host_time

MAGIC = b"BPMSRAW\0"
FORMAT_VERSION = 2
#: The first version with event records (version 1 holds frame records only).
EVENTS_VERSION = 2
EXTENSION = ".bpmsraw"
PREAMBLE = struct.Struct("<8sHI")
RECORD_DTYPE = np.dtype([("time", "<f8"), ("frame", FRAME_DTYPE)])
RECORD_SIZE = RECORD_DTYPE.itemsize
assert RECORD_SIZE == 8 + FRAME_SIZE

FRAME_START, FRAME_END = b"$#", b"#$"
EVENT_START, EVENT_END = b"$E", b"E$"
EVENT_HEAD = struct.Struct("<d2sI")  # time, "$E", payload length
EVENT_TAIL = struct.Struct("<I2s")  # CRC-32, "E$"
EVENT_OVERHEAD = EVENT_HEAD.size + EVENT_TAIL.size
MAX_EVENT_PAYLOAD = 65_536


class RawFileError(Exception):
    """A file that cannot be read as a BPMS raw recording (message says why)."""


class RecordingError(Exception):
    """Writing a recording failed (disk full, folder not writable): recording must stop."""


def header_bytes(header: dict[str, Any]) -> bytes:
    """The header text, padded with spaces so records start on a 16-byte boundary."""
    text = json.dumps(header, indent=1, sort_keys=True).encode("utf-8")
    pad = (-(PREAMBLE.size + len(text))) % 16
    return text + b" " * pad


def read_header(path: str | Path) -> tuple[dict[str, Any], int]:
    """(header dict, offset of the first record). Raises RawFileError."""
    header, offset, _ = read_preamble(path)
    return header, offset


def read_preamble(path: str | Path) -> tuple[dict[str, Any], int, int]:
    """(header dict, offset of the first record, format version). Raises RawFileError."""
    path = Path(path)
    try:
        require_regular_input(path)
        with path.open("rb") as f:
            preamble = f.read(PREAMBLE.size)
            if len(preamble) < PREAMBLE.size or not preamble.startswith(MAGIC):
                raise RawFileError(f"{path}: not a BPMS raw recording (no BPMSRAW signature)")
            _, version, length = PREAMBLE.unpack(preamble)
            if version > FORMAT_VERSION:
                raise RawFileError(
                    f"{path}: raw format version {version} is newer than this software "
                    f"({FORMAT_VERSION}); update BPMS Suite")
            try:  # bounded before anything is read or parsed (bpms/io/bounded.py)
                check_size(length, MAX_HEADER_BYTES, "the header")
            except BoundError as exc:
                raise RawFileError(f"{path}: {exc}") from None
            text = f.read(length)
    except OSError as exc:
        raise RawFileError(f"{path}: cannot be read ({exc.strerror or exc})") from exc
    if len(text) < length:
        raise RawFileError(f"{path}: the header is cut short ({len(text)} of {length} bytes)")
    try:
        header = loads_json(text.decode("utf-8"), "the header")
    except BoundError as exc:
        raise RawFileError(f"{path}: {exc}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RawFileError(f"{path}: the header is damaged ({exc})") from exc
    if not isinstance(header, dict):
        raise RawFileError(f"{path}: the header is not a JSON object")
    return header, PREAMBLE.size + length, version


def event_record(event: SessionEvent, host_time: float) -> bytes:
    """The bytes of one event record (``host_time``: s since the epoch, when written)."""
    payload = event.to_json()
    if len(payload) > MAX_EVENT_PAYLOAD:
        raise ValueError(f"an event holds at most {MAX_EVENT_PAYLOAD} bytes, "
                         f"got {len(payload)}")
    head = EVENT_HEAD.pack(float(host_time), EVENT_START, len(payload)) + payload
    return head + EVENT_TAIL.pack(zlib.crc32(head), EVENT_END)


def event_size_at(data: bytes, q: int) -> int | None:
    """The size of the event record whose header starts at ``q`` (its marker and length
    plausible), or None. The record may extend beyond ``data``."""
    if data[q + 8:q + 10] != EVENT_START or q + EVENT_HEAD.size > len(data):
        return None
    length = struct.unpack_from("<I", data, q + 10)[0]
    if length > MAX_EVENT_PAYLOAD:
        return None
    return EVENT_OVERHEAD + length


def parse_event(data: bytes, q: int, size: int) -> SessionEvent | None:
    """The event record of ``size`` bytes at ``q`` (wholly inside ``data``), or None when its
    end marker, CRC or JSON is wrong."""
    end = q + size
    if data[end - 2:end] != EVENT_END:
        return None
    crc = struct.unpack_from("<I", data, end - EVENT_TAIL.size)[0]
    if zlib.crc32(data[q:end - EVENT_TAIL.size]) != crc:
        return None
    try:
        event = SessionEvent.from_json(data[q + EVENT_HEAD.size:end - EVENT_TAIL.size])
    except ValueError:
        return None
    if not plausible_host_time(event.time):  # not in the JSON, or no clock's: the record's
        record_time = struct.unpack_from("<d", data, q)[0]  # (checked as the frame index is)
        event = SessionEvent(event.kind, event.frame, record_time
                             if plausible_host_time(record_time) else float("nan"), event.data)
    return event


def is_frame_record_at(data: bytes, q: int) -> bool:
    """A frame record's markers at ``q`` (the record wholly inside ``data``)."""
    return (data[q + 8:q + 10] == FRAME_START
            and data[q + RECORD_SIZE - 2:q + RECORD_SIZE] == FRAME_END)
