"""The filtered file (docs/filter.md): CSV text, one row per frame.

Columns: ``time_s`` (seconds since the stream started, on the fixed 50 Hz filter clock), then
roll, pitch, yaw of IMU 0..17 (``imu0_right_leg_roll_rad``, ...), then optionally the 28 joint
angles (``joint_knee_r_flexion_rad``, ...). Angles are radians by default, degrees when the
names end in ``_deg``. The first row names every column with its unit. NaN (an IMU not yet
initialised) is written ``nan``.

The reader also accepts the legacy header-less layout of the original suite: 55 comma-separated
numbers per line, time then roll, pitch, yaw in radians for IMU 0..17.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np

from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.io.frames import IMU_NAMES, N_IMUS

EULER_NAMES = ("roll", "pitch", "yaw")
N_LEGACY_COLUMNS = 1 + 3 * N_IMUS
_FMT = "%.10g"


class FilteredFileError(Exception):
    """A file that cannot be read as a filtered file (message says why)."""


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")


def filtered_columns(degrees: bool = False, joints: bool = False) -> list[str]:
    """Column names of a filtered file."""
    unit = "deg" if degrees else "rad"
    cols = ["time_s"]
    for i, name in enumerate(IMU_NAMES):
        cols += [f"imu{i}_{_slug(name)}_{e}_{unit}" for e in EULER_NAMES]
    if joints:
        cols += [f"joint_{_slug(j)}_{unit}" for j in JOINT_ANGLE_NAMES]
    return cols


class FilteredWriter:
    """Writes a filtered file row by row or in blocks (live logging or whole files).

    Angles are given in radians; with ``degrees`` they are written in degrees.
    """

    def __init__(self, path: str | Path | TextIO, degrees: bool = False,
                 joints: bool = False) -> None:
        self.degrees = degrees
        self.joints = joints
        self.columns = filtered_columns(degrees, joints)
        self.rows = 0
        if isinstance(path, str | Path):
            self.path: Path | None = Path(path)
            self._file: TextIO = open(self.path, "x", encoding="utf-8", newline="\n")  # noqa: SIM115
            self._owns = True
        else:
            self.path, self._file, self._owns = None, path, False
        self._file.write(",".join(self.columns) + "\n")

    def write_block(self, t: np.ndarray, euler: np.ndarray,
                    joint_angles: np.ndarray | None = None) -> None:
        """``t[N]`` s, ``euler[N, 18, 3]`` rad, ``joint_angles[N, 28]`` rad (with ``joints``)."""
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        n = len(t)
        parts = [t[:, None], np.asarray(euler, dtype=np.float64).reshape(n, 3 * N_IMUS)]
        if self.joints:
            if joint_angles is None:
                raise ValueError("this file has joint-angle columns: give joint_angles")
            parts.append(np.asarray(joint_angles, dtype=np.float64).reshape(n, -1))
        block = np.concatenate(parts, axis=1)
        if self.degrees:
            block[:, 1:] = np.degrees(block[:, 1:])
        if n:
            np.savetxt(self._file, block, fmt=_FMT, delimiter=",")
        self.rows += n

    def write(self, t: float, euler: np.ndarray, joint_angles: np.ndarray | None = None) -> None:
        """One row: ``euler[18, 3]`` rad, ``joint_angles[28]`` rad."""
        self.write_block(np.array([t]), np.asarray(euler)[None],
                         None if joint_angles is None else np.asarray(joint_angles)[None])

    def flush(self) -> None:
        self._file.flush()

    def close(self) -> None:
        if self._owns and not self._file.closed:
            self._file.close()

    def __enter__(self) -> FilteredWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass
class FilteredData:
    """A filtered file read back; angles always in radians.

    t ``[N]`` s; euler ``[N, 18, 3]``; joint_angles ``[N, 28]`` or None; columns as in the
    file (legacy files get the standard radian names); unit of the file ("rad"/"deg");
    legacy: the file had no header.
    """

    t: np.ndarray
    euler: np.ndarray
    joint_angles: np.ndarray | None
    columns: list[str]
    unit: str
    legacy: bool
    problems: list[str] = field(default_factory=list)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def read_filtered(path: str | Path) -> FilteredData:
    """Read a filtered file (this suite's, or the legacy header-less layout).

    Raises :class:`FilteredFileError` with a one-line reason for anything else.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise FilteredFileError(f"{path}: cannot be read ({exc})") from exc
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise FilteredFileError(f"{path}: empty file, not a filtered file")
    first = [c.strip() for c in lines[0].split(",")]
    legacy = all(_is_number(c) for c in first)
    if legacy:
        if len(first) != N_LEGACY_COLUMNS:
            raise FilteredFileError(f"{path}: not a filtered file ({len(first)} numbers per line, "
                                    f"the legacy layout has {N_LEGACY_COLUMNS})")
        columns, body = filtered_columns(), lines
    else:
        columns, body = first, lines[1:]
    if columns[0] != "time_s" or len(columns) < N_LEGACY_COLUMNS:
        raise FilteredFileError(f"{path}: not a filtered file (header {lines[0][:60]!r})")
    unit = "deg" if columns[1].endswith("_deg") else "rad"
    expected = filtered_columns(unit == "deg", joints=len(columns) > N_LEGACY_COLUMNS)
    if columns != expected:
        raise FilteredFileError(f"{path}: unexpected columns (e.g. {columns[1]!r})")
    problems = []
    rows = []
    for number, line in enumerate(body, start=1 if legacy else 2):
        cells = line.split(",")
        if len(cells) != len(columns):
            problems.append(f"{path}: line {number} has {len(cells)} values, expected "
                            f"{len(columns)}: skipped")
            continue
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            problems.append(f"{path}: line {number} holds a value that is not a number: skipped")
    data = np.array(rows, dtype=np.float64).reshape(-1, len(columns))
    angles = data[:, 1:]
    if unit == "deg":
        angles = np.radians(angles)
    euler = angles[:, : 3 * N_IMUS].reshape(-1, N_IMUS, 3)
    joints = angles[:, 3 * N_IMUS:] if len(columns) > N_LEGACY_COLUMNS else None
    return FilteredData(data[:, 0].copy(), euler, joints, columns, unit, legacy, problems)


def default_output_path(raw_path: str | Path) -> Path:
    """``Raw…`` → ``Filtered….csv`` in the same folder (``Filtered_<stem>.csv`` otherwise)."""
    raw_path = Path(raw_path)
    stem = raw_path.stem
    name = ("Filtered" + stem[3:]) if stem.lower().startswith("raw") else f"Filtered_{stem}"
    return raw_path.with_name(name + ".csv")


__all__ = ["FilteredData", "FilteredFileError", "FilteredWriter", "default_output_path",
           "filtered_columns", "read_filtered"]
