"""Names shared by files and the filter: the 28 joint angles (order of every joint-angle array
and column), the text slugs, and the one scheme of column names every output uses. Kept here,
below ``bpms.filter``, so that file readers and writers need no filter import;
``bpms.filter.joints`` re-exports the joint-angle names.

**Column names** (docs/analysis.md, "Column names"): ``GROUP_ITEM_QUANTITY_UNIT``, lower case,
``_`` between words, where GROUP says what the item is:

- ``imu<N>_<imu>`` IMU N and the body segment it sits on (named after each other): the
  segment's orientation after Reset Zero (``imu0_right_leg_qw``, ``imu0_right_leg_roll_deg``),
  the IMU's own filter attitude (``sensor_``: ``imu0_right_leg_sensor_roll_deg``), its sensor
  channels (``imu0_right_leg_ax_counts``, ``imu0_right_leg_gz_rad_s``) and flags
  (``imu5_right_forearm_mag_disturbed``);
- ``joint_<joint>`` a joint angle, e.g. ``joint_knee_r_flexion_deg``;
- ``point_<point>`` a joint centre of the body model, e.g. ``point_pelvis_z_m``;

and ``time_s`` (s since the first frame), ``host_time_s``, ``utc``. The unit is the last word
(``deg``, ``rad``, ``m``, ``m_s2``, ``gauss``, ``rad_s``, ``counts``); unit-free quantities
(quaternion components, flags) have none, and where a format states the unit apart (an LSL
channel's ``unit``, the ``.mat`` file's ``units``) the name is used without it.
"""

from __future__ import annotations

import re

HINGE_NAMES = ("elbow_r", "elbow_l", "knee_r", "knee_l")
BALL_NAMES = ("shoulder_r", "shoulder_l", "hip_r", "hip_l", "ankle_r", "ankle_l", "torso", "head")
#: Components of a ball joint: roll, pitch, yaw of the distal segment relative to the proximal.
BALL_COMPONENTS = ("abduction", "flexion", "rotation")

#: The joint angles in order: 4 hinge flexions, then 8 ball joints × 3 components.
JOINT_ANGLE_NAMES: tuple[str, ...] = (
    *(f"{j}.flexion" for j in HINGE_NAMES),
    *(f"{j}.{c}" for j in BALL_NAMES for c in BALL_COMPONENTS),
)


def slug(text: str) -> str:
    """``"Right Leg"`` → ``"right_leg"``, ``"knee_r.flexion"`` → ``"knee_r_flexion"``."""
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")


def joint_column(name: str, unit: str | None = None) -> str:
    """``"knee_r.flexion"``, ``"deg"`` → ``"joint_knee_r_flexion_deg"``."""
    return _with_unit(f"joint_{slug(name)}", unit)


def imu_column(index: int, quantity: str, unit: str | None = None) -> str:
    """IMU ``index``'s own ``quantity``: ``0, "sensor_roll", "deg"`` →
    ``"imu0_right_leg_sensor_roll_deg"``."""
    from bpms.io.frames import IMU_NAMES

    return _with_unit(f"imu{index}_{slug(IMU_NAMES[index])}_{quantity}", unit)


def point_column(point: str, quantity: str, unit: str | None = None) -> str:
    """A body-model point: ``"pelvis", "z", "m"`` → ``"point_pelvis_z_m"``."""
    return _with_unit(f"point_{slug(point)}_{quantity}", unit)


def _with_unit(name: str, unit: str | None) -> str:
    return f"{name}_{unit}" if unit else name
