"""The one reader of filtered files of every version (see :mod:`bpms.io.filtered_file`):
:class:`FilteredReader` streams blocks, :func:`iter_filtered` and :func:`read_filtered` wrap
it."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np

from bpms.io.bounded import MAX_HEADER_BYTES
from bpms.io.closing import Closing
from bpms.io.filtered_file.columns import FIXED_COLUMNS, FORMAT_NAME, FORMAT_VERSION, column_groups
from bpms.io.frames import N_IMUS
from bpms.io.paths import require_regular_input

N_LEGACY_COLUMNS = 1 + 3 * N_IMUS
#: The first column of a version-0 file is absolute epoch time when above this (s; 1973).
EPOCH_THRESHOLD_S = 1e8
BLOCK_ROWS = 10_000


class FilteredFileError(Exception):
    """A file that cannot be read as a filtered file (message says why)."""


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


def is_number(text: str) -> bool:
    """``text`` reads as a float (a number cell, or a value typed into a field)."""
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


class FilteredReader(Closing):
    """Streams a filtered file of any version (see the module docstring).

    ``info`` is read on construction; :meth:`blocks` yields :class:`FilteredBlock` of at most
    ``block_rows`` rows; bad lines are skipped and described in ``problems``. Raises
    :class:`FilteredFileError` with a one-line reason for a file that is not a filtered file.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.problems: list[str] = []
        try:
            require_regular_input(self.path)
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
        self._known = column_groups()
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
        if all(is_number(c) for c in cells) and not meta:
            version = 0
            if len(cells) != N_LEGACY_COLUMNS:
                raise FilteredFileError(
                    f"{path}: not a filtered file ({len(cells)} numbers per line, the original "
                    f"layout has {N_LEGACY_COLUMNS})")
            columns = ["time_s", *self._known["euler"].names("rad")]
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
        for name, group in self._known.items():
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
            g = self._known[name]
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

    def group(g: str) -> Callable[[FilteredBlock], np.ndarray]:
        return lambda b: b.groups[g]

    def extra(c: str) -> Callable[[FilteredBlock], np.ndarray]:
        return lambda b: b.extra[c]

    known = column_groups()
    groups = {g: cat(group(g), known[g].shape) for g in info.groups}
    return FilteredData(
        t=cat(lambda b: b.t, ()), euler=groups[euler_name],
        joint_angles=groups.get("joints"), columns=info.columns, unit=info.unit,
        legacy=info.legacy, problems=list(problems), host_time=cat(lambda b: b.host_time, ()),
        hole=cat(lambda b: b.hole, ()).astype(bool), groups=groups,
        extra={c: cat(extra(c), ()) for c in info.extra}, info=info)
