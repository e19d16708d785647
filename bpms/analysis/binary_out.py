"""Binary exports: a MATLAB ``.mat`` file (v5, written here) and a Parquet table (pyarrow).

Both are chunk-wise writers with one interface: ``open_writer(kind, path, meta)``, then
``write(result)`` for each chunk's :class:`bpms.filter.processor.Result`, then ``close()``.
Both hold, per frame: time (s since the first frame), segment orientations after Reset Zero
(quaternions w, x, y, z; segment axes → world NED), the 28 joint angles (degrees, in the
convention named in the file), the 21 joint positions (m, NED, lowest foot on the ground) and
the whole body's centre of mass (m, the same frame; :mod:`bpms.filter.centre_of_mass`).
Both state the recording's UTC start time (the receive time of its first frame) and the units.

- ``.mat``: written chunk by chunk when the frame count is known in advance (it is for a
  recording; :mod:`bpms.analysis.mat5_stream`), else assembled at ``close``; no third-party
  package: ``t`` [N×1] s,
  ``quaternions`` [N×18×4], ``joint_angles`` [N×28] deg,
  ``joint_positions`` [N×21×3] m, ``centre_of_mass`` [N×3] m, ``segment_names``,
  ``joint_names``, ``point_names`` (cell arrays), ``units`` (struct), ``utc_start`` (ISO
  8601 text), ``utc_start_posix`` (s since 1970), ``joint_angle_convention``,
  ``rate_hz``, ``source``, and where the file came from
  (:func:`bpms.analysis.stamp.provenance`): ``heading``, ``bpms_version``, ``filter``,
  ``reset_zero``, ``recording``.
- Parquet: one row per frame, written one row group per chunk (constant memory): column
  ``time_s``, ``utc`` (timestamp, µs, UTC), ``imuN_SEGMENT_qw`` …, ``joint_JOINT_deg`` …,
  ``point_POINT_x_m`` …, ``point_centre_of_mass_x_m`` … (the names of docs/analysis.md,
  "Column names");
  the file's key-value metadata holds ``bpms`` (JSON: utc_start, units, convention, and the
  provenance: bpms_version, filter, reset_zero, recording).
  docs/analysis.md says why Parquet.
"""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from bpms.filter.body_model import POINT_NAMES
from bpms.filter.joints import CONVENTION_TEXT, JOINT_ANGLE_NAMES
from bpms.io.frames import IMU_NAMES
from bpms.io.names import imu_column, joint_column, point_column, slug

KINDS = ("mat", "parquet")
SUFFIX = {"mat": ".mat", "parquet": ".parquet"}
UNITS = {"t": "s", "quaternions": "1 (unit quaternion w, x, y, z; segment -> world NED)",
         "joint_angles": "deg", "joint_positions": "m (NED, lowest foot at z = 0)",
         "centre_of_mass": "m (NED, as joint_positions; Dempster via Winter 2009 Table 4.1)"}
COM_POINT = "centre_of_mass"


SEGMENT_SLUGS = tuple(slug(n) for n in IMU_NAMES)
#: :func:`bpms.analysis.stamp.provenance`'s keys: .mat variables of their own (text).
PROVENANCE_KEYS = ("heading", "bpms_version", "filter", "reset_zero", "recording")


@dataclass
class ExportMeta:
    """What every export states. utc_start: s since 1970 (UTC) of frame 0; convention: the
    joint-angle convention of the angles written; source: the recording's path."""

    utc_start: float
    convention: str = "isb"
    rate_hz: float = 50.0
    source: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    n_frames: int | None = None  # known in advance: the .mat file is written chunk by chunk
    #: study columns (a batch's study sheet: trial, condition, ...): the same text on every
    #: Parquet row (string columns after the data), the .mat file's ``study`` struct
    columns: dict[str, str] = field(default_factory=dict)

    @property
    def utc_iso(self) -> str:
        return utc_iso(self.utc_start)

    def as_dict(self) -> dict[str, Any]:
        return {"utc_start": self.utc_iso, "utc_start_posix": self.utc_start,
                "joint_angle_convention": CONVENTION_TEXT.get(self.convention, self.convention),
                "rate_hz": self.rate_hz, "source": self.source, "units": UNITS, **self.extra}


def utc_iso(posix: float) -> str:
    """``2026-11-30T08:12:41.250Z`` (milliseconds, UTC); ``unknown`` for a time no clock
    gives (a damaged record's time, NaN)."""
    try:
        t = dt.datetime.fromtimestamp(posix, tz=dt.UTC)
    except (OverflowError, OSError, ValueError):
        return "unknown"
    return t.strftime("%Y-%m-%dT%H:%M:%S.") + f"{t.microsecond // 1000:03d}Z"


class ChunkWriter(Protocol):
    path: Path
    rows: int

    def write(self, result) -> None: ...

    def close(self) -> None: ...


def _arrays(result) -> tuple[np.ndarray, ...]:
    """(t [N], quaternions [N, 18, 4], joint angles deg [N, 28], positions [N, 21, 3],
    centre of mass [N, 3])."""
    return (np.asarray(result.t, dtype=np.float64),
            np.asarray(result.segment_quaternions, dtype=np.float32),
            np.degrees(result.joint_angles).astype(np.float32),
            np.asarray(result.joint_positions, dtype=np.float32),
            np.asarray(result.centre_of_mass, dtype=np.float32))


class MatWriter:
    """MATLAB v5 ``.mat`` (:mod:`bpms.analysis.mat5_stream`, no third-party package). With
    ``meta.n_frames`` the arrays are written chunk by chunk into space reserved for them
    (constant memory); without it the chunks are kept until :meth:`close`."""

    _ARRAYS = ("t", "quaternions", "joint_angles", "joint_positions", "centre_of_mass")

    def __init__(self, path: str | Path, meta: ExportMeta) -> None:
        self.path = Path(path)
        self.meta = meta
        self.rows = 0
        self._parts: list[tuple[np.ndarray, ...]] = []
        self._stream = None
        if meta.n_frames is not None:
            self._stream = self._open(int(meta.n_frames))
        else:
            self.path.write_bytes(b"")  # fail early (folder missing, no permission)

    def _open(self, n: int):
        from bpms.analysis.mat5_stream import Mat5Stream

        return Mat5Stream(self.path, self._small(), {
            "t": ((n, 1), np.float64), "quaternions": ((n, 18, 4), np.float32),
            "joint_angles": ((n, 28), np.float32),
            "joint_positions": ((n, 21, 3), np.float32),
            "centre_of_mass": ((n, 3), np.float32)})

    def _small(self) -> dict:
        meta = self.meta.as_dict()
        study = ({"study": {_field(k): str(v) for k, v in self.meta.columns.items()}}
                 if self.meta.columns else {})
        return {**study, "segment_names": SEGMENT_SLUGS,
                "joint_names": [joint_column(j) for j in JOINT_ANGLE_NAMES],
                "point_names": POINT_NAMES,
                **{key: meta[key] for key in ("units", "utc_start", "utc_start_posix",
                                              "joint_angle_convention", "rate_hz", "source")},
                **{key: str(meta[key]) for key in PROVENANCE_KEYS if key in meta}}

    def _write(self, lo: int, arrays: tuple[np.ndarray, ...]) -> None:
        t, *rest = arrays
        for name, rows in zip(self._ARRAYS, (t[:, None], *rest), strict=True):
            self._stream.write_rows(name, lo, rows)

    def write(self, result) -> None:
        arrays = _arrays(result)
        if self._stream is not None:
            self._write(self.rows, arrays)
        else:
            self._parts.append(arrays)
        self.rows += len(result.t)

    def close(self) -> None:
        if self._stream is None:  # the frame count is known now
            self._stream = self._open(self.rows)
            lo = 0
            for part in self._parts:
                self._write(lo, part)
                lo += len(part[0])
            self._parts.clear()
        self._stream.close()


def _field(name: str) -> str:
    """A MATLAB struct field name for a study column: ``"Suit pressure"`` →
    ``suit_pressure``; a leading digit gets ``c_``."""
    text = slug(name)
    return (text if text[:1].isalpha() else f"c_{text}")[:60]


def parquet_columns() -> list[str]:
    """Column names of the Parquet table, in order."""
    return ["time_s", "utc",
            *(imu_column(i, f"q{c}") for i in range(len(IMU_NAMES)) for c in "wxyz"),
            *(joint_column(j, "deg") for j in JOINT_ANGLE_NAMES),
            *(point_column(p, a, "m") for p in POINT_NAMES for a in "xyz"),
            *(point_column(COM_POINT, a, "m") for a in "xyz")]


class ParquetWriter:
    """One Parquet row group per chunk (pyarrow), float32 data, the metadata in the footer."""

    def __init__(self, path: str | Path, meta: ExportMeta, compression: str = "snappy") -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        self._pa = pa
        self.path = Path(path)
        self.meta = meta
        self.rows = 0
        names = parquet_columns()
        fields = [pa.field("time_s", pa.float64()),
                  pa.field("utc", pa.timestamp("us", tz="UTC"))]
        fields += [pa.field(n, pa.float32()) for n in names[2:]]
        fields += [pa.field(k, pa.string()) for k in meta.columns]
        self._schema = pa.schema(fields, metadata={"bpms": json.dumps(meta.as_dict())})
        # Dictionary encoding of float columns costs 5× the write time and gains nothing on
        # continuous signals (the study's text columns: one value, dictionary-encoded);
        # statistics only where queries filter (time).
        self._writer = pq.ParquetWriter(self.path, self._schema, compression=compression,
                                        use_dictionary=list(meta.columns) or False,
                                        write_statistics=["time_s", "utc"])

    def write(self, result) -> None:
        pa = self._pa
        t, q, a, p, com = _arrays(result)
        n = len(t)
        if n == 0:
            return
        us = np.round((self.meta.utc_start + t) * 1e6)
        # a damaged receive time (NaN, 1e300 s) has no timestamp: null, not a wrapped integer
        known = np.isfinite(us) & (np.abs(us) < 2.0 ** 63)
        utc = pa.array(np.where(known, us, 0.0).astype("int64"), mask=~known,
                       type=pa.timestamp("us", tz="UTC"))
        block = np.concatenate([q.reshape(n, -1), a, p.reshape(n, -1), com], axis=1)
        block = np.asfortranarray(block)  # contiguous columns: no copy per column
        cols = [pa.array(t), utc]
        cols += [pa.array(block[:, k]) for k in range(block.shape[1])]
        cols += [pa.array([v] * n, type=pa.string()) for v in self.meta.columns.values()]
        self._writer.write_table(pa.Table.from_arrays(cols, schema=self._schema))
        self.rows += n

    def close(self) -> None:
        self._writer.close()


class MissingPackageError(RuntimeError):
    """The package a format needs is not installed (one-line message)."""


#: kind → (package, the pip extra that installs it); kinds not listed need nothing more.
_PACKAGES = {"parquet": ("pyarrow", "parquet")}


def check_available(kind: str) -> None:
    """Raise :class:`MissingPackageError` when ``kind``'s package is not installed."""
    import importlib.util

    if kind not in _PACKAGES:
        return
    package, extra = _PACKAGES[kind]
    if importlib.util.find_spec(package) is None:
        raise MissingPackageError(f"{kind} export needs the {package} package "
                                  f'(pip install "bpms[{extra}]")')


def open_writer(kind: str, path: str | Path, meta: ExportMeta) -> ChunkWriter:
    """A chunk-wise writer of ``kind`` (:data:`KINDS`)."""
    if kind not in KINDS:
        raise ValueError(f"unknown export kind {kind!r} (one of {', '.join(KINDS)})")
    check_available(kind)
    return MatWriter(path, meta) if kind == "mat" else ParquetWriter(path, meta)
