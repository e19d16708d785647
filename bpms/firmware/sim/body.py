"""The simulated subject's skeleton: where each segment points and where each IMU sits.

Written from the specification's body-model description (standing calibration pose: spine,
arms and legs point down, shoulders and hips sideways, feet forward; segment lengths of the
specification's Table 2.4, kept here in :class:`SubjectDimensions`), apart from the product's
body model and its options, so the simulated truth shares neither the code nor the default
numbers it checks. Segment orientations ``C[..., 18, 3, 3]`` map segment axes (X forward,
Y right, Z down in the calibration pose) to the world frame (north-east-down).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from bpms.io.frames import N_IMUS

#: The height the specification's default lengths belong to (Table 2.4: 50th-percentile US
#: male), m.
STANDARD_HEIGHT_M = 1.73


@dataclass(frozen=True)
class SubjectDimensions:
    """The simulated subject's segment lengths, m. The defaults are the specification's
    Table 2.4 (50th-percentile US male, 1.73 m tall), written here apart from the product's
    options. :meth:`of_height` scales them to another subject."""

    low_spine: float = 0.21
    mid_spine: float = 0.27
    neck: float = 0.20
    head: float = 0.22
    shoulder: float = 0.16
    arm: float = 0.34
    forearm: float = 0.27
    hand: float = 0.19
    hip: float = 0.17  # half the hip width
    thigh: float = 0.43
    shank: float = 0.40
    foot: float = 0.27
    height: float = STANDARD_HEIGHT_M

    @classmethod
    def of_height(cls, height: float, **lengths: float) -> SubjectDimensions:
        """A subject ``height`` m tall: Table 2.4's lengths × height / 1.73, except those
        given one by one in ``lengths`` (m)."""
        if not 0.5 <= height <= 2.5:
            raise ValueError(f"height {height} m is outside 0.5 .. 2.5 m")
        unknown = set(lengths) - {f.name for f in fields(cls)}
        if unknown:
            raise ValueError(f"unknown segment(s): {', '.join(sorted(unknown))}")
        ratio = height / STANDARD_HEIGHT_M
        base = cls()
        scaled = {f.name: getattr(base, f.name) * ratio for f in fields(cls)
                  if f.name != "height"}
        return replace(base, **{**scaled, **lengths}, height=height)

    def lengths(self) -> dict[str, float]:
        """Every segment length by name, m (height left out)."""
        return {f.name: float(getattr(self, f.name)) for f in fields(self) if f.name != "height"}

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


def point_positions(C: np.ndarray, body: SubjectDimensions | None = None) -> np.ndarray:
    """Skeleton points ``[N, 21, 3]`` (order :data:`POINTS`), metres, world NED axes, with
    the pelvis at the origin, by walking the chain from the pelvis: ``child = parent +
    C[imu] @ direction * length``. ``body``: any object with the lengths' attributes
    (default :class:`SubjectDimensions`)."""
    body = body or SubjectDimensions()
    C = np.asarray(C, dtype=np.float64)
    pos = np.zeros((C.shape[0], len(POINTS), 3))
    for name, parent, imu, direction, length in SKELETON:
        step = C[:, imu] @ (np.asarray(direction) * getattr(body, length))
        pos[:, POINT[name]] = pos[:, POINT[parent]] + step
    return pos


def imu_positions(points: np.ndarray) -> np.ndarray:
    """``[N, 18, 3]``: each IMU midway along its segment, from :func:`point_positions`."""
    return 0.5 * (points[:, IMU_SEGMENT_START] + points[:, IMU_SEGMENT_END])
