"""Translators (the original "translator scripts"): one or several IMUs' raw counts, calibrated
values or Euler angles, or one rigid body of a Vicon/Qualisys export, to a CSV file whose
header row names every column with its unit."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bpms.analysis.textout import write_rows
from bpms.filter.calibration import SensorCalibration
from bpms.io.calib_file import load_calibration
from bpms.io.filtered_file import read_filtered
from bpms.io.frames import CHANNEL_NAMES, IMU_NAMES, N_IMUS
from bpms.io.options import load_options
from bpms.io.recordings import open_recording

_FMT = "%.10g"
#: Units of the calibrated channels (``SensorCalibration.physical_units``, signed board axes).
CALIBRATED_UNITS = ("m_s2",) * 3 + ("gauss",) * 3 + ("rad_s",) * 3


class ExtractError(Exception):
    """A request that cannot be met (unknown IMU id, unknown body, ...): one line."""


def slug(text: str) -> str:
    """``"Right Leg"`` → ``"right_leg"``."""
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")


def available_imus() -> str:
    """``0 (Right Leg), 1 (Right Foot), ...`` for messages."""
    return ", ".join(f"{i} ({name})" for i, name in enumerate(IMU_NAMES))


def parse_imu_ids(specs: Sequence[str]) -> list[int]:
    """``["all"]``, ``["0", "5"]``, ``["0,5"]`` or IMU names (``right_leg``) → ids 0..17."""
    ids: list[int] = []
    for spec in specs:
        for item in filter(None, (s.strip() for s in str(spec).split(","))):
            if item.lower() == "all":
                ids.extend(range(N_IMUS))
                continue
            if item.isdigit() and int(item) < N_IMUS:
                ids.append(int(item))
                continue
            names = [slug(n) for n in IMU_NAMES]
            if slug(item) in names:
                ids.append(names.index(slug(item)))
                continue
            raise ExtractError(f"no IMU {item!r}; available ids: {available_imus()}, or 'all'")
    if not ids:
        raise ExtractError(f"no IMU given; available ids: {available_imus()}, or 'all'")
    return list(dict.fromkeys(ids))


def write_csv(path: str | Path, columns: Sequence[str], data: np.ndarray) -> None:
    """A header row, then one row per sample (``nan`` for missing values). Columns named
    ``*_counts`` are written as integers (half the formatting time of floats)."""
    fmt = ["%d" if c.endswith("_counts") else _FMT for c in columns]
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(",".join(columns) + "\n")
        write_rows(f, data, fmt, ",", f"writing {Path(path).name}")


def raw_table(raw_path: str | Path, ids: Sequence[int], calibrated: bool = False,
              calibration: str | Path | None = None) -> tuple[list[str], np.ndarray]:
    """Columns and rows of ``bpms extract raw``.

    ``time_s`` (frame index × 0.02 s, the fixed filter clock), ``host_time_s`` (receive time
    since the first frame), then per IMU its 9 channels: raw counts (``imu0_right_leg_ax_counts``)
    or, with ``calibrated``, accel m/s², mag gauss, gyro rad/s in signed board axes
    (:meth:`SensorCalibration.physical_units`, the calibration stored in the recording unless
    ``calibration`` names a Calib.cfg).
    """
    from bpms.analysis.source import header_calibration, header_options

    recording = open_recording(raw_path)
    decoded = recording.decode()
    n = len(decoded.raw)
    if n == 0:
        raise ExtractError(f"{raw_path}: the recording holds no frames")
    t = np.arange(n) * 0.02
    host = recording.times - recording.times[0] if n else np.zeros(0)
    if calibrated:
        table = load_calibration(calibration) if calibration else header_calibration(recording)
        if table is None:
            table = load_calibration(None)
        opts = header_options(recording) or load_options(None)
        cal = SensorCalibration.from_table(table, opts.sensors)
        acc, mag, gyr = cal.physical_units(decoded.raw)
        values = np.concatenate([acc, mag, gyr], axis=-1)
        units = CALIBRATED_UNITS
    else:
        values = decoded.raw.astype(np.float64)
        units = ("counts",) * 9
    columns = ["time_s", "host_time_s"]
    for i in ids:
        stem = f"imu{i}_{slug(IMU_NAMES[i])}"
        columns += [f"{stem}_{c}_{u}" for c, u in zip(CHANNEL_NAMES, units, strict=True)]
    data = np.concatenate([t[:, None], host[:, None], values[:, ids, :].reshape(n, -1)], axis=1)
    return columns, data


def filtered_table(filtered_path: str | Path, ids: Sequence[int],
                   degrees: bool = False) -> tuple[list[str], np.ndarray, list[str]]:
    """Columns, rows and reader problems of ``bpms extract filtered``: ``time_s`` then roll,
    pitch, yaw of each IMU in rad (deg with ``degrees``). Raises
    :class:`bpms.io.filtered_file.FilteredFileError` for a file that is not a filtered file."""
    data = read_filtered(filtered_path)
    if len(data.t) == 0:
        raise ExtractError(f"{filtered_path}: the file holds no rows of data")
    unit = "deg" if degrees else "rad"
    columns = ["time_s"]
    for i in ids:
        columns += [f"imu{i}_{slug(IMU_NAMES[i])}_{e}_{unit}" for e in ("roll", "pitch", "yaw")]
    angles = data.euler[:, ids, :].reshape(len(data.t), -1)
    if degrees:
        angles = np.degrees(angles)
    return columns, np.concatenate([data.t[:, None], angles], axis=1), data.problems
