"""MATLAB v5 ``.mat`` files written by hand, the large numeric arrays chunk by chunk.

A v5 ``.mat`` file (MathWorks, "MAT-File Format", level 5) is a 128-byte header followed by
data elements. Each element is an 8-byte tag (type, byte count), its data, and padding to a
multiple of 8 bytes. A variable is an ``miMATRIX`` element holding, in order, its array flags
(class), dimensions, name and values; values are in column-major order.

- The small variables (text, lists of names, a struct of units, scalars) are encoded here:
  text as a ``char`` row (UTF-16 code units), a list of texts as an N×1 ``cell``, a dict as a
  1×1 ``struct``, a number as a 1×1 ``double``.
- For an ``[N, ...]`` numeric array whose N is known in advance, each column (all N values of
  one channel) is a contiguous run in the file, so a chunk of rows ``lo:hi`` is one ``seek`` +
  ``write`` per column into space reserved up front: constant memory for any recording.

No third-party package is needed to write (``bpms convert -f mat`` works on a plain install);
MATLAB's ``load`` and ``scipy.io.loadmat`` read the result (the tests use scipy as the judge).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import BinaryIO

import numpy as np

MI_INT8, MI_INT32, MI_UINT16, MI_UINT32, MI_SINGLE, MI_DOUBLE, MI_MATRIX = 1, 5, 4, 6, 7, 9, 14
MX_CELL, MX_STRUCT, MX_CHAR, MX_DOUBLE, MX_SINGLE = 1, 2, 4, 6, 7
_TYPES = {np.dtype(np.float32): (MI_SINGLE, MX_SINGLE), np.dtype(np.float64): (MI_DOUBLE,
                                                                                MX_DOUBLE)}
#: Longest struct field name MATLAB accepts (``namelengthmax``) + the terminating zero.
_FIELD_NAME_BYTES = 64
E = "<"  # this writer's byte order: little-endian (the header says so; readers follow it)


def _pad8(n: int) -> int:
    return (n + 7) // 8 * 8


def _element(mi_type: int, payload: bytes) -> bytes:
    return struct.pack(f"{E}II", mi_type, len(payload)) + payload + b"\0" * (
        _pad8(len(payload)) - len(payload))


def _matrix(mx_class: int, shape: tuple[int, ...], name: str, body: bytes) -> bytes:
    """An ``miMATRIX`` element: flags, dimensions, name, then ``body`` (already encoded)."""
    inner = (_element(MI_UINT32, struct.pack(f"{E}II", mx_class, 0))
             + _element(MI_INT32, struct.pack(f"{E}{len(shape)}i", *shape))
             + _element(MI_INT8, name.encode("ascii")) + body)
    return struct.pack(f"{E}II", MI_MATRIX, len(inner)) + inner


def encode_variable(name: str, value: object) -> bytes:
    """One variable as a v5 element: ``str`` → char row; a list/tuple (or 1-D object array)
    of ``str`` → N×1 cell; a ``dict`` → 1×1 struct; a number → 1×1 double. ``name`` is ``""``
    inside a cell or struct."""
    if isinstance(value, str):
        units = np.frombuffer(value.encode("utf-16-le"), dtype="<u2")
        return _matrix(MX_CHAR, (1, len(units)), name, _element(MI_UINT16, units.tobytes()))
    if isinstance(value, Mapping):
        fields = [str(k) for k in value]
        for f in fields:
            if not f.isidentifier() or len(f) >= _FIELD_NAME_BYTES:
                raise ValueError(f"{f!r} cannot be a MATLAB struct field name")
        names = b"".join(f.encode("ascii").ljust(_FIELD_NAME_BYTES, b"\0") for f in fields)
        body = (_element(MI_INT32, struct.pack(f"{E}i", _FIELD_NAME_BYTES))
                + _element(MI_INT8, names)
                + b"".join(encode_variable("", value[k]) for k in value))
        return _matrix(MX_STRUCT, (1, 1), name, body)
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        return _matrix(MX_DOUBLE, (1, 1), name, _element(MI_DOUBLE, struct.pack(
            f"{E}d", float(value))))
    if isinstance(value, (Sequence, np.ndarray)) and all(isinstance(v, str) for v in value):
        items = list(value)
        return _matrix(MX_CELL, (len(items), 1), name,
                       b"".join(encode_variable("", v) for v in items))
    raise TypeError(f"{name}: cannot write a {type(value).__name__} to a .mat file")


def file_header(text: str = "MATLAB 5.0 MAT-file, written by BPMS Suite") -> bytes:
    """The 128-byte v5 header: descriptive text, no subsystem data, version 0x0100, 'IM'.
    No date in the text: the same recording gives the same bytes (the file holds its UTC
    start)."""
    return (text.encode("ascii", "replace")[:116].ljust(116, b" ") + b"\0" * 8
            + struct.pack(f"{E}H", 0x0100) + b"IM")


#: A v5 element states its byte count in 32 bits: one variable holds less than 4 GiB.
MAX_ELEMENT_BYTES = 2**32 - 1


class ExportLimitError(ValueError):
    """The output would pass its format's limit (one line: what, and what to use instead)."""


class _Var:
    def __init__(self, name: str, shape: tuple[int, ...], dtype: np.dtype, offset: int) -> None:
        self.name, self.shape, self.dtype = name, shape, np.dtype(dtype)
        mi_type, mx_class = _TYPES[self.dtype]
        self.nbytes = math.prod(shape) * self.dtype.itemsize
        if self.nbytes + 256 > MAX_ELEMENT_BYTES:
            per_row = self.nbytes // max(shape[0], 1)
            raise ExportLimitError(
                f"a MATLAB v5 .mat variable holds less than 4 GiB: {name} of {shape[0]} frames "
                f"needs {self.nbytes / 2**30:.1f} GiB (at most "
                f"{(MAX_ELEMENT_BYTES - 256) // max(per_row, 1):,} frames); export Parquet, "
                "or cut the recording")
        body = (_element(MI_UINT32, struct.pack(f"{E}II", mx_class, 0))
                + _element(MI_INT32, struct.pack(f"{E}{len(shape)}i", *shape))
                + _element(MI_INT8, name.encode("ascii"))
                + struct.pack(f"{E}II", mi_type, self.nbytes))
        self.header = struct.pack(f"{E}II", MI_MATRIX, len(body) + _pad8(self.nbytes)) + body
        self.offset = offset
        self.data_offset = offset + len(self.header)
        self.end = self.data_offset + _pad8(self.nbytes)


class Mat5Stream:
    """Write the ``small`` variables (name → value for :func:`encode_variable`), reserve
    ``arrays`` (name → (shape with N first, float32/float64)), then :meth:`write_rows` chunks
    of rows and :meth:`close`."""

    def __init__(self, path: str | Path, small: Mapping[str, object],
                 arrays: Mapping[str, tuple]) -> None:
        self.path = Path(path)
        head = file_header() + b"".join(encode_variable(n, v) for n, v in small.items())
        pos = len(head)
        self.vars: dict[str, _Var] = {}
        for name, (shape, dtype) in arrays.items():  # past a limit: refused before writing
            var = _Var(name, tuple(int(s) for s in shape), dtype, pos)
            self.vars[name] = var
            pos = var.end
        self._f: BinaryIO = open(self.path, "wb")  # noqa: SIM115 (closed in close())
        self._f.write(head)
        for var in self.vars.values():
            self._f.seek(var.offset)
            self._f.write(var.header)
        self._f.truncate(pos)  # reserved (zero) space for every array

    def write_rows(self, name: str, lo: int, rows: np.ndarray) -> None:
        """Rows ``lo : lo + len(rows)`` of array ``name`` (``rows[m, ...]``)."""
        var = self.vars[name]
        n = var.shape[0]
        m = len(rows)
        if m == 0:
            return
        if lo + m > n:
            raise ValueError(f"{name}: rows {lo}..{lo + m} beyond the reserved {n}")
        cols = np.asarray(rows, dtype=var.dtype.newbyteorder(E)).reshape(m, -1, order="F")
        size = var.dtype.itemsize
        for c in range(cols.shape[1]):
            self._f.seek(var.data_offset + (c * n + lo) * size)
            self._f.write(np.ascontiguousarray(cols[:, c]).tobytes())

    def close(self) -> None:
        self._f.close()
