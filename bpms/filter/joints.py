"""Joint angles (dissertation chapter 3.1; docs/joint-angles.md has the table).

- Elbow and knee flexion: the angle between the two segments' long axes (eq. 3.8), radians,
  0 in the calibration pose.
- Multi-DOF joints: ``R = C_static^T C_dynamic`` of the two calibrated segment orientations,
  then roll (about the static segment's forward X), pitch (about its right Y) and yaw (about its
  downward Z) with ``R = Rz(yaw) Ry(pitch) Rx(roll)``, named as Table 3.1: roll =
  adduction/abduction, pitch = flexion/extension, yaw = rotation.

Conventions (:data:`CONVENTIONS`, option ``joints.convention``):

- ``"isb"`` (default): the clinical/ISB sense, the same on both sides: flexion, abduction and
  external rotation positive; for the midline joints (torso, head) forward flexion, lateral
  bending to the right and axial rotation to the left positive (the right-hand rule about the
  upward axis, as ISB's and OpenSim's ``lumbar_rotation``).
- ``"original"``: the raw roll/pitch/yaw of the original software, which mirror between left and
  right (a sideways raise reads −80° abduction on the right, +80° on the left).
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


# The joint tables as arrays: IMU pairs; each hinge segment's axis as (axis, sign), every one a
# segment axis.
_HINGE = np.array([(j.proximal, j.distal) for j in HINGE_JOINTS], dtype=np.int64)
_HINGE_AXES = np.array([(SEGMENT_AXIS[j.proximal], SEGMENT_AXIS[j.distal])
                        for j in HINGE_JOINTS], dtype=np.float64)
assert (np.abs(_HINGE_AXES).sum(axis=-1) == 1).all(), "hinge axes must be segment axes"
_HINGE_AXIS = np.abs(_HINGE_AXES).argmax(axis=-1)
_HINGE_SIGN = np.take_along_axis(_HINGE_AXES, _HINGE_AXIS[..., None], -1)[..., 0]
_BALL = np.array([(j.static, j.dynamic) for j in BALL_JOINTS], dtype=np.int64)


CONVENTIONS = ("isb", "original")
DEFAULT_CONVENTION = "isb"
#: Human-readable one-liners, written into every output's header/metadata.
CONVENTION_TEXT = {
    "isb": "isb (flexion, abduction, external rotation positive on both sides; "
           "docs/joint-angles.md)",
    "original": "original (raw roll/pitch/yaw of R_static^T R_dynamic; left/right mirrored; "
                "docs/joint-angles.md)",
}


def _isb_signs() -> np.ndarray:
    """Per-column factor from the original's raw angles to the ISB convention."""
    signs = {
        # (abduction, flexion, rotation) factors applied to (roll, pitch, yaw)
        "r": (-1.0, 1.0, 1.0),   # right: abduction = -roll, external rotation = +yaw
        "l": (1.0, 1.0, -1.0),   # left: abduction = +roll, external rotation = -yaw
        # midline: the segment points up, so forward flexion = -pitch; bending right = +roll;
        # rotation to the left = -yaw (right-hand rule about the upward axis)
        "m": (1.0, -1.0, -1.0),
    }
    out = [1.0] * len(HINGE_JOINTS)
    for j in BALL_JOINTS:
        side = j.name[-1] if j.name[-2:] in ("_r", "_l") else "m"
        out.extend(signs[side])
    return np.array(out)


#: ISB value = ``ISB_SIGNS * original value``, column by column (the conversion is a pure sign
#: change because both read the same Euler decomposition).
ISB_SIGNS = _isb_signs()
_ORIGINAL_SIGNS = np.ones_like(ISB_SIGNS)


def check_convention(convention: str) -> str:
    """``convention`` if known, else ValueError naming the choices."""
    if convention not in CONVENTIONS:
        raise ValueError(f"joint-angle convention must be one of {', '.join(CONVENTIONS)}, "
                         f"not {convention!r}")
    return convention


def convert(angles: np.ndarray, source: str, target: str) -> np.ndarray:
    """Joint angles ``[..., 28]`` in convention ``source`` → ``target`` (a sign change)."""
    check_convention(source)
    check_convention(target)
    angles = np.asarray(angles, dtype=np.float64)
    return angles if source == target else angles * ISB_SIGNS


def joint_angles(C: np.ndarray, convention: str = DEFAULT_CONVENTION) -> np.ndarray:
    """Joint angles ``[..., 28]`` in radians, order :data:`JOINT_ANGLE_NAMES`, from calibrated
    segment orientations ``C[..., 18, 3, 3]``, in ``convention`` (:data:`CONVENTIONS`).

    Hinge flexion = ``acos`` of the cosine between the two segments' axes (clipped to
    [−1, 1]); ball joints: the Euler angles of ``C_staticᵀ C_dynamic``. NaN where an
    orientation involved is NaN."""
    signs = ISB_SIGNS if check_convention(convention) == "isb" else _ORIGINAL_SIGNS
    C = np.asarray(C, dtype=np.float64)
    # each segment's axis in the world: a column of C (a row of Cᵀ), both of a hinge at once
    axes = np.swapaxes(C, -1, -2)[..., _HINGE, _HINGE_AXIS, :] * _HINGE_SIGN[:, :, None]
    u, v = axes[..., 0, :], axes[..., 1, :]
    cosine = (u * v).sum(axis=-1) / np.sqrt((u * u).sum(axis=-1) * (v * v).sum(axis=-1))
    flexion = np.arccos(np.clip(cosine, -1.0, 1.0))
    relative = np.swapaxes(C[..., _BALL[:, 0], :, :], -1, -2) @ C[..., _BALL[:, 1], :, :]
    ball = dcm_to_euler(relative).reshape(*C.shape[:-3], 3 * len(_BALL))
    return np.concatenate([flexion, ball], axis=-1) * signs


#: OpenSim coordinate (Rajagopal 2016 / gait2392 / Hamner names) → (BPMS ISB column, factor):
#: ``coordinate = factor * column``. Approximate where OpenSim's joint uses another Euler
#: sequence (the shoulder) — the signs are what this table states exactly.
OPENSIM_COORDINATES: dict[str, tuple[str, float]] = {
    **{name: item for side in "rl" for name, item in {
        f"hip_flexion_{side}": (f"hip_{side}.flexion", 1.0),
        f"hip_adduction_{side}": (f"hip_{side}.abduction", -1.0),
        f"hip_rotation_{side}": (f"hip_{side}.rotation", -1.0),  # internal rotation positive
        f"knee_angle_{side}": (f"knee_{side}.flexion", 1.0),  # Rajagopal; gait2392: -1
        f"ankle_angle_{side}": (f"ankle_{side}.flexion", 1.0),  # dorsiflexion positive
        f"arm_flex_{side}": (f"shoulder_{side}.flexion", 1.0),
        f"arm_add_{side}": (f"shoulder_{side}.abduction", -1.0),
        f"arm_rot_{side}": (f"shoulder_{side}.rotation", -1.0),  # internal rotation positive
        f"elbow_flex_{side}": (f"elbow_{side}.flexion", 1.0),
    }.items()},
    "lumbar_extension": ("torso.flexion", -1.0),
    "lumbar_bending": ("torso.abduction", 1.0),
    "lumbar_rotation": ("torso.rotation", 1.0),
}


def opensim_coordinates(angles: np.ndarray, convention: str = DEFAULT_CONVENTION,
                        ) -> dict[str, np.ndarray]:
    """OpenSim coordinate values (rad) from joint angles ``[..., 28]`` in ``convention``."""
    isb = convert(angles, convention, "isb")
    index = {name: k for k, name in enumerate(JOINT_ANGLE_NAMES)}
    return {coord: factor * isb[..., index[col]]
            for coord, (col, factor) in OPENSIM_COORDINATES.items()}
