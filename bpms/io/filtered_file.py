"""The filtered file: CSV text, one row per frame (docs/filtered-file.md).

Version 2 (written now)::

    # bpms-filtered-file 2
    # euler: sensor
    # convention: ...
    # groups: euler,joints
    time_s,host_time_s,hole,imu0_right_leg_roll_rad,...,joint_elbow_r_flexion_rad,...

- ``#`` lines: the header, ``key: value``. ``euler`` says which Euler angles the ``euler``
  group holds: ``sensor`` (each IMU's filter orientation, filter frame → NED) or ``segment``
  (segment orientations corrected by Reset Zero); ``groups`` lists the column groups in order.
- Fixed columns: ``time_s`` (s since the stream started, fixed filter clock,
  :mod:`bpms.io.timebase`), ``host_time_s`` (s since the epoch, UTC, when the host received the
  frame; ``nan`` when unknown) and ``hole`` (1 for a frame that was received but not filtered:
  its values are ``nan``; 0 otherwise).
- Then the column groups (:func:`register_column_group`), each a fixed set of named columns;
  angular groups are radians (``_rad``) or degrees (``_deg``) for the whole file.

One reader, :func:`iter_filtered` (streaming, block by block) / :func:`read_filtered` (whole
file), reads every version:

- version 2 (above), with column groups it does not know kept by name in ``extra``;
- version 1, this project's earlier layout: one header row ``time_s,imu0_..._roll_rad,...``
  (+ joint columns), no host time, no holes;
- version 0, the original suite's file: no header, one line per frame, ``time.time()`` epoch
  seconds then roll, pitch, yaw (rad) of IMU 0..17, each value followed by a comma (a trailing
  comma ends the line). Its absolute time becomes ``host_time`` (float64, to the millisecond
  and better) and ``time_s`` counts from its first row.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np

from bpms.io.bounded import MAX_HEADER_BYTES
from bpms.io.frames import IMU_NAMES, N_IMUS
from bpms.io.names import JOINT_ANGLE_NAMES, slug

FORMAT_NAME = "bpms-filtered-file"
FORMAT_VERSION = 2
EULER_NAMES = ("roll", "pitch", "yaw")
FIXED_COLUMNS = ("time_s", "host_time_s", "hole")
N_LEGACY_COLUMNS = 1 + 3 * N_IMUS
#: The first column of a version-0 file is absolute epoch time when above this (s; 1973).
EPOCH_THRESHOLD_S = 1e8
BLOCK_ROWS = 10_000
_FMT = "%.10g"
_HOST_FMT = "%.6f"
_DEGREES = np.degrees(1.0)
#: Written when the writer is given no convention (callers give the joint-angle convention in
#: force: :func:`bpms.filter.door.filtered_convention`).
_DEFAULT_CONVENTION = ("Euler roll, pitch, yaw (R = Rz Ry Rx), frame -> NED; joint angles: "
                       "docs/joint-angles.md")


class FilteredFileError(Exception):
    """A file that cannot be read as a filtered file (message says why)."""


# -- column groups ------------------------------------------------------------------------
@dataclass(frozen=True)
class ColumnGroup:
    """A named set of columns of the filtered file.

    name: the group's name (the ``groups`` header line, keyword of :meth:`FilteredWriter.
    write_block`); names: ``names(unit)`` → the column names, where ``unit`` is the file's
    angle unit ``"rad"``/``"deg"``; shape: the per-frame array shape the writer takes and the
    reader returns (its product = the number of columns); angular: values are angles in rad,
    written in the file's unit; fmt: ``printf`` format of a value; description: one line for
    docs.
    """

    name: str
    names: Callable[[str], list[str]]
    shape: tuple[int, ...]
    angular: bool = False
    fmt: str = _FMT
    description: str = ""

    @property
    def width(self) -> int:
        return int(np.prod(self.shape))


_GROUPS: dict[str, ColumnGroup] = {}


def register_column_group(group: ColumnGroup) -> ColumnGroup:
    """Add a column group (one call, at import of the module that owns the data). Registering
    the same name again with the same columns is allowed (module re-import). Raises ValueError
    for a name or a column name already used by another group."""
    old = _GROUPS.get(group.name)
    if old is not None and old.names("rad") != group.names("rad"):
        raise ValueError(f"column group {group.name!r} is already registered")
    if len(group.names("rad")) != group.width:
        raise ValueError(f"column group {group.name!r}: {len(group.names('rad'))} names for "
                         f"shape {group.shape}")
    taken = {c for g in _GROUPS.values() if g.name != group.name for u in ("rad", "deg")
             for c in g.names(u)} | set(FIXED_COLUMNS)
    clash = [c for u in ("rad", "deg") for c in group.names(u) if c in taken]
    if clash:
        raise ValueError(f"column group {group.name!r}: column {clash[0]!r} already exists")
    _GROUPS[group.name] = group
    return group


def column_groups() -> dict[str, ColumnGroup]:
    """The registered column groups by name (registration order)."""
    return dict(_GROUPS)


def _imu_euler_names(infix: str) -> Callable[[str], list[str]]:
    def names(unit: str) -> list[str]:
        return [f"imu{i}_{slug(n)}_{infix}{e}_{unit}" for i, n in enumerate(IMU_NAMES)
                for e in EULER_NAMES]
    return names


register_column_group(ColumnGroup(
    "euler", _imu_euler_names(""), (N_IMUS, 3), angular=True,
    description="roll, pitch, yaw of IMU 0..17 (which ones: the 'euler' header line)"))
register_column_group(ColumnGroup(
    "euler_sensor", _imu_euler_names("sensor_"), (N_IMUS, 3), angular=True,
    description="each IMU's uncorrected filter roll, pitch, yaw, when 'euler' holds the "
                "Reset-Zero-corrected segment angles"))
register_column_group(ColumnGroup(
    "corrected", lambda unit: ["corrected"], (1,), fmt="%.0f",
    description="1 where the 'euler' columns hold Reset-Zero-corrected segment angles, 0 "
                "where they still hold the sensor angles (before the first Reset Zero, or "
                "with the correction switched off)"))
register_column_group(ColumnGroup(
    "joints", lambda unit: [f"joint_{slug(j)}_{unit}" for j in JOINT_ANGLE_NAMES],
    (len(JOINT_ANGLE_NAMES),), angular=True, description="the 28 joint angles"))


def _imu_names(suffixes: Sequence[str]) -> Callable[[str], list[str]]:
    def names(unit: str) -> list[str]:
        return [f"imu{i}_{slug(n)}_{x}" for i, n in enumerate(IMU_NAMES) for x in suffixes]
    return names


# Flags are written 1/0 (``nan`` in a hole row); the reader returns them as floats 1.0/0.0/NaN.
_FLAG_FMT = "%.0f"
register_column_group(ColumnGroup(
    "reinitialised", _imu_names(["reinit"]), (N_IMUS,), fmt=_FLAG_FMT,
    description="1 where the state guard re-initialised IMU i's filter at that frame"))
register_column_group(ColumnGroup(
    "mag_disturbed", _imu_names(["mag_disturbed"]), (N_IMUS,), fmt=_FLAG_FMT,
    description="1 where IMU i's magnetometer is disturbed (field norm or dip off)"))
register_column_group(ColumnGroup(
    "acc_disturbed", _imu_names(["acc_disturbed"]), (N_IMUS,), fmt=_FLAG_FMT,
    description="1 where IMU i's acceleration has been far from gravity for long"))
register_column_group(ColumnGroup(
    "gyro_bias", _imu_names([f"gyro_bias_{a}_rad_s" for a in "xyz"]), (N_IMUS, 3),
    description="gyro-bias estimate of IMU i, rad/s, sensor (filter-frame) axes x, y, z"))
register_column_group(ColumnGroup(
    "body_acc", _imu_names([f"body_acc_{a}_m_s2" for a in "ned"]), (N_IMUS, 3),
    description="body-acceleration estimate of IMU i, m/s², NED axes (observer/adaptive "
                "filters; nan for the others)"))


def filtered_columns(degrees: bool = False, joints: bool = False,
                     groups: Sequence[str] | None = None) -> list[str]:
    """Column names of a version-2 filtered file: the fixed columns, then the groups
    (default ``euler``, plus ``joints`` with ``joints``)."""
    unit = "deg" if degrees else "rad"
    cols = list(FIXED_COLUMNS)
    for g in _group_list(groups, joints):
        cols += _GROUPS[g].names(unit)
    return cols


def _group_list(groups: Sequence[str] | None, joints: bool) -> list[str]:
    if groups is None:
        groups = ["euler", *(["joints"] if joints else [])]
    unknown = [g for g in groups if g not in _GROUPS]
    if unknown:
        raise ValueError(f"unknown column group {unknown[0]!r} (known: {', '.join(_GROUPS)})")
    return list(dict.fromkeys(groups))


# -- writing ------------------------------------------------------------------------------
class FilteredWriter:
    """Writes a version-2 filtered file block by block (live logging or whole files).

    degrees: angles written in degrees (given in radians); joints: add the ``joints`` group;
    groups: the column groups, in order (overrides ``joints``); euler: ``"sensor"`` or
    ``"segment"``, what the ``euler`` group holds; meta: extra ``key: value`` header lines.
    """

    def __init__(self, path: str | Path | TextIO, degrees: bool = False,
                 joints: bool = False, groups: Sequence[str] | None = None,
                 euler: str = "sensor", convention: str = _DEFAULT_CONVENTION,
                 meta: Mapping[str, str] | None = None) -> None:
        if euler not in ("sensor", "segment"):
            raise ValueError(f"euler must be 'sensor' or 'segment', not {euler!r}")
        self.degrees = degrees
        self.groups = _group_list(groups, joints)
        self.joints = "joints" in self.groups
        self.columns = filtered_columns(degrees, groups=self.groups)
        self.rows = 0
        self.holes = 0
        unit = "deg" if degrees else "rad"
        fmts = [_FMT, _HOST_FMT, "%d"]
        for g in self.groups:
            fmts += [_GROUPS[g].fmt] * _GROUPS[g].width
        self._fmt = ",".join(fmts)
        # The trailing flag columns (0/1, "%.0f") are written from their bytes: formatting them
        # as floats was a sixth of a live row's cost. Rows with other values take self._fmt.
        flags = len(fmts) - next(k for k in range(len(fmts), 0, -1)
                                 if fmts[k - 1] != _FLAG_FMT)
        self._flags = flags
        self._head_fmt = ",".join(fmts[:len(fmts) - flags])
        # (group, first column, width, angular columns scaled to degrees), computed once: a
        # live file takes one row per frame and this is its per-row overhead
        self._layout: list[tuple[str, int, int, bool]] = []
        col = len(FIXED_COLUMNS)
        for g in self.groups:
            w = _GROUPS[g].width
            self._layout.append((g, col, w, degrees and _GROUPS[g].angular))
            col += w
        if isinstance(path, str | Path):
            self.path: Path | None = Path(path)
            self._file: TextIO = open(self.path, "x", encoding="utf-8", newline="\n")  # noqa: SIM115
            self._owns = True
        else:
            self.path, self._file, self._owns = None, path, False
        header = {"euler": euler, "convention": convention, "angles": unit,
                  "groups": ",".join(self.groups), **(meta or {})}
        lines = [f"# {FORMAT_NAME} {FORMAT_VERSION}"]
        lines += [f"# {k}: {str(v).replace(chr(10), ' ')}" for k, v in header.items()]
        self._file.write("\n".join(lines) + "\n" + ",".join(self.columns) + "\n")

    def write_block(self, t: np.ndarray, euler: np.ndarray | None = None,
                    joint_angles: np.ndarray | None = None, *,
                    host_time: np.ndarray | None = None, hole: np.ndarray | None = None,
                    **groups: np.ndarray) -> None:
        """N rows: ``t[N]`` s since the start, ``euler[N, 18, 3]`` rad, ``joint_angles[N, 28]``
        rad (the ``joints`` group), ``host_time[N]`` s since the epoch (NaN unknown),
        ``hole[N]`` bool, other groups by name (``[N, *shape]``). A group of the file that is
        not given is written as NaN."""
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        n = len(t)
        if euler is not None:
            groups["euler"] = euler
        if joint_angles is not None:
            groups["joints"] = joint_angles
        elif self.joints and "joints" not in groups and euler is not None:
            raise ValueError("this file has joint-angle columns: give joint_angles")
        block = np.empty((n, len(self.columns)))
        block[:, 0] = t
        block[:, 1] = (np.nan if host_time is None
                       else np.asarray(host_time, dtype=np.float64).reshape(-1))
        holes = 0
        if hole is None:
            block[:, 2] = 0
        else:
            hole = np.asarray(hole, dtype=bool).reshape(-1)
            block[:, 2] = hole
            holes = int(np.count_nonzero(hole))
        for g, col, w, to_degrees in self._layout:
            values = groups.get(g)
            if values is None:
                block[:, col:col + w] = np.nan
                continue
            block[:, col:col + w] = np.reshape(values, (n, w))
            if to_degrees:
                block[:, col:col + w] *= _DEGREES
        if n:  # one format string per row: half the cost of numpy.savetxt for live rows
            self._file.write(self._rows_text(block))
        self.rows += n
        self.holes += holes

    def _rows_text(self, block: np.ndarray) -> str:
        """The rows of ``block`` as text, each ending in a newline."""
        fmt, flags = self._fmt, self._flags
        tail = block[:, block.shape[1] - flags:] if flags else None
        if tail is None or not ((tail == 1.0) | ((tail == 0.0) & ~np.signbit(tail))).all():
            return "\n".join([fmt % tuple(r) for r in block.tolist()]) + "\n"
        # ",0,1,..." for each row, as "%.0f" writes exact 0.0 and 1.0
        chars = np.full((len(block), 2 * flags), ord(","), dtype=np.uint8)
        chars[:, 1::2] = tail.astype(np.uint8) + ord("0")
        tails = chars.view(f"S{2 * flags}").ravel().tolist()
        head = self._head_fmt
        return "\n".join([(head % tuple(r)) + t.decode("ascii") for r, t in
                          zip(block[:, :block.shape[1] - flags].tolist(), tails,
                              strict=True)]) + "\n"

    def write(self, t: float, euler: np.ndarray, joint_angles: np.ndarray | None = None,
              host_time: float | None = None) -> None:
        """One row: ``euler[18, 3]`` rad, ``joint_angles[28]`` rad."""
        self.write_block(np.array([t]), np.asarray(euler)[None],
                         None if joint_angles is None else np.asarray(joint_angles)[None],
                         host_time=None if host_time is None else np.array([host_time]))

    def write_holes(self, t: np.ndarray, host_time: np.ndarray | None = None) -> None:
        """Rows for frames received but not filtered: ``hole`` = 1, values NaN."""
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        self.write_block(t, host_time=host_time, hole=np.ones(len(t), dtype=bool))

    def flush(self) -> None:
        self._file.flush()

    def close(self) -> None:
        if self._owns and not self._file.closed:
            self._file.close()

    def __enter__(self) -> FilteredWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# -- reading ------------------------------------------------------------------------------
@dataclass
class FilteredInfo:
    """What a filtered file's header says.

    version: 0 (original suite), 1 or 2; columns: as in the file (version 0: the standard
    names); unit "rad"/"deg"; meta: the ``key: value`` header lines (version 2); groups: the
    known column groups present, in order; extra: column names of unknown groups.
    """

    path: Path
    version: int
    columns: list[str]
    unit: str
    meta: dict[str, str] = field(default_factory=dict)
    groups: list[str] = field(default_factory=list)
    extra: list[str] = field(default_factory=list)

    @property
    def legacy(self) -> bool:
        return self.version == 0

    @property
    def euler_kind(self) -> str:
        """``"sensor"`` or ``"segment"``: what the ``euler`` group holds."""
        return self.meta.get("euler", "sensor")


@dataclass
class FilteredBlock:
    """Rows of a filtered file; angles in radians. t ``[N]`` s since the start; host_time
    ``[N]`` s since the epoch (NaN unknown); hole ``[N]`` bool; groups by name
    (``euler`` ``[N, 18, 3]``, ``joints`` ``[N, 28]`` ...); extra: unknown columns ``[N]``."""

    t: np.ndarray
    host_time: np.ndarray
    hole: np.ndarray
    groups: dict[str, np.ndarray]
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.t)


@dataclass
class FilteredData:
    """A whole filtered file read back (:func:`read_filtered`); angles in radians.

    t ``[N]`` s; euler ``[N, 18, 3]``; joint_angles ``[N, 28]`` or None; host_time ``[N]`` s
    since the epoch (NaN unknown); hole ``[N]`` bool; groups by name; columns and unit of the
    file; legacy: an original-suite file (version 0); info: the header.
    """

    t: np.ndarray
    euler: np.ndarray
    joint_angles: np.ndarray | None
    columns: list[str]
    unit: str
    legacy: bool
    problems: list[str] = field(default_factory=list)
    host_time: np.ndarray | None = None
    hole: np.ndarray | None = None
    groups: dict[str, np.ndarray] = field(default_factory=dict)
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    info: FilteredInfo | None = None

    @property
    def version(self) -> int:
        return self.info.version if self.info else (0 if self.legacy else 1)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _cells(line: str, version: int) -> list[str]:
    cells = line.rstrip("\r\n").split(",")
    if version == 0 and len(cells) > 1 and cells[-1].strip() == "":
        cells.pop()  # the original's trailing comma
    return cells


class FilteredReader:
    """Streams a filtered file of any version (see the module docstring).

    ``info`` is read on construction; :meth:`blocks` yields :class:`FilteredBlock` of at most
    ``block_rows`` rows; bad lines are skipped and described in ``problems``. Raises
    :class:`FilteredFileError` with a one-line reason for a file that is not a filtered file.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.problems: list[str] = []
        try:
            self._file: TextIO = open(self.path, encoding="utf-8", newline="")  # noqa: SIM115
            self._header()
        except (OSError, UnicodeDecodeError) as exc:
            self.close()
            raise FilteredFileError(f"{self.path}: cannot be read ({exc})") from exc
        except FilteredFileError:
            self.close()
            raise

    def _header(self) -> None:
        path = self.path
        meta: dict[str, str] = {}
        version = 1
        first = ""
        self._line_no = 0
        left = MAX_HEADER_BYTES  # the header is bounded before it is parsed (io/bounded.py)
        while True:
            line = self._file.readline(left + 1)
            if not line:
                break
            left -= len(line)
            if left < 0:
                raise FilteredFileError(f"{path}: the header is longer than the "
                                        f"{MAX_HEADER_BYTES // (1024 * 1024)} MiB this "
                                        "software reads")
            self._line_no += 1
            if not line.strip():
                continue
            if line.startswith("#"):
                text = line[1:].strip()
                if text.startswith(FORMAT_NAME):
                    try:
                        version = int(text.split()[1])
                    except (IndexError, ValueError):
                        raise FilteredFileError(f"{path}: damaged header line {text[:60]!r}")\
                            from None
                    if version > FORMAT_VERSION:
                        raise FilteredFileError(
                            f"{path}: filtered file version {version} is newer than this "
                            f"software ({FORMAT_VERSION}); update BPMS Suite")
                elif ":" in text:
                    key, _, value = text.partition(":")
                    meta[key.strip()] = value.strip()
                continue
            first = line
            break
        if not first:
            raise FilteredFileError(f"{path}: empty file, not a filtered file")
        cells = [c.strip() for c in _cells(first, 0)]
        self._pending: str | None = None
        if all(_is_number(c) for c in cells) and not meta:
            version = 0
            if len(cells) != N_LEGACY_COLUMNS:
                raise FilteredFileError(
                    f"{path}: not a filtered file ({len(cells)} numbers per line, the original "
                    f"layout has {N_LEGACY_COLUMNS})")
            columns = ["time_s", *_GROUPS["euler"].names("rad")]
            self._pending = first
            self._first_line_no = self._line_no
        else:
            columns = [c.strip() for c in first.rstrip("\r\n").split(",")]
            self._first_line_no = self._line_no + 1
        if columns[0] != "time_s":
            raise FilteredFileError(f"{path}: not a filtered file (header {first[:60]!r})")
        angular = [c for c in columns if c.endswith(("_rad", "_deg"))]
        unit = meta.get("angles") or ("deg" if angular and angular[0].endswith("_deg")
                                      else "rad")
        index = {c: k for k, c in enumerate(columns)}
        if len(index) != len(columns):
            raise FilteredFileError(f"{path}: a column name appears twice")
        groups: list[str] = []
        self._slices: dict[str, list[int]] = {}
        used = {c for c in FIXED_COLUMNS if c in index}
        for name, group in _GROUPS.items():
            names = group.names(unit)
            present = [c in index for c in names]
            if all(present):
                groups.append(name)
                self._slices[name] = [index[c] for c in names]
                used.update(names)
            elif any(present):
                missing = names[present.index(False)]
                raise FilteredFileError(f"{path}: column group {name!r} is incomplete "
                                        f"(no {missing!r})")
        if "euler" not in groups and "euler_sensor" not in groups:
            raise FilteredFileError(f"{path}: not a filtered file (no Euler-angle columns, e.g. "
                                    f"{columns[1] if len(columns) > 1 else ''!r})")
        extra = [c for c in columns if c not in used]
        self._index = index
        self.info = FilteredInfo(path, version, columns, unit, meta, groups, extra)
        self._t0: float | None = None

    def _parse(self, lines: list[tuple[int, str]]) -> np.ndarray:
        n_cols = len(self.info.columns)
        version = self.info.version
        texts = [",".join(_cells(s, version)) for _, s in lines]
        try:
            data = np.loadtxt(texts, delimiter=",", dtype=np.float64, ndmin=2)
            if data.shape[1] == n_cols or not len(texts):
                return data.reshape(-1, n_cols)
        except ValueError:
            pass
        rows = []
        for number, line in lines:
            cells = _cells(line, version)
            if len(cells) != n_cols:
                self.problems.append(f"{self.path}: line {number} has {len(cells)} values, "
                                     f"expected {n_cols}: skipped")
                continue
            try:
                rows.append([float(c) for c in cells])
            except ValueError:
                self.problems.append(f"{self.path}: line {number} holds a value that is not "
                                     "a number: skipped")
        return np.array(rows, dtype=np.float64).reshape(-1, n_cols)

    def blocks(self, block_rows: int = BLOCK_ROWS) -> Iterator[FilteredBlock]:
        """The file's rows, block by block."""
        number = self._first_line_no
        batch: list[tuple[int, str]] = []
        if self._pending is not None:
            batch.append((number, self._pending))
            number += 1
            self._pending = None
        for line in self._file:
            if line.strip():
                batch.append((number, line))
            number += 1
            if len(batch) >= block_rows:
                yield self._block(self._parse(batch))
                batch = []
        if batch:
            yield self._block(self._parse(batch))

    def _block(self, data: np.ndarray) -> FilteredBlock:
        info = self.info
        n = len(data)
        col = data[:, 0]
        if info.version == 0 and n and (self._t0 is not None or col[0] > EPOCH_THRESHOLD_S):
            # The original wrote time.time(): absolute epoch seconds.
            if self._t0 is None:
                self._t0 = float(col[0])
            host, t = col.copy(), col - self._t0
        else:
            t = col.copy()
            host = (data[:, self._index["host_time_s"]].copy() if "host_time_s" in self._index
                    else np.full(n, np.nan))
        hole = (data[:, self._index["hole"]] != 0 if "hole" in self._index
                else np.zeros(n, dtype=bool))
        scale = np.radians(1.0) if info.unit == "deg" else 1.0
        groups = {}
        for name in info.groups:
            g = _GROUPS[name]
            values = data[:, self._slices[name]]
            if g.angular and scale != 1.0:
                values = values * scale
            groups[name] = values.reshape(n, *g.shape)
        extra = {c: data[:, self._index[c]].copy() for c in info.extra}
        return FilteredBlock(t, host, hole, groups, extra)

    def close(self) -> None:
        f = getattr(self, "_file", None)
        if f is not None:
            f.close()

    def __enter__(self) -> FilteredReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def iter_filtered(path: str | Path, block_rows: int = BLOCK_ROWS
                  ) -> tuple[FilteredInfo, Iterator[FilteredBlock], list[str]]:
    """(header, block iterator, problems list filled while iterating). The file is closed
    when the iterator is exhausted. Raises :class:`FilteredFileError`."""
    reader = FilteredReader(path)

    def run() -> Iterator[FilteredBlock]:
        with reader:
            yield from reader.blocks(block_rows)

    return reader.info, run(), reader.problems


def read_filtered(path: str | Path) -> FilteredData:
    """Read a whole filtered file of any version. Raises :class:`FilteredFileError` with a
    one-line reason for a file that is not a filtered file."""
    info, blocks, problems = iter_filtered(path)
    parts = list(blocks)
    euler_name = "euler" if "euler" in info.groups else "euler_sensor"

    def cat(get: Callable[[FilteredBlock], np.ndarray], shape: tuple[int, ...]) -> np.ndarray:
        return (np.concatenate([get(b) for b in parts]) if parts
                else np.zeros((0, *shape)))

    groups = {g: cat(lambda b, g=g: b.groups[g], _GROUPS[g].shape) for g in info.groups}
    return FilteredData(
        t=cat(lambda b: b.t, ()), euler=groups[euler_name],
        joint_angles=groups.get("joints"), columns=info.columns, unit=info.unit,
        legacy=info.legacy, problems=list(problems), host_time=cat(lambda b: b.host_time, ()),
        hole=cat(lambda b: b.hole, ()).astype(bool), groups=groups,
        extra={c: cat(lambda b, c=c: b.extra[c], ()) for c in info.extra}, info=info)


def default_output_path(raw_path: str | Path) -> Path:
    """``Raw…`` → ``Filtered….csv`` in the same folder (``Filtered_<stem>.csv`` otherwise)."""
    raw_path = Path(raw_path)
    stem = raw_path.stem
    name = ("Filtered" + stem[3:]) if stem.lower().startswith("raw") else f"Filtered_{stem}"
    return raw_path.with_name(name + ".csv")


__all__ = ["ColumnGroup", "FilteredBlock", "FilteredData", "FilteredFileError", "FilteredInfo",
           "FilteredReader", "FilteredWriter", "column_groups", "default_output_path",
           "filtered_columns", "iter_filtered", "read_filtered", "register_column_group"]
