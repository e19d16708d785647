"""Reader for the original suite's raw files (docs/raw-format.md), without ever executing code.

The original (Python 2.7) wrote one ``pickle.dump([host_time, frame_str], f)`` per frame,
protocol 0 (text) by default, 1 or 2 possibly; ``frame_str`` is the 340-byte frame as a Python 2
byte string. Pickle can call any importable function, so these files are read through a
restricted unpickler:

- ``find_class`` refuses every global except ``_codecs.encode``, which is replaced by a
  function that only turns a str into latin-1 bytes (that is how Python 3 writes ``bytes`` at
  protocols 0–2). This also covers GLOBAL, STACK_GLOBAL, INST and the EXT1/2/4 extension
  codes, which all go through ``find_class``.
- ``persistent_load`` refuses PERSID / BINPERSID.
- REDUCE, OBJ, NEWOBJ and BUILD can only call what is on the stack; with no global available
  nothing callable but the latin-1 function ever gets there.
- Each record must then be a list or tuple ``[time, frame]`` with a finite float (or an int
  that fits in 64 bits: a 400-digit int is a bad record, not an ``OverflowError``) time and a
  str (latin-1 code points) or bytes frame.

Python 2 strings are loaded with ``encoding="latin1"`` (every byte ↦ one code point) and turned
back into the original bytes with ``.encode("latin1")``.

Reading is linear in the file size: each record is unpickled from a window of at most
:data:`MAX_RECORD_BYTES`, and the search for the next record start after damage never scans
the same bytes twice.

A record whose frame lacks the ``$#``/``#$`` markers or is not 340 bytes is skipped with a
warning ("File Error" in the original) and counted; a damaged record is skipped by
re-synchronising on the next record start; a cut-off last record ends the file with a
warning. A file that asks for any global (a malicious or foreign pickle) is refused as a
whole with :class:`~bpms.io.rawfile.RawFileError`, before anything can run.
"""

from __future__ import annotations

import io
import logging
import math
import pickle
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from bpms.io.frames import FRAME_DTYPE, FRAME_SIZE, is_frame
from bpms.io.paths import require_regular_input
from bpms.io.rawfile import RawFileError, RawRecording

log = logging.getLogger(__name__)

FORMAT_NAME = "legacy pickle"
#: Bytes read to sniff a file (a protocol-0 record with an escaped frame is < 1,500 bytes).
SNIFF_BYTES = 4096
#: Longest record the reader accepts, bytes (Python 3's protocol 0 writes a 340-byte frame
#: in at most ~2,100). Each attempt to read a record sees only this many bytes, so the time
#: to read a file is linear in its size whatever a crafted file holds.
MAX_RECORD_BYTES = 4096


class RefusedPickle(pickle.UnpicklingError):
    """The pickle asked for something a raw file never contains (a global, a persistent id)."""


_LATIN1_NAMES = {"latin1", "latin-1", "iso-8859-1", "iso8859-1", "l1", "latin_1"}


def _latin1_encode(text: object, encoding: object = "latin1", *rest: object) -> bytes:
    """Stand-in for ``_codecs.encode`` that only does what Python 3's bytes pickling needs."""
    if rest or not isinstance(text, str) or not isinstance(encoding, str) \
            or encoding.lower() not in _LATIN1_NAMES:
        raise RefusedPickle("the file calls _codecs.encode with unexpected arguments")
    return text.encode("latin1")


class _RestrictedUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        if (module, name) == ("_codecs", "encode"):
            return _latin1_encode
        raise RefusedPickle(f"the file asks to import {module}.{name}")

    def persistent_load(self, pid: Any) -> Any:
        raise RefusedPickle("the file uses a persistent id")


def _load_record(f: io.BufferedIOBase) -> Any:
    with warnings.catch_warnings():
        # Damaged protocol-0 strings hold invalid escapes; the record is judged on its own.
        warnings.simplefilter("ignore", DeprecationWarning)
        return _RestrictedUnpickler(f, encoding="latin1", errors="strict").load()


def _record_fields(obj: Any) -> tuple[float, bytes] | str:
    """(time, frame bytes) from one loaded record, or the reason it is not a raw record."""
    if not isinstance(obj, list | tuple) or len(obj) != 2:
        return f"not a [time, frame] pair ({type(obj).__name__})"
    t, frame = obj
    if isinstance(t, bool) or not isinstance(t, float | int):
        return f"the time is a {type(t).__name__}, not a number"
    if isinstance(t, int) and not -(2 ** 63) <= t < 2 ** 63:  # no float holds a 400-digit int
        return f"the time is an integer of {t.bit_length()} bits, not a time"
    t = float(t)
    if not math.isfinite(t):
        return "the time is not a finite number"
    if isinstance(frame, str):
        try:
            frame = frame.encode("latin1")
        except UnicodeEncodeError:
            return "the frame holds characters that are not bytes"
    elif not isinstance(frame, bytes | bytearray):
        return f"the frame is a {type(frame).__name__}, not a byte string"
    return t, bytes(frame)


def _record_starts(data: bytes) -> tuple[bytes, ...]:
    """Byte patterns that begin a record of the protocol the file starts with."""
    if data.startswith(b"\x80"):
        if len(data) > 2 and data[1] >= 4:  # PROTO, FRAME <8-byte length>, ...
            return (data[:3],)
        return (data[:3] + b"q\x00(", data[:3] + b"(")  # PROTO n, EMPTY_LIST, [BINPUT 0,] MARK
    if data.startswith(b"]"):
        return (b"]q\x00(", b"](")
    return (b"(lp0\n", b"(l")


def is_legacy_raw(path: str | Path) -> bool:
    """True when ``path`` begins with a pickled ``[time, frame]`` list (protocol 0, 1 or 2),
    judged from its first opcodes alone (nothing is unpickled)."""
    try:
        require_regular_input(path)
        with Path(path).open("rb") as f:
            head = f.read(SNIFF_BYTES)
    except OSError:
        return False
    if head.startswith(b"\x80"):
        # PROTO 2..5, [FRAME n (protocol 4+)], then EMPTY_LIST
        if len(head) < 3 or not 2 <= head[1] <= 5:
            return False
        body = head[11:] if head[1] >= 4 and head[2:3] == b"\x95" else head[2:]
        return body[:1] == b"]"
    if head.startswith(b"]"):
        return head[1:2] in (b"q", b"(", b"r")
    return head.startswith(b"(l") and head[2:3] in (b"p", b"F", b"I", b"L", b"a")


def _refused(path: Path, offset: int, exc: Exception) -> RawFileError:
    return RawFileError(
        f"{path}: refused at byte {offset}: {exc}. A BPMS raw file holds only numbers and "
        "byte strings; this one is not a raw file, is damaged or may be malicious. Nothing in "
        "it was run")


def read_legacy_raw(path: str | Path) -> RawRecording:
    """Read an original-suite raw file into the same :class:`RawRecording` as the native
    reader: host times [N] s (as written, seconds since the epoch) and frames [N].

    Bad records are skipped and listed in ``problems``; raises :class:`RawFileError` when the
    file cannot be read, holds no record at all, or asks to run code.
    """
    path = Path(path)
    try:
        require_regular_input(path)
        data = path.read_bytes()
    except OSError as exc:
        raise RawFileError(f"{path}: cannot be read ({exc.strerror or exc})") from exc
    if not is_legacy_raw(path):
        raise RawFileError(f"{path}: not a legacy BPMS raw file (no pickled record at the start)")
    starts = _record_starts(data)
    times: list[float] = []
    frames = bytearray()
    bad_frames: list[int] = []  # record index of each "File Error"
    bad_records: list[tuple[int, str]] = []  # (byte offset, reason)
    damaged: list[tuple[int, int, str]] = []  # (offset, bytes skipped, reason)
    problems: list[str] = []
    next_start = [-2] * len(starts)  # cached next occurrence of each start pattern

    def find_next(after: int) -> int:
        """The next record start after ``after`` (-1: none); each pattern is searched
        forward only, so all searches together scan the file once per pattern."""
        for k, pattern in enumerate(starts):
            if next_start[k] != -1 and next_start[k] <= after:
                next_start[k] = data.find(pattern, after + 1)
        found = [i for i in next_start if i >= 0]
        return min(found) if found else -1

    pos = 0
    index = 0
    while pos < len(data):
        f = io.BytesIO(data[pos : pos + MAX_RECORD_BYTES])
        try:
            obj = _load_record(f)
        except RefusedPickle as exc:
            raise _refused(path, pos, exc) from None
        except Exception as exc:  # any damage in untrusted bytes
            # Skip to the next place a record can start; none left: the file was cut off.
            nxt = find_next(pos)
            reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            if nxt < 0:
                problems.append(f"{path}: the last record (from byte {pos}) is incomplete or "
                                f"damaged ({reason}): the file ends there")
                break
            damaged.append((pos, nxt - pos, reason))
            pos = nxt
            continue
        end = pos + f.tell()
        fields = _record_fields(obj)
        if isinstance(fields, str):
            bad_records.append((pos, fields))
        elif len(fields[1]) != FRAME_SIZE or not is_frame(fields[1]):
            bad_frames.append(index)
        else:
            times.append(fields[0])
            frames += fields[1]
        index += 1
        pos = end
    if bad_frames:
        problems.append(
            f"{path}: File Error: {len(bad_frames)} record(s) whose frame lacks the $#/#$ "
            f"markers or is not {FRAME_SIZE} bytes were skipped (first: record {bad_frames[0]})")
    if bad_records:
        off, why = bad_records[0]
        problems.append(f"{path}: {len(bad_records)} record(s) that are not [time, frame] "
                        f"pairs were skipped (first at byte {off}: {why})")
    if damaged:
        off, n, why = damaged[0]
        total = sum(d[1] for d in damaged)
        problems.append(f"{path}: {len(damaged)} damaged stretch(es), {total} bytes, skipped "
                        f"(first at byte {off}, {n} bytes: {why})")
    for p in problems:
        log.warning("%s", p)
    if not times:
        raise RawFileError(f"{path}: no readable frame in this legacy raw file"
                           + (f" ({problems[0]})" if problems else ""))
    protocol = data[1] if data[:1] == b"\x80" else (1 if data[:1] == b"]" else 0)
    header = {
        "format": FORMAT_NAME,
        "source": "original BPMS suite (Python 2.7 pickle)",
        "pickle_protocol": protocol,
        "records": index,
        "frames": len(times),
        "skipped_frames": len(bad_frames),
        "skipped_records": len(bad_records),
        "damaged_bytes": sum(d[1] for d in damaged),
        "start_time": times[0],
        "frame_size": FRAME_SIZE,
        "frame_rate_hz": 50.0,
    }
    return RawRecording(str(path), header, np.asarray(times, dtype=np.float64),
                        np.frombuffer(bytes(frames), dtype=FRAME_DTYPE).copy(), problems)
