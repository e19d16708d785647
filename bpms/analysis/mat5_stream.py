"""Numeric MATLAB v5 variables written chunk by chunk (constant memory).

A v5 ``.mat`` file is a 128-byte header followed by data elements; a numeric matrix element
holds its class, dimensions, name and then its values in column-major order. For an
``[N, ...]`` array whose N is known in advance, each column (all N values of one channel) is a
contiguous run in the file, so a chunk of rows ``lo:hi`` is one ``seek`` + ``write`` per column.
The small variables (text, names, units) are written first by ``scipy.io.savemat``; the big
arrays follow with their space reserved up front. ``scipy.io.loadmat`` and MATLAB's ``load``
read the result like any other v5 file.
"""

from __future__ import annotations

import math
import struct
from pathlib import Path
from typing import BinaryIO

import numpy as np

MI_INT8, MI_INT32, MI_UINT32, MI_SINGLE, MI_DOUBLE, MI_MATRIX = 1, 5, 6, 7, 9, 14
MX_DOUBLE, MX_SINGLE = 6, 7
_TYPES = {np.dtype(np.float32): (MI_SINGLE, MX_SINGLE), np.dtype(np.float64): (MI_DOUBLE,
                                                                                MX_DOUBLE)}


def _pad8(n: int) -> int:
    return (n + 7) // 8 * 8


def _element(mi_type: int, payload: bytes, e: str) -> bytes:
    return struct.pack(f"{e}II", mi_type, len(payload)) + payload + b"\0" * (
        _pad8(len(payload)) - len(payload))


class _Var:
    def __init__(self, name: str, shape: tuple[int, ...], dtype: np.dtype, offset: int,
                 e: str) -> None:
        self.name, self.shape, self.dtype, self.e = name, shape, np.dtype(dtype), e
        mi_type, mx_class = _TYPES[self.dtype]
        self.nbytes = math.prod(shape) * self.dtype.itemsize
        body = (_element(MI_UINT32, struct.pack(f"{e}II", mx_class, 0), e)
                + _element(MI_INT32, struct.pack(f"{e}{len(shape)}i", *shape), e)
                + _element(MI_INT8, name.encode("ascii"), e)
                + struct.pack(f"{e}II", mi_type, self.nbytes))
        self.header = struct.pack(f"{e}II", MI_MATRIX, len(body) + _pad8(self.nbytes)) + body
        self.offset = offset
        self.data_offset = offset + len(self.header)
        self.end = self.data_offset + _pad8(self.nbytes)


class Mat5Stream:
    """Reserve ``arrays`` (name → (shape with N first, dtype)) after the ``small`` variables
    (a dict for ``scipy.io.savemat``), then :meth:`write_rows` chunks of rows."""

    def __init__(self, path: str | Path, small: dict, arrays: dict[str, tuple]) -> None:
        from scipy.io import savemat

        self.path = Path(path)
        savemat(self.path, small, format="5", do_compression=False, oned_as="column")
        self._f: BinaryIO = open(self.path, "r+b")  # noqa: SIM115 (closed in close())
        self._f.seek(126)
        e = "<" if self._f.read(2) == b"IM" else ">"
        self._f.seek(0, 2)
        pos = self._f.tell()
        self.vars: dict[str, _Var] = {}
        for name, (shape, dtype) in arrays.items():
            var = _Var(name, tuple(int(s) for s in shape), dtype, pos, e)
            self._f.seek(var.offset)
            self._f.write(var.header)
            self.vars[name] = var
            pos = var.end
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
        cols = np.asarray(rows, dtype=var.dtype.newbyteorder(var.e)).reshape(m, -1, order="F")
        size = var.dtype.itemsize
        for c in range(cols.shape[1]):
            self._f.seek(var.data_offset + (c * n + lo) * size)
            self._f.write(np.ascontiguousarray(cols[:, c]).tobytes())

    def close(self) -> None:
        self._f.close()
