"""C3D files written here, frame by frame, in constant memory (no third-party package).

A C3D file (C3D.org, "The C3D File Format User Guide") is a sequence of 512-byte blocks:

- block 1, the header: 16-bit words (word 1: the first parameter block and the key 0x50;
  word 2: points per frame; word 3: analog values per frame; words 4-5: first and last frame;
  words 7-8: the scale factor, negative for floating-point data; word 9: the first data block;
  word 10: analog samples per frame; words 11-12: the frame rate);
- the parameter section: a 4-byte preamble (key 0x50, the number of parameter blocks,
  processor type 84 = Intel, little-endian), then groups and parameters, each a record with
  its name, its group's id, the byte offset to the next record (0 for the last), and for a
  parameter its type (-1 char, 1 byte, 2 int16, 4 float), dimensions (each ≤ 255, the first
  varying fastest) and values;
- the data: per frame, every point's x, y, z and residual word (-1: invalid), then every
  analog channel's values, here all float32.

The header's last frame is a 16-bit word, so a trial of more than 65,535 frames states its
length in parameters: ``TRIAL:ACTUAL_END_FIELD`` (two 16-bit words, low then high: the
Vicon convention, read by ezc3d and the ``c3d`` package) and ``POINT:FRAMES`` as a float
(the header's word holds 65,535). The parameter section is reserved when the file is opened
and written at :meth:`C3dStream.finish`, when the frame count and the events are known: the
frames stream straight to disk.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bpms.io.closing import Closing

BLOCK = 512
INTEL = 84
KEY = 0x50
UINT16_MAX = 65535
MAX_DIM = 255  # one dimension of a parameter is one byte

#: (name, value, description); value: str, list of str, int, float, or a numpy array
#: (int16 or float32; shape reversed into C3D's dimensions).
Param = tuple[str, object, str]
#: (name, description, parameters)
Group = tuple[str, str, Sequence[Param]]


def _value(name: str, value: object) -> tuple[int, list[int], bytes]:
    """(type, dimensions, bytes) of one parameter value."""
    if isinstance(value, str):
        data = value.encode("latin-1", "replace") or b" "
        return -1, [len(data)], data
    if isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value):
        items = [v.encode("latin-1", "replace") for v in value]
        width = max([1, *(len(v) for v in items)])
        return -1, [width, len(items)], b"".join(v.ljust(width) for v in items)
    if isinstance(value, bool):
        raise TypeError(f"{name}: a bool is not a C3D value")
    if isinstance(value, int):
        return 2, [], struct.pack("<h", value)
    if isinstance(value, float):
        return 4, [], struct.pack("<f", value)
    arr = np.asarray(value)
    if arr.dtype == np.int16:
        return 2, list(reversed(arr.shape)), arr.astype("<i2").tobytes()
    if arr.dtype == np.float32:
        return 4, list(reversed(arr.shape)), arr.astype("<f4").tobytes()
    raise TypeError(f"{name}: cannot write a {arr.dtype} array to a C3D parameter")


def _record(name: str, gid: int, body: bytes, last: bool) -> bytes:
    raw = name.upper().encode("ascii")
    if not 0 < len(raw) < 128:
        raise ValueError(f"C3D name {name!r}: 1 to 127 characters")
    offset = 0 if last else 2 + len(body)
    return struct.pack("<bb", len(raw), gid) + raw + struct.pack("<h", offset) + body


def _desc(text: str) -> bytes:
    raw = text.encode("latin-1", "replace")[:255]
    return struct.pack("<B", len(raw)) + raw


def encode_parameters(groups: Sequence[Group]) -> bytes:
    """The parameter records of ``groups`` (without the 4-byte preamble)."""
    records: list[tuple[str, int, bytes]] = []
    for gid, (gname, gdesc, params) in enumerate(groups, start=1):
        records.append((gname, -gid, _desc(gdesc)))
        for pname, value, pdesc in params:
            kind, dims, data = _value(f"{gname}:{pname}", value)
            if any(d > MAX_DIM for d in dims):
                raise ValueError(f"{gname}:{pname}: a dimension above {MAX_DIM} ({dims})")
            body = struct.pack("<bB", kind, len(dims)) + bytes(dims) + data + _desc(pdesc)
            records.append((pname, gid, body))
    return b"".join(_record(n, g, b, k == len(records) - 1)
                    for k, (n, g, b) in enumerate(records))


class C3dStream(Closing):
    """A C3D file written frame chunk by frame chunk.

    ``n_points`` points and ``n_analog`` analog channels (one sample per frame) per frame,
    ``param_blocks`` 512-byte blocks reserved for the parameters (at most 255). Write frames
    with :meth:`write`, then :meth:`finish` with the parameter groups (the ``POINT``,
    ``ANALOG`` and ``TRIAL`` entries the layout needs are added here)."""

    def __init__(self, path: str | Path, rate_hz: float, n_points: int, n_analog: int,
                 param_blocks: int) -> None:
        if not 0 < param_blocks <= 255:
            raise ValueError("param_blocks: 1 to 255")
        self.path = Path(path)
        self.rate_hz = float(rate_hz)
        self.n_points = int(n_points)
        self.n_analog = int(n_analog)
        self.param_blocks = int(param_blocks)
        self.data_block = 2 + self.param_blocks  # 1-based block number
        self.frames = 0
        self._file = open(self.path, "wb")  # noqa: SIM115 (closed by finish/close)
        self._file.write(b"\0" * (BLOCK * (self.data_block - 1)))

    def write(self, points: np.ndarray, analog: np.ndarray | None = None) -> None:
        """``points[N, n_points, 3]`` (NaN: invalid, written as residual -1) and
        ``analog[N, n_analog]`` (any float; NaN stays NaN)."""
        xyz = np.asarray(points, dtype=np.float32)
        n = len(xyz)
        block = np.zeros((n, self.n_points * 4 + self.n_analog), dtype="<f4")
        valid = np.isfinite(xyz).all(axis=-1)
        p = block[:, : self.n_points * 4].reshape(n, self.n_points, 4)
        p[..., :3] = np.where(valid[..., None], xyz, 0.0)
        p[..., 3] = np.where(valid, 0.0, -1.0)
        if self.n_analog:
            block[:, self.n_points * 4:] = np.asarray(analog, dtype=np.float32)
        self._file.write(block.tobytes())
        self.frames += n

    def _header(self) -> bytes:
        words = np.zeros(256, dtype="<u2")
        words[0] = 2 | (KEY << 8)
        words[1] = self.n_points
        words[2] = self.n_analog
        words[3] = 1
        words[4] = min(max(self.frames, 1), UINT16_MAX)
        words[5] = 10
        words[8] = self.data_block
        words[9] = 1
        head = bytearray(words.tobytes())
        head[12:16] = struct.pack("<f", -1.0)
        head[20:24] = struct.pack("<f", self.rate_hz)
        head[298:300] = struct.pack("<H", 12345)  # 4-character event labels (none here)
        return bytes(head)

    def layout_groups(self) -> list[Group]:
        """The entries the data layout needs: frame count, rate, data start, scale."""
        n = self.frames
        frames = int(np.array(min(n, UINT16_MAX), np.uint16).astype(np.int16))
        trial = ("TRIAL", "trial", [
            ("ACTUAL_START_FIELD", np.array([1, 0], np.int16), "first frame (low, high word)"),
            ("ACTUAL_END_FIELD", np.array([n & 0xFFFF, n >> 16], np.uint16).astype(np.int16),
             "last frame (low, high word)"),
            ("CAMERA_RATE", float(self.rate_hz), "frames per second")])
        point = [("USED", self.n_points, "points per frame"),
                 ("SCALE", -1.0, "negative: floating-point data"),
                 ("RATE", float(self.rate_hz), "frames per second"),
                 ("DATA_START", self.data_block, "first data block"),
                 ("FRAMES", frames, "frames (at most 65535: TRIAL:ACTUAL_END_FIELD holds more)")]
        return [("POINT", "3-D point parameters", point), trial]

    def finish(self, groups: Sequence[Group]) -> None:
        """Write the header and the parameters (the ``POINT`` group of ``groups`` is merged
        with the layout's entries) and close. Raises ValueError when the parameters do not
        fit the reserved blocks."""
        layout = self.layout_groups()
        merged: list[Group] = []
        names = {g[0] for g in groups}
        for name, desc, params in groups:
            extra = [p for g in layout if g[0] == name for p in g[2]]
            merged.append((name, desc, [*extra, *params]))
        merged += [g for g in layout if g[0] not in names]
        body = struct.pack("<BBBB", 1, KEY, self.param_blocks, INTEL) + encode_parameters(
            merged)
        room = self.param_blocks * BLOCK
        if len(body) > room:
            self._file.close()
            raise ValueError(f"C3D parameters need {len(body)} bytes; {room} reserved")
        self._file.seek(0)
        self._file.write(self._header() + body + b"\0" * (room - len(body)))
        self._file.close()

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()
