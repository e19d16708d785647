"""BVH export of the stick figure (:mod:`bpms.filter.body_model`), for Blender and other
animation tools.

- One BVH joint per body-model segment, named after the segment (:func:`joint_name`:
  ``low_spine``, ``mid_spine``, ``neck``, ``head``, ``shoulder_r``, ``arm_r``, ``forearm_r``,
  ``hand_r``, ``hip_r``, ``thigh_r``, ``shank_r``, ``foot_r`` and the left side), placed at the
  segment's start point (``thigh_r`` at the hip joint); its rotation is the segment orientation
  ``C[imu]`` relative to its parent joint's. Leaf segments end in an ``End Site``. The
  root ``pelvis`` carries the pelvis position (``joint_positions``, lowest foot on the
  ground) and ``C[6]``.
- Axes: BVH/Blender's y-up frame, ``x = north (forward), y = up, z = east (right)`` — NED
  rotated +90° about X, the same as the OpenSim export. Offsets and positions in
  **centimetres** (Blender's BVH importer: scale 0.01 for metres).
- Channels: root ``Xposition Yposition Zposition Zrotation Xrotation Yrotation``, joints
  ``Zrotation Xrotation Yrotation`` (degrees, local ``R = Rz Rx Ry``).
- The rest pose is the calibration pose (every segment orientation = identity), with the
  per-subject lengths of ``Options.body``. Frames where the figure is not yet defined (before
  the first Reset Zero) are written in the rest pose.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bpms.analysis.textout import TextWriter, write_rows
from bpms.filter.body_model import BODY_POINTS
from bpms.io.options import BodyOptions

#: NED → BVH (x forward, y up, z right).
NED_TO_BVH = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
CM_PER_M = 100.0
ROOT_IMU = 6


def joint_name(k: int) -> str:
    """BVH joint name of body-model segment ``k`` (``BODY_POINTS[k]``)."""
    p = BODY_POINTS[k]
    side = p.name[-2:] if p.name[-2:] in ("_r", "_l") else ""
    return p.length + ("" if p.length.endswith(side) else side)


def zxy_angles(R: np.ndarray) -> np.ndarray:
    """``R[..., 3, 3] = Rz(z) Rx(x) Ry(y)`` → ``[..., 3]`` (z, x, y) in degrees."""
    x = np.arcsin(np.clip(R[..., 2, 1], -1.0, 1.0))
    y = np.arctan2(-R[..., 2, 0], R[..., 2, 2])
    z = np.arctan2(-R[..., 0, 1], R[..., 1, 1])
    return np.degrees(np.stack([z, x, y], axis=-1))


def hierarchy(body: BodyOptions | None = None) -> tuple[list[str], list[tuple[int, int]]]:
    """The HIERARCHY lines and the (imu of joint, imu of parent joint) order of the motion
    channels after the root's."""
    body = body or BodyOptions()
    children: dict[str, list[int]] = {}  # point name → indices of the segments starting there
    for k, p in enumerate(BODY_POINTS):
        children.setdefault(p.parent, []).append(k)
    lines: list[str] = ["HIERARCHY"]
    order: list[tuple[int, int]] = []

    def fmt(v: np.ndarray) -> str:
        return " ".join(f"{c:.6f}" for c in v)

    def emit(k: int, parent_imu: int, offset: np.ndarray, depth: int) -> None:
        p = BODY_POINTS[k]
        pad = "  " * depth
        lines.extend([f"{pad}JOINT {joint_name(k)}", f"{pad}{{", f"{pad}  OFFSET {fmt(offset)}",
                      f"{pad}  CHANNELS 3 Zrotation Xrotation Yrotation"])
        order.append((p.imu, parent_imu))
        vec = NED_TO_BVH @ np.array(p.direction) * getattr(body, p.length) * CM_PER_M
        kids = children.get(p.name, [])
        for c in kids:
            emit(c, p.imu, vec, depth + 1)
        if not kids:
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET {fmt(vec)}",
                          f"{pad}  }}"])
        lines.append(f"{pad}}}")

    lines += ["ROOT pelvis", "{", "  OFFSET 0.000000 0.000000 0.000000",
              "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]
    for k in children["pelvis"]:
        emit(k, ROOT_IMU, np.zeros(3), 1)
    lines.append("}")
    return lines, order


def motion_rows(C: np.ndarray, pelvis: np.ndarray, order: list[tuple[int, int]]) -> np.ndarray:
    """``[N, channels]`` motion values of ``C[N, 18, 3, 3]`` and ``pelvis[N, 3]`` (m, NED);
    frames without a figure (NaN) in the rest pose."""
    C = np.array(C, dtype=np.float64)
    bad = ~np.isfinite(C).all(axis=(-1, -2, -3))
    C[bad] = np.eye(3)
    pelvis = np.where(np.isfinite(pelvis), pelvis, 0.0)
    G = NED_TO_BVH @ C @ NED_TO_BVH.T  # global rotations in BVH axes
    columns = [(pelvis @ NED_TO_BVH.T) * CM_PER_M, zxy_angles(G[:, ROOT_IMU])]
    for imu, parent in order:
        local = np.swapaxes(G[:, parent], -1, -2) @ G[:, imu]
        columns.append(zxy_angles(local))
    return np.concatenate(columns, axis=1)


class BvhWriter(TextWriter):
    """A BVH file written block by block (constant memory): the frame count is patched in
    when the file is closed."""

    def __init__(self, path: str | Path, body: BodyOptions | None = None,
                 frame_time_s: float = 0.02) -> None:
        lines, self.order = hierarchy(body)
        super().__init__(path)
        self.frames = 0
        self._file.write("\n".join(lines) + "\nMOTION\n")
        self._reserve_count("Frames: ")
        self._file.write(f"\nFrame Time: {frame_time_s:.6f}\n")

    def write(self, C: np.ndarray, pelvis: np.ndarray) -> None:
        """Frames ``C[N, 18, 3, 3]`` (segment → NED) and ``pelvis[N, 3]`` (m, NED)."""
        if len(C):
            write_rows(self._file, motion_rows(C, pelvis, self.order), "%.5f", " ", "")
        self.frames += len(C)

    def close(self) -> None:
        if not self._file.closed:
            self._patch_count(self.frames)
        super().close()
