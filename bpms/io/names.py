"""Names shared by files and the filter: the 28 joint angles (order of every joint-angle array
and column) and the text slugs used in column names. Kept here, below ``bpms.filter``, so that
file readers and writers need no filter import; ``bpms.filter.joints`` re-exports them."""

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
