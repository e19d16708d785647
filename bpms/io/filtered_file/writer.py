"""The filtered-file writer: :class:`FilteredWriter` writes a version-2 file block by block
(live logging and whole recordings alike)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import BinaryIO, TextIO, cast

import numpy as np

from bpms.io.closing import Closing
from bpms.io.filtered_file.columns import (
    FIXED_COLUMNS,
    FORMAT_NAME,
    FORMAT_VERSION,
    HOST_TIME_FMT,
    VALUE_FMT,
    column_groups,
    filtered_columns,
    group_list,
)
from bpms.io.text_rows import RowFormat

_DEGREES = np.degrees(1.0)
#: Written when the writer is given no convention (callers give the joint-angle convention in
#: force: :func:`bpms.filter.door.filtered_convention`).
_DEFAULT_CONVENTION = ("Euler roll, pitch, yaw (R = Rz Ry Rx), frame -> NED; joint angles: "
                       "docs/joint-angles.md")


class FilteredWriter(Closing):
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
        self.groups = group_list(groups, joints)
        self.joints = "joints" in self.groups
        self.columns = filtered_columns(degrees, groups=self.groups)
        self.rows = 0
        self.holes = 0
        #: characters handed to the file so far (its size once flushed), bytes
        self.bytes_written = 0
        unit = "deg" if degrees else "rad"
        known = column_groups()
        fmts = [VALUE_FMT, HOST_TIME_FMT, "%d"]
        for g in self.groups:
            fmts += [known[g].fmt] * known[g].width
        self._rows = RowFormat(fmts, [","] * (len(fmts) - 1))
        # (group, first column, width, angular columns scaled to degrees), computed once: a
        # live file takes one row per frame and this is its per-row overhead
        self._layout: list[tuple[str, int, int, bool]] = []
        col = len(FIXED_COLUMNS)
        for g in self.groups:
            w = known[g].width
            self._layout.append((g, col, w, degrees and known[g].angular))
            col += w
        # A file is written in binary mode (the rows are ASCII bytes already); a text stream
        # given by the caller receives text.
        self._file: BinaryIO | TextIO
        if isinstance(path, str | Path):
            self.path: Path | None = Path(path)
            self._file = open(self.path, "xb")  # noqa: SIM115
            self._owns = self._binary = True
        else:
            self.path, self._file, self._owns, self._binary = None, path, False, False
        header = {"euler": euler, "convention": convention, "angles": unit,
                  "groups": ",".join(self.groups), **(meta or {})}
        lines = [f"# {FORMAT_NAME} {FORMAT_VERSION}"]
        lines += [f"# {k}: {str(v).replace(chr(10), ' ')}" for k, v in header.items()]
        self._write("\n".join(lines) + "\n" + ",".join(self.columns) + "\n")

    def _write(self, text: str | bytes) -> None:
        self.bytes_written += len(text)
        if self._binary:
            cast(BinaryIO, self._file).write(text.encode("utf-8") if isinstance(text, str)
                                             else text)
        else:
            cast(TextIO, self._file).write(text.decode("ascii") if isinstance(text, bytes)
                                           else text)

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
        if n:
            self._write(self._rows.ascii(block))
        self.rows += n
        self.holes += holes

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


def default_output_path(raw_path: str | Path) -> Path:
    """``Raw…`` → ``Filtered….csv`` in the same folder (``Filtered_<stem>.csv`` otherwise)."""
    raw_path = Path(raw_path)
    stem = raw_path.stem
    name = ("Filtered" + stem[3:]) if stem.lower().startswith("raw") else f"Filtered_{stem}"
    return raw_path.with_name(name + ".csv")
