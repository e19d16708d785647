"""Joint angles (SPEC §7, dissertation chapter 3.1).

- Elbow and knee flexion: the angle between the two segments' long axes (eq. 3.8), radians,
  0 in the calibration pose.
- Multi-DOF joints: ``R = C_static^T C_dynamic`` of the two calibrated segment orientations,
  then roll/pitch/yaw as SPEC §5 step 5, named as Table 3.1: roll = adduction/abduction,
  pitch = flexion/extension, yaw = lateral/medial rotation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bpms.filter.body_model import SEGMENT_AXIS
from bpms.filter.rotations import dcm_to_euler
from bpms.io.names import JOINT_ANGLE_NAMES


@dataclass(frozen=True)
class HingeJoint:
    name: str
    proximal: int  # IMU id
    distal: int


@dataclass(frozen=True)
class BallJoint:
    name: str
    dynamic: int  # IMU id of the moving segment
    static: int  # IMU id of the reference segment


HINGE_JOINTS: tuple[HingeJoint, ...] = (
    HingeJoint("elbow_r", 4, 5),
    HingeJoint("elbow_l", 10, 11),
    HingeJoint("knee_r", 0, 2),
    HingeJoint("knee_l", 12, 14),
)
BALL_JOINTS: tuple[BallJoint, ...] = (
    BallJoint("shoulder_r", 4, 15),
    BallJoint("shoulder_l", 10, 16),
    BallJoint("hip_r", 0, 6),
    BallJoint("hip_l", 12, 6),
    BallJoint("ankle_r", 1, 2),
    BallJoint("ankle_l", 13, 14),
    BallJoint("torso", 8, 6),
    BallJoint("head", 17, 7),
)
BALL_COMPONENTS = ("abduction", "flexion", "rotation")  # roll, pitch, yaw (Table 3.1)

#: Column names of :func:`joint_angles`, in order (defined in :mod:`bpms.io.names`, which the
#: file readers use; the joint tables here must give the same names).
assert (
    *(f"{j.name}.flexion" for j in HINGE_JOINTS),
    *(f"{j.name}.{c}" for j in BALL_JOINTS for c in BALL_COMPONENTS),
) == JOINT_ANGLE_NAMES, "bpms.io.names.JOINT_ANGLE_NAMES disagrees with the joint tables"


_HINGE_PROXIMAL = np.array([j.proximal for j in HINGE_JOINTS])
_HINGE_DISTAL = np.array([j.distal for j in HINGE_JOINTS])
_HINGE_AXIS_P = np.array([SEGMENT_AXIS[j.proximal] for j in HINGE_JOINTS])
_HINGE_AXIS_D = np.array([SEGMENT_AXIS[j.distal] for j in HINGE_JOINTS])
_BALL_STATIC = np.array([j.static for j in BALL_JOINTS])
_BALL_DYNAMIC = np.array([j.dynamic for j in BALL_JOINTS])


def joint_angles(C: np.ndarray) -> np.ndarray:
    """Joint angles ``[..., 28]`` in radians, order :data:`JOINT_ANGLE_NAMES`, from calibrated
    segment orientations ``C[..., 18, 3, 3]``."""
    C = np.asarray(C, dtype=np.float64)
    u = np.einsum("...jab,jb->...ja", C[..., _HINGE_PROXIMAL, :, :], _HINGE_AXIS_P)
    v = np.einsum("...jab,jb->...ja", C[..., _HINGE_DISTAL, :, :], _HINGE_AXIS_D)
    cos = np.sum(u * v, axis=-1) / np.sqrt(np.sum(u * u, axis=-1) * np.sum(v * v, axis=-1))
    flexion = np.arccos(np.clip(cos, -1.0, 1.0))
    rel = np.swapaxes(C[..., _BALL_STATIC, :, :], -1, -2) @ C[..., _BALL_DYNAMIC, :, :]
    ball = dcm_to_euler(rel).reshape(*C.shape[:-3], 3 * len(BALL_JOINTS))
    return np.concatenate([flexion, ball], axis=-1)
