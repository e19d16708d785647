"""The filtered file's columns: the format's name and version, the fixed columns, the
column groups (built-in and registered by the modules that own the data) and the value
formats."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from bpms.io.frames import IMU_NAMES, N_IMUS
from bpms.io.names import JOINT_ANGLE_NAMES, imu_column, joint_column

FORMAT_NAME = "bpms-filtered-file"
FORMAT_VERSION = 2
EULER_NAMES = ("roll", "pitch", "yaw")
FIXED_COLUMNS = ("time_s", "host_time_s", "hole")
VALUE_FMT = "%.10g"
HOST_TIME_FMT = "%.6f"
# Flags are written 1/0 (``nan`` in a hole row); the reader returns them as floats 1.0/0.0/NaN.
FLAG_FMT = "%.0f"


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
    fmt: str = VALUE_FMT
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


def _imu_names(suffixes: Sequence[str], angular: bool = False) -> Callable[[str], list[str]]:
    """The columns ``suffixes`` of every IMU, ending in the file's angle unit when
    ``angular``."""
    def names(unit: str) -> list[str]:
        return [imu_column(i, x, unit if angular else None) for i in range(len(IMU_NAMES))
                for x in suffixes]
    return names


register_column_group(ColumnGroup(
    "euler", _imu_names(EULER_NAMES, angular=True), (N_IMUS, 3), angular=True,
    description="roll, pitch, yaw of IMU 0..17 (which ones: the 'euler' header line)"))
register_column_group(ColumnGroup(
    "euler_sensor", _imu_names([f"sensor_{e}" for e in EULER_NAMES], angular=True),
    (N_IMUS, 3), angular=True,
    description="each IMU's uncorrected filter roll, pitch, yaw, when 'euler' holds the "
                "Reset-Zero-corrected segment angles"))
register_column_group(ColumnGroup(
    "corrected", lambda unit: ["corrected"], (1,), fmt="%.0f",
    description="1 where the 'euler' columns hold Reset-Zero-corrected segment angles, 0 "
                "where they still hold the sensor angles (before the first Reset Zero, or "
                "with the correction switched off)"))
register_column_group(ColumnGroup(
    "joints", lambda unit: [joint_column(j, unit) for j in JOINT_ANGLE_NAMES],
    (len(JOINT_ANGLE_NAMES),), angular=True, description="the 28 joint angles"))


register_column_group(ColumnGroup(
    "reinitialised", _imu_names(["reinit"]), (N_IMUS,), fmt=FLAG_FMT,
    description="1 where the state guard re-initialised IMU i's filter at that frame"))
register_column_group(ColumnGroup(
    "mag_disturbed", _imu_names(["mag_disturbed"]), (N_IMUS,), fmt=FLAG_FMT,
    description="1 where IMU i's magnetometer is disturbed (field off the earth's or turned)"))
register_column_group(ColumnGroup(
    "acc_disturbed", _imu_names(["acc_disturbed"]), (N_IMUS,), fmt=FLAG_FMT,
    description="1 where IMU i accelerates (over 0.2 g RMS)"))
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
    for g in group_list(groups, joints):
        cols += _GROUPS[g].names(unit)
    return cols


def group_list(groups: Sequence[str] | None, joints: bool) -> list[str]:
    """The column groups of a file, in order, once each: ``groups``, or by default ``euler``
    (plus ``joints`` with ``joints``). Raises ValueError for an unknown group."""
    if groups is None:
        groups = ["euler", *(["joints"] if joints else [])]
    unknown = [g for g in groups if g not in _GROUPS]
    if unknown:
        raise ValueError(f"unknown column group {unknown[0]!r} (known: {', '.join(_GROUPS)})")
    return list(dict.fromkeys(groups))
