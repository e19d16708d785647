"""OpenSim OpenSense orientations file (``.sto``, ``DataType=Quaternion``).

Each cell is one IMU's orientation ``w,x,y,z``: the segment orientation after Reset Zero
(``Result.segment_quaternions``), segment axes → world NED. In the calibration pose every such
"sensor" frame is the body's frame (x forward, y right, z down), so in the IMU placer use
``base_imu_label = pelvis_imu``, ``base_heading_axis = x`` and
``sensor_to_opensim_rotations = SENSOR_TO_OPENSIM_ROTATIONS`` (NED z-down → OpenSim y-up).
Rows before the first Reset Zero capture (no segment orientation yet) are left out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from bpms.analysis.textout import TextWriter, write_rows

if TYPE_CHECKING:
    from bpms.filter.pose import Zero

#: IMU id → OpenSim body (Rajagopal 2015 / gait2392 names) + "_imu".
OPENSIM_IMUS: dict[int, str] = {
    6: "pelvis_imu",
    8: "torso_imu",
    4: "humerus_r_imu",
    5: "radius_r_imu",
    3: "hand_r_imu",
    0: "femur_r_imu",
    2: "tibia_r_imu",
    1: "calcn_r_imu",
    10: "humerus_l_imu",
    11: "radius_l_imu",
    9: "hand_l_imu",
    12: "femur_l_imu",
    14: "tibia_l_imu",
    13: "calcn_l_imu",
}
#: For models with a head and neck (e.g. full-body models with cervical bodies).
OPENSIM_HEAD_IMUS: dict[int, str] = {7: "neck_imu", 17: "head_imu"}

#: Space-fixed X, Y, Z rotations (rad) for the IMU placer: world NED (x north, y east,
#: z down) → OpenSim ground (x forward, y up, z right) is a rotation of +90° about X.
SENSOR_TO_OPENSIM_ROTATIONS = (math.pi / 2, 0.0, 0.0)


def imu_columns(head_neck: bool = False) -> dict[int, str]:
    """IMU id → column name of the orientations file."""
    return {**OPENSIM_IMUS, **(OPENSIM_HEAD_IMUS if head_neck else {})}


class OrientationsWriter(TextWriter):
    """An OpenSense orientations file written block by block (constant memory).

    ``write(t[N], quaternions[N, 18, 4])``: rows where a mapped IMU has no orientation (NaN)
    are skipped; each quaternion is normalised. ``rows``: rows written so far. meta: extra
    ``key=value`` header lines (the recording's ``utc_start`` and ``joint_angle_convention``,
    :meth:`bpms.analysis.stamp.Stamp.items`)."""

    def __init__(self, path: str | Path, rate_hz: float = 50.0, head_neck: bool = False,
                 opensim_version: str = "4.5",
                 meta: Sequence[tuple[str, str]] = ()) -> None:
        cols = imu_columns(head_neck)
        self.ids = list(cols)
        super().__init__(path)
        self.rows = 0
        self._row = "\t".join(["%.6f", *(["%.8f,%.8f,%.8f,%.8f"] * len(self.ids))])
        self._file.write(f"DataRate={rate_hz:.6f}\nDataType=Quaternion\nversion=3\n"
                         f"OpenSimVersion={opensim_version}\n")
        for key, value in meta:
            self._file.write(f"{key}={str(value).replace(chr(10), ' ')}\n")
        self._file.write("endheader\n")
        self._file.write("\t".join(["time", *(cols[i] for i in self.ids)]) + "\n")

    def write(self, t: np.ndarray, quaternions: np.ndarray) -> int:
        q = np.asarray(quaternions, dtype=np.float64)[:, self.ids, :]
        keep = np.isfinite(q).all(axis=(1, 2))
        q = q[keep]
        q = q / np.linalg.norm(q, axis=-1, keepdims=True)
        times = np.asarray(t, dtype=np.float64)[keep]
        if len(times):
            write_rows(self._file, np.concatenate([times[:, None], q.reshape(len(q), -1)],
                                                  axis=1), self._row, "\t", "")
        self.rows += len(times)
        return len(times)


def calibration_window(settle_frames: int, window_frames: int, n: int) -> tuple[int, int]:
    """Frame range ``[lo, hi)`` of the calibration pose: the averaging window of the automatic
    Reset Zero (``settle`` frames after the start, ``window`` frames long; docs/body-model.md)."""
    lo = min(n, max(0, settle_frames))
    return lo, min(n, lo + max(1, window_frames))


def pose_calibration_window(data: dict, n: int) -> tuple[int, int, Zero]:
    """``(lo, hi, zero)`` for a pose calibration's ``reset_zero`` event (``--pose-calibration
    posture|functional``, docs/pose-calibration.md, its ``data``): the frame range ``[lo, hi)``
    of its still window in a recording of ``n`` frames, and the zero it adopts. The event takes
    effect the frame after that window, so the window's orientations are made again with
    :func:`calibration_quaternions`. Raises ValueError when the event lacks them."""
    from bpms.filter.pose import Zero
    from bpms.io.event_types import ResetZero

    try:  # the one reader of a reset_zero event's data
        change = ResetZero.from_data(data)
        values = change.zero
        first, last = (int(k) for k in change.details["still"])
    except (KeyError, TypeError, ValueError):
        values = None
    if values is None:
        raise ValueError("the pose calibration's event has no still window or zero")
    lo = min(n, max(0, first))
    return lo, min(n, max(lo + 1, last + 1)), Zero(values[0], values[1], last + 1,
                                                   str(data.get("source", "")))


def calibration_quaternions(R: np.ndarray, zero: Zero) -> np.ndarray:
    """``[N, 18, 4]`` (w, x, y, z): the segment orientations of the filter's DCMs
    ``R[N, 18, 3, 3]`` with ``zero`` in force instead of the zero that was (the processor's own
    :func:`bpms.filter.pose.segment_orientations` and :class:`bpms.filter.result.Result`)."""
    from bpms.filter.pose import segment_orientations
    from bpms.filter.result import Result

    C = segment_orientations(R, zero)
    return Result(t=np.zeros(len(R)), R=R, C=C).segment_quaternions


#: The OpenSim model whose coordinate names the .mot uses (its knee flexion is positive).
MOT_MODEL = "Rajagopal et al. 2016 full-body model (Rajagopal2015.osim)"


class JointAnglesMotWriter(TextWriter):
    """The joint angles as an OpenSim motion file (``.mot``, degrees), written block by block:
    one column per coordinate of :data:`bpms.filter.joints.OPENSIM_COORDINATES` (the names
    of :data:`MOT_MODEL`, OpenSim's signs: adduction and internal rotation positive), every
    frame a row, ``nan`` where a segment has no orientation (before the first Reset Zero, a
    failed IMU). ``nRows`` is patched in at :meth:`close`. meta: extra ``key=value`` header
    lines (:meth:`bpms.analysis.stamp.Stamp.items`)."""

    def __init__(self, path: str | Path, convention: str = "isb",
                 meta: Sequence[tuple[str, str]] = ()) -> None:
        from bpms.filter.joints import OPENSIM_COORDINATES

        super().__init__(path)
        self.convention = convention
        self.columns = list(OPENSIM_COORDINATES)
        self.rows = 0
        self._file.write("joint_angles\nversion=1\n")
        self._reserve_count("nRows=")
        self._file.write(f"\nnColumns={len(self.columns) + 1}\n"
                         f"inDegrees=yes\nmodel={MOT_MODEL}\n")
        for key, value in meta:
            self._file.write(f"{key}={str(value).replace(chr(10), ' ')}\n")
        self._file.write("endheader\n" + "\t".join(["time", *self.columns]) + "\n")

    def write(self, t: np.ndarray, joint_angles: np.ndarray) -> None:
        """``t[N]`` s, ``joint_angles[N, 28]`` rad in :attr:`convention`."""
        from bpms.filter.joints import opensim_coordinates

        coords = opensim_coordinates(joint_angles, self.convention)
        data = np.column_stack([np.asarray(t, np.float64),
                                *(np.degrees(coords[c]) for c in self.columns)])
        if len(data):
            write_rows(self._file, data, "%.6f", "\t", "")
        self.rows += len(data)

    def close(self) -> None:
        if not self._file.closed:
            self._patch_count(self.rows)
        super().close()
