"""The simulated subject's skeleton: where each segment points and where each IMU sits.

Written from the specification's body-model description (standing calibration pose: spine,
arms and legs point down, shoulders and hips sideways, feet forward; segment lengths from
``BodyOptions``), apart from the filter package's body model so the simulated truth does not share
the code it checks. Segment orientations ``C[..., 18, 3, 3]`` map segment axes (X forward,
Y right, Z down in the calibration pose) to the world frame (north-east-down).
"""

from __future__ import annotations

import numpy as np

from bpms.io.frames import N_IMUS
from bpms.io.options import BodyOptions

_UP, _DOWN = (0.0, 0.0, -1.0), (0.0, 0.0, 1.0)
_RIGHT, _LEFT, _FORWARD = (0.0, 1.0, 0.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0)

#: (point, parent point, IMU whose segment carries it, direction in segment axes, length name).
#: "pelvis" is the root, where the low spine meets the hips.
SKELETON: tuple[tuple[str, str, int, tuple[float, float, float], str], ...] = (
    ("spine_mid", "pelvis", 6, _UP, "low_spine"),
    ("neck_base", "spine_mid", 8, _UP, "mid_spine"),
    ("head_base", "neck_base", 7, _UP, "neck"),
    ("head_top", "head_base", 17, _UP, "head"),
    ("shoulder_r", "neck_base", 15, _RIGHT, "shoulder"),
    ("elbow_r", "shoulder_r", 4, _DOWN, "arm"),
    ("wrist_r", "elbow_r", 5, _DOWN, "forearm"),
    ("fingers_r", "wrist_r", 3, _DOWN, "hand"),
    ("shoulder_l", "neck_base", 16, _LEFT, "shoulder"),
    ("elbow_l", "shoulder_l", 10, _DOWN, "arm"),
    ("wrist_l", "elbow_l", 11, _DOWN, "forearm"),
    ("fingers_l", "wrist_l", 9, _DOWN, "hand"),
    ("hip_r", "pelvis", 6, _RIGHT, "hip"),
    ("knee_r", "hip_r", 0, _DOWN, "thigh"),
    ("ankle_r", "knee_r", 2, _DOWN, "shank"),
    ("toe_r", "ankle_r", 1, _FORWARD, "foot"),
    ("hip_l", "pelvis", 6, _LEFT, "hip"),
    ("knee_l", "hip_l", 12, _DOWN, "thigh"),
    ("ankle_l", "knee_l", 14, _DOWN, "shank"),
    ("toe_l", "ankle_l", 13, _FORWARD, "foot"),
)
POINTS: tuple[str, ...] = ("pelvis", *(row[0] for row in SKELETON))
POINT = {name: i for i, name in enumerate(POINTS)}

#: Each IMU sits midway along the first segment the table gives it (the pelvis IMU on the low
#: spine, the shoulder IMUs on the shoulder girdle).
_IMU_ENDS: dict[int, tuple[int, int]] = {}
for _name, _parent, _imu, _d, _l in SKELETON:
    _IMU_ENDS.setdefault(_imu, (POINT[_parent], POINT[_name]))
IMU_SEGMENT_START = np.array([_IMU_ENDS[i][0] for i in range(N_IMUS)])
IMU_SEGMENT_END = np.array([_IMU_ENDS[i][1] for i in range(N_IMUS)])


def point_positions(C: np.ndarray, body: BodyOptions | None = None) -> np.ndarray:
    """Skeleton points ``[N, 21, 3]`` (order :data:`POINTS`), metres, world NED axes, with
    the pelvis at the origin, by walking the chain from the pelvis: ``child = parent +
    C[imu] @ direction * length``."""
    body = body or BodyOptions()
    C = np.asarray(C, dtype=np.float64)
    pos = np.zeros((C.shape[0], len(POINTS), 3))
    for name, parent, imu, direction, length in SKELETON:
        step = C[:, imu] @ (np.asarray(direction) * getattr(body, length))
        pos[:, POINT[name]] = pos[:, POINT[parent]] + step
    return pos


def imu_positions(points: np.ndarray) -> np.ndarray:
    """``[N, 18, 3]``: each IMU midway along its segment, from :func:`point_positions`."""
    return 0.5 * (points[:, IMU_SEGMENT_START] + points[:, IMU_SEGMENT_END])
