"""A CSV for MATLAB (``readtable``/``readmatrix``): one header row, one row per frame.

Columns: ``time_s``; per IMU its filter orientation as a quaternion (``imu0_right_leg_qw`` ...,
filter frame → NED, unitless) and Euler angles (``imu0_right_leg_roll_deg`` ..., docs/filter.md);
then the 28 joint angles (``joint_knee_r_flexion_deg`` ...). Degrees (radians with
``degrees=False``, names ending ``_rad``). Missing values are ``NaN``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bpms.analysis.extract import slug
from bpms.analysis.textout import write_rows
from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.io.frames import IMU_NAMES, N_IMUS


def matlab_columns(degrees: bool = True) -> list[str]:
    unit = "deg" if degrees else "rad"
    cols = ["time_s"]
    for i, name in enumerate(IMU_NAMES):
        s = f"imu{i}_{slug(name)}"
        cols += [f"{s}_q{c}" for c in "wxyz"] + [f"{s}_{e}_{unit}" for e in ("roll", "pitch",
                                                                              "yaw")]
    cols += [f"joint_{slug(j)}_{unit}" for j in JOINT_ANGLE_NAMES]
    return cols


def write_matlab_csv(path: str | Path, t: np.ndarray, quaternions: np.ndarray,
                     euler: np.ndarray, joint_angles: np.ndarray, degrees: bool = True) -> int:
    """``t[N]`` s, ``quaternions[N, 18, 4]``, ``euler[N, 18, 3]`` rad, ``joint_angles[N, 28]``
    rad → the CSV. Returns the number of rows."""
    n = len(t)
    scale = np.degrees(1.0) if degrees else 1.0
    per_imu = np.concatenate([quaternions, euler * scale], axis=-1).reshape(n, N_IMUS * 7)
    data = np.concatenate([np.asarray(t)[:, None], per_imu, joint_angles * scale], axis=1)
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(",".join(matlab_columns(degrees)) + "\n")
        write_rows(f, data, "%.8g", ",", f"writing {Path(path).name}")
    return n
