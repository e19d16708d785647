"""Stick-figure geometry shared by the Qt 3D windows and the vpython views (no Qt, no GL).

Display frame: the body model works in world NED (x north, y east, z down, metres, lowest foot
on z = 0). 3D views want z up, so every point is drawn as ``(x, -y, -z)``: display x = north,
display y = west, display z = up, a 180° rotation about north (the frame stays right-handed).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bpms.filter.body_model import BODY_POINTS, POINT_INDEX, SEGMENTS, joint_positions
from bpms.io.options import BodyOptions

#: NED → display (z up): x stays, y and z flip.
NED_TO_DISPLAY = np.diag([1.0, -1.0, -1.0])

RIGHT_COLOUR = (0.15, 0.85, 0.15, 1.0)
LEFT_COLOUR = (0.95, 0.2, 0.2, 1.0)
CENTRE_COLOUR = (0.35, 0.65, 1.0, 1.0)
JOINT_COLOUR = (1.0, 0.85, 0.2, 1.0)
AXIS_COLOURS = ((1.0, 0.0, 0.0, 1.0), (0.0, 1.0, 0.0, 1.0), (0.0, 0.0, 1.0, 1.0))
AXIS_LENGTH_M = 0.12


def _segment_colour(child: str) -> tuple[float, float, float, float]:
    if child.endswith("_r"):
        return RIGHT_COLOUR
    if child.endswith("_l"):
        return LEFT_COLOUR
    return CENTRE_COLOUR


#: Per segment: start and end point index (POINT_NAMES order) and RGBA colour.
SEG_START = np.array([POINT_INDEX[a] for a, _, _ in SEGMENTS])
SEG_END = np.array([POINT_INDEX[b] for _, b, _ in SEGMENTS])
SEG_COLOURS = np.array([_segment_colour(b) for _, b, _ in SEGMENTS])
#: Each IMU's triad sits at the mid-point of the first segment it drives.
_IMU_SEGMENT: dict[int, int] = {}
for _k, _p in enumerate(BODY_POINTS):
    _IMU_SEGMENT.setdefault(_p.imu, _k)
#: IMU ids with a triad, and the segment each one sits on.
AXIS_IMUS = np.array(sorted(_IMU_SEGMENT))
AXIS_SEGMENTS = np.array([_IMU_SEGMENT[i] for i in AXIS_IMUS])
#: The calibration pose (every segment aligned with the body), shown grey before Reset Zero.
CALIBRATION_POSE = joint_positions(np.broadcast_to(np.eye(3), (18, 3, 3)))


def calibration_pose(body: BodyOptions | None = None) -> np.ndarray:
    """``[21, 3]`` NED metres: the calibration pose with the segment lengths ``body`` (a
    sample's :attr:`~bpms.pipeline.sample.PoseSample.body`: the subject's, docs/subject.md;
    None: the factory's, :data:`CALIBRATION_POSE`)."""
    if body is None:
        return CALIBRATION_POSE
    return joint_positions(np.broadcast_to(np.eye(3), (18, 3, 3)), body)


def pose_points(sample: Any, aligned: bool = True) -> np.ndarray | None:
    """``[21, 3]`` NED metres the 3D views draw for ``sample`` (a PoseSample; None: nothing
    yet): its joint positions after Reset Zero (``aligned``), else the figure of the filter
    DCMs as they are (the ``v`` key), with the same segment lengths, the sample's own."""
    if sample is None:
        return None
    if aligned:
        return sample.joint_positions
    return joint_positions(np.asarray(sample.R), getattr(sample, "body", None))


def to_display(points_ned: np.ndarray) -> np.ndarray:
    """``[..., 3]`` NED metres → display metres (x north, y west, z up)."""
    return np.asarray(points_ned, dtype=np.float64) @ NED_TO_DISPLAY


def figure_lines(points: np.ndarray, colours: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Line-segment vertices ``[2M, 3]`` and colours ``[2M, 4]`` for the stick figure.

    points: ``[21, 3]`` display metres; segments with a non-finite end are left out.
    colours: one RGBA per segment (default: left/right/centre colours).
    """
    colours = SEG_COLOURS if colours is None else colours
    a, b = points[SEG_START], points[SEG_END]
    ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    pos = np.stack([a[ok], b[ok]], axis=1).reshape(-1, 3)
    col = np.repeat(colours[ok], 2, axis=0)
    return pos, col


def imu_axes_lines(points: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """RGB triads ``[2K, 3]`` / ``[2K, 4]`` at each IMU's segment mid-point.

    points: ``[21, 3]`` display metres; C: ``[18, 3, 3]`` segment → NED orientations.
    """
    mid = 0.5 * (points[SEG_START[AXIS_SEGMENTS]] + points[SEG_END[AXIS_SEGMENTS]])
    # Column k of C is the segment's k-th axis in NED; rows after the transpose.
    axes = np.swapaxes(C[AXIS_IMUS], 1, 2) @ NED_TO_DISPLAY * AXIS_LENGTH_M  # [K, 3, 3]
    starts = np.repeat(mid[:, None, :], 3, axis=1)
    ends = starts + axes
    ok = (np.isfinite(starts).all(axis=2) & np.isfinite(ends).all(axis=2)).reshape(-1)
    pos = np.stack([starts, ends], axis=2).reshape(-1, 2, 3)[ok].reshape(-1, 3)
    col = np.tile(np.array(AXIS_COLOURS), (len(AXIS_IMUS), 1))[ok]
    return pos, np.repeat(col, 2, axis=0)


def camera_axes(elevation_deg: float, azimuth_deg: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors (towards the camera, screen right, screen up) in display axes for a
    camera at ``elevation`` above the ground plane and ``azimuth`` about display z, as
    pyqtgraph's GLViewWidget places it (camera = centre + distance × the first vector)."""
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    back = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    right = np.array([-np.sin(az), np.cos(az), 0.0])
    up = np.array([-np.sin(el) * np.cos(az), -np.sin(el) * np.sin(az), np.cos(el)])
    return back, right, up


#: Framing: room left around the figure (capsule radii, head), metres, and the share of the
#: view the figure may fill.
FRAME_PAD_M = 0.12
FRAME_FILL = 0.92


_ARMS = tuple(tuple(POINT_INDEX[f"{joint}_{side}"]
                    for joint in ("shoulder", "elbow", "wrist", "fingers")) for side in "rl")
_REACH = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], np.float64)


def reach_points(points: np.ndarray) -> np.ndarray:
    """``points [21, 3]`` (display metres) and, around each shoulder, where the hand can reach
    (forward, back, both sides, up: one arm's length away), so that a view framed on them
    keeps the whole body in the picture when the arms are raised."""
    pts = np.asarray(points, np.float64)
    extra = []
    for shoulder, elbow, wrist, fingers in _ARMS:
        chain = pts[[shoulder, elbow, wrist, fingers]]
        if not np.isfinite(chain).all():
            continue
        length = float(np.linalg.norm(np.diff(chain, axis=0), axis=1).sum())
        extra.append(chain[0] + length * _REACH)
    return np.concatenate([pts, *extra]) if extra else pts


def frame_camera(points: np.ndarray, elevation_deg: float, azimuth_deg: float,
                 fov_deg: float, aspect: float) -> tuple[np.ndarray, float]:
    """(centre, distance) of a camera looking from ``elevation``/``azimuth`` that shows every
    point of ``points [N, 3]`` (display metres; non-finite rows ignored), padded by
    :data:`FRAME_PAD_M`, within :data:`FRAME_FILL` of the view. ``fov_deg`` is the horizontal
    field of view (pyqtgraph's ``fov``); ``aspect`` width / height of the view in pixels."""
    pts = np.asarray(points, np.float64)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) == 0:
        pts = CALIBRATION_POSE @ NED_TO_DISPLAY
    centre = (pts.min(axis=0) + pts.max(axis=0)) / 2.0
    back, right, up = camera_axes(elevation_deg, azimuth_deg)
    q = pts - centre
    depth = q @ back  # towards the camera
    half_h = np.tan(np.radians(fov_deg) / 2.0) * FRAME_FILL
    half_v = half_h / max(aspect, 1e-6)
    need = np.maximum(depth + (np.abs(q @ right) + FRAME_PAD_M) / half_h,
                      depth + (np.abs(q @ up) + FRAME_PAD_M) / half_v)
    return centre, float(need.max())
