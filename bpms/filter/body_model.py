"""The stick-figure body model (docs/body-model.md, appendix C).

Segment orientations ``C[18, 3, 3]`` map segment axes to the world frame (north-east-down).
A segment's axes coincide with the body's (X forward, Y right, Z down) in the calibration
pose: standing upright, arms straight down at the sides, feet forward. After Reset Zero,
``C_i = R_i R0_i^T Rz(ψ_hip)``, so the whole figure faces the hip IMU's magnetic heading.

Joint positions come from walking the chain below from the pelvis (the root, where the low
spine meets the hips), each point = parent point + ``C[imu] @ direction * length``. The figure
is then lifted so that its lowest foot point sits on the ground (z = 0, z down).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bpms.io.options import BodyOptions

UP = (0.0, 0.0, -1.0)
DOWN = (0.0, 0.0, 1.0)
RIGHT = (0.0, 1.0, 0.0)
LEFT = (0.0, -1.0, 0.0)
FORWARD = (1.0, 0.0, 0.0)


@dataclass(frozen=True)
class BodyPoint:
    """A joint or end point: ``parent + C[imu] @ direction * length``."""

    name: str
    parent: str
    imu: int
    direction: tuple[float, float, float]
    length: str  # attribute of BodyOptions


#: The chain, parents before children. "pelvis" is the root at the origin.
BODY_POINTS: tuple[BodyPoint, ...] = (
    BodyPoint("spine_mid", "pelvis", 6, UP, "low_spine"),
    BodyPoint("neck_base", "spine_mid", 8, UP, "mid_spine"),
    BodyPoint("head_base", "neck_base", 7, UP, "neck"),
    BodyPoint("head_top", "head_base", 17, UP, "head"),
    BodyPoint("shoulder_r", "neck_base", 15, RIGHT, "shoulder"),
    BodyPoint("elbow_r", "shoulder_r", 4, DOWN, "arm"),
    BodyPoint("wrist_r", "elbow_r", 5, DOWN, "forearm"),
    BodyPoint("fingers_r", "wrist_r", 3, DOWN, "hand"),
    BodyPoint("shoulder_l", "neck_base", 16, LEFT, "shoulder"),
    BodyPoint("elbow_l", "shoulder_l", 10, DOWN, "arm"),
    BodyPoint("wrist_l", "elbow_l", 11, DOWN, "forearm"),
    BodyPoint("fingers_l", "wrist_l", 9, DOWN, "hand"),
    BodyPoint("hip_r", "pelvis", 6, RIGHT, "hip"),
    BodyPoint("knee_r", "hip_r", 0, DOWN, "thigh"),
    BodyPoint("ankle_r", "knee_r", 2, DOWN, "shank"),
    BodyPoint("toe_r", "ankle_r", 1, FORWARD, "foot"),
    BodyPoint("hip_l", "pelvis", 6, LEFT, "hip"),
    BodyPoint("knee_l", "hip_l", 12, DOWN, "thigh"),
    BodyPoint("ankle_l", "knee_l", 14, DOWN, "shank"),
    BodyPoint("toe_l", "ankle_l", 13, FORWARD, "foot"),
)
POINT_NAMES: tuple[str, ...] = ("pelvis", *(p.name for p in BODY_POINTS))
POINT_INDEX = {name: i for i, name in enumerate(POINT_NAMES)}
#: Segments to draw, as (start point, end point, imu id).
SEGMENTS: tuple[tuple[str, str, int], ...] = tuple((p.parent, p.name, p.imu) for p in BODY_POINTS)
FOOT_POINTS = ("ankle_r", "toe_r", "ankle_l", "toe_l")

#: Each IMU's segment vector in segment axes (the limb's long axis, or sideways for
#: shoulders and the hip), used for flexion angles and the IMU's place on the figure.
SEGMENT_AXIS: dict[int, tuple[float, float, float]] = {}
for _p in BODY_POINTS:
    SEGMENT_AXIS.setdefault(_p.imu, _p.direction)


# The chain as arrays: each point's IMU; its direction in segment axes as (axis, sign) — every
# direction is a segment axis; which segments lie on the way from the pelvis to each point;
# the foot points.
_POINT_IMUS = np.array([p.imu for p in BODY_POINTS], dtype=np.int64)
_DIRECTIONS = np.array([p.direction for p in BODY_POINTS], dtype=np.float64)
assert (np.abs(_DIRECTIONS).sum(axis=1) == 1).all(), "directions must be segment axes"
_AXIS = np.abs(_DIRECTIONS).argmax(axis=1)
_SIGN = _DIRECTIONS[np.arange(len(BODY_POINTS)), _AXIS]
_FOOT_INDEX = np.array([POINT_INDEX[n] for n in FOOT_POINTS], dtype=np.int64)


def _on_the_way() -> np.ndarray:
    """``[21, 20]``: 1 where segment p (ending at point p + 1) lies on the way from the pelvis to
    point q, so that point positions = this @ segment vectors."""
    way = np.zeros((len(POINT_NAMES), len(BODY_POINTS)))
    for p, point in enumerate(BODY_POINTS):
        q = p + 1
        way[q] = way[POINT_INDEX[point.parent]]
        way[q, p] = 1.0
    return way


_ON_THE_WAY = _on_the_way()


def segment_lengths(lengths: BodyOptions | None = None) -> np.ndarray:
    """``[20]`` m: the length of each segment of :data:`BODY_POINTS` (``Options.body``)."""
    lengths = lengths or BodyOptions()
    return np.array([float(getattr(lengths, p.length)) for p in BODY_POINTS])


def joint_positions(C: np.ndarray, lengths: BodyOptions | None = None,
                    on_ground: bool = True) -> np.ndarray:
    """Joint positions ``[..., 21, 3]`` (order :data:`POINT_NAMES`), metres, world NED axes:
    each point = its parent + ``C[imu] @ (direction × length)``, the pelvis at the origin.
    With ``on_ground`` the whole figure is shifted along z (down) so that the lowest foot
    point is at z = 0 (NaN when one of the foot points is). NaN below a NaN orientation."""
    C = np.asarray(C, dtype=np.float64)
    # C[imu] @ axis is a column of C: the rows of Cᵀ, picked for every segment at once
    columns = np.swapaxes(C, -1, -2)[..., _POINT_IMUS, _AXIS, :]
    segments = columns * (_SIGN * segment_lengths(lengths))[:, None]
    missing = np.isnan(segments).any(axis=-1)
    if missing.any():  # a NaN segment makes the points beyond it NaN, and no others
        segments = np.where(missing[..., None], 0.0, segments)
        out = _ON_THE_WAY @ segments
        out[(missing @ _ON_THE_WAY.T) > 0] = np.nan
    else:
        out = _ON_THE_WAY @ segments
    if on_ground:
        out[..., 2] -= out[..., _FOOT_INDEX, 2].max(axis=-1)[..., None]
    return out
