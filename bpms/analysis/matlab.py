"""A CSV for MATLAB (``readtable``/``readmatrix``): one header row, one row per frame.

Columns (the names of docs/analysis.md, "Column names"): ``time_s``; per IMU its filter
orientation as a quaternion (``imu0_right_leg_sensor_qw`` ..., filter frame → NED, unitless) and
Euler angles (``imu0_right_leg_sensor_roll_deg`` ..., docs/filter.md); then the 28 joint angles
(``joint_knee_r_flexion_deg`` ...). Degrees (radians with
``degrees=False``, names ending ``_rad``). Missing values are ``NaN``. Before the column row,
``% key: value`` lines state the recording's UTC start and the joint-angle convention: read
with ``readtable(file, 'CommentStyle', '%')``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bpms.analysis.textout import TextWriter, write_rows
from bpms.io.frames import IMU_NAMES, N_IMUS
from bpms.io.names import JOINT_ANGLE_NAMES, imu_column, joint_column


def matlab_columns(degrees: bool = True) -> list[str]:
    unit = "deg" if degrees else "rad"
    cols = ["time_s"]
    for i in range(len(IMU_NAMES)):
        cols += [imu_column(i, f"sensor_q{c}") for c in "wxyz"]
        cols += [imu_column(i, f"sensor_{e}", unit) for e in ("roll", "pitch", "yaw")]
    cols += [joint_column(j, unit) for j in JOINT_ANGLE_NAMES]
    return cols


class MatlabCsvWriter(TextWriter):
    """The MATLAB CSV written block by block (constant memory); ``rows`` written so far."""

    def __init__(self, path: str | Path, degrees: bool = True,
                 meta: Sequence[tuple[str, str]] = ()) -> None:
        super().__init__(path)
        self.scale = np.degrees(1.0) if degrees else 1.0
        self.rows = 0
        for key, value in meta:  # MATLAB comment lines (readtable 'CommentStyle', '%')
            self._file.write(f"% {key}: {str(value).replace(chr(10), ' ')}\n")
        self._file.write(",".join(matlab_columns(degrees)) + "\n")

    def write(self, t: np.ndarray, quaternions: np.ndarray, euler: np.ndarray,
              joint_angles: np.ndarray) -> None:
        """``t[N]`` s, ``quaternions[N, 18, 4]``, ``euler[N, 18, 3]`` rad,
        ``joint_angles[N, 28]`` rad."""
        n = len(t)
        per_imu = np.concatenate([quaternions, euler * self.scale], axis=-1).reshape(
            n, N_IMUS * 7)
        data = np.concatenate([np.asarray(t)[:, None], per_imu, joint_angles * self.scale],
                              axis=1)
        write_rows(self._file, data, "%.10g", ",", "")
        self.rows += n
