"""Translators (the original "translator scripts"): one or several IMUs' raw counts, calibrated
values or Euler angles, or one rigid body of a Vicon/Qualisys export, to a CSV file whose
header row names every column with its unit."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np

from bpms.analysis.textout import write_rows
from bpms.io.filtered_file.reader import iter_filtered
from bpms.io.frames import CHANNEL_NAMES, IMU_NAMES, N_IMUS
from bpms.io.names import imu_column, slug

_FMT = "%.10g"
_HOST_FMT = "%.6f"
#: Units of the calibrated channels (``SensorCalibration.physical_units``, signed board axes).
CALIBRATED_UNITS = ("m_s2",) * 3 + ("gauss",) * 3 + ("rad_s",) * 3


class ExtractError(Exception):
    """A request that cannot be met (unknown IMU id, unknown body, ...): one line."""


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


def write_csv(path: str | Path, columns: Sequence[str], data: np.ndarray | Iterable[np.ndarray]
              ) -> int:
    """A header row, then one row per sample (``nan`` for missing values); ``data`` an array
    or an iterable of row blocks (written as they come). Columns named ``*_counts`` are
    written as integers, ``host_time_s`` to the microsecond. Returns the rows written."""
    fmt = ["%d" if c.endswith("_counts") else _HOST_FMT if c == "host_time_s" else _FMT
           for c in columns]
    blocks = [data] if isinstance(data, np.ndarray) else data
    rows = 0
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(",".join(columns) + "\n")
        for block in blocks:
            write_rows(f, block, fmt, ",", f"writing {Path(path).name}" if isinstance(
                data, np.ndarray) else "")
            rows += len(block)
    return rows


def raw_rows(raw_path: str | Path, ids: Sequence[int], calibrated: bool = False,
             calibration: str | Path | None = None
             ) -> tuple[list[str], Iterator[np.ndarray], object]:
    """Columns and row blocks (streamed, chunk by chunk) of ``bpms extract raw``, and the
    opened recording (:class:`bpms.filter.door.OpenedRecording`, its sources).

    ``time_s`` (stream time, :mod:`bpms.io.timebase`), ``host_time_s`` (receive time, s since
    the epoch, UTC), then per IMU its 9 channels: raw counts (``imu0_right_leg_ax_counts``)
    or, with ``calibrated``, accel m/s², mag gauss, gyro rad/s in signed board axes
    (:meth:`SensorCalibration.physical_units`; the calibration by the one door's precedence:
    ``calibration`` > the recording's header > the user's default > factory).
    """
    from bpms.filter.door import open_for_processing
    from bpms.io.timebase import stream_times

    opened = open_for_processing(raw_path, calibration)
    if opened.n_frames == 0:
        raise ExtractError(f"{raw_path}: the recording holds no frames")
    cal = opened.processor.sensor_calibration
    dt = opened.processor.options.filter.dt
    units = CALIBRATED_UNITS if calibrated else ("counts",) * 9
    columns = ["time_s", "host_time_s"]
    for i in ids:
        columns += [imu_column(i, c, u) for c, u in zip(CHANNEL_NAMES, units, strict=True)]

    def blocks() -> Iterator[np.ndarray]:
        for lo, host, decoded in opened.raw_chunks():
            n = len(host)
            if calibrated:
                acc, mag, gyr = cal.physical_units(decoded.raw)
                values = np.concatenate([acc, mag, gyr], axis=-1)
            else:
                values = decoded.raw.astype(np.float64)
            yield np.concatenate([stream_times(lo, n, dt)[:, None], host[:, None],
                                  values[:, ids, :].reshape(n, -1)], axis=1)

    return columns, blocks(), opened


def filtered_rows(filtered_path: str | Path, ids: Sequence[int], degrees: bool = False
                  ) -> tuple[list[str], Iterator[np.ndarray], list[str]]:
    """Columns, row blocks (streamed) and reader problems (filled while streaming) of ``bpms
    extract filtered``: ``time_s`` (s since the start), ``host_time_s`` (s since the epoch,
    UTC; ``nan`` when the file has none), then roll, pitch, yaw of each IMU in rad (deg with
    ``degrees``). Reads every version of the filtered file, the original suite's included.
    Raises :class:`bpms.io.filtered_file.reader.FilteredFileError` for a file that is not one."""
    info, blocks, problems = iter_filtered(filtered_path)
    name = "euler" if "euler" in info.groups else "euler_sensor"
    unit = "deg" if degrees else "rad"
    infix = "" if name == "euler" else "sensor_"  # the file's own names for these angles
    columns = ["time_s", "host_time_s"]
    for i in ids:
        columns += [imu_column(i, f"{infix}{e}", unit) for e in ("roll", "pitch", "yaw")]

    def rows() -> Iterator[np.ndarray]:
        for block in blocks:
            angles = block.groups[name][:, ids, :].reshape(len(block), -1)
            if degrees:
                angles = np.degrees(angles)
            yield np.concatenate([block.t[:, None], block.host_time[:, None], angles], axis=1)

    return columns, rows(), problems
