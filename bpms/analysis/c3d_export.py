"""C3D export (``bpms export c3d``), for Vicon Nexus, Visual3D, Mokka and OpenSim (via ezc3d).

What the file holds (docs/analysis.md, "C3D"):

- **Points: the 21 joint centres** of the body model (``Result.joint_positions``,
  :data:`bpms.filter.body_model.POINT_NAMES`), in **millimetres**, in a Z-up lab frame:
  ``X = north, Y = west, Z = up`` (the suite's north-east-down turned half a turn about north,
  ``P = diag(1, -1, -1)``), lowest foot on the floor, pelvis above the origin (the figure does
  not travel). Frames before the first Reset Zero are invalid points (residual -1).
- **Joint angles as Vicon writes its model outputs**: one 3-component "angle point" per joint
  (``knee_r_angles`` ...) listed in ``POINT:ANGLES`` with ``POINT:ANGLE_UNITS = deg``, as
  Plug-in Gait writes ``LKneeAngles``: X = flexion, Y = abduction, Z = rotation of the joint
  angles of :data:`bpms.filter.joints.JOINT_ANGLE_NAMES` in the convention in force (the
  hinges' Y and Z are 0: the body model's elbow and knee have one axis).
- **The whole body's centre of mass**, the last point (``centre_of_mass``, mm, the same
  frame; :mod:`bpms.filter.centre_of_mass`).
- ``POINT:RATE`` (50 Hz), ``POINT:UNITS`` (mm), ``POINT:LABELS`` and ``POINT:DESCRIPTIONS``;
  a ``BPMS`` group states the recording's UTC start, the joint-angle convention, the axes and
  the source file.

ezc3d (the ``c3d`` extra) writes the file; it holds the whole trial in memory while writing
(≈ 3 MB per minute of recording).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bpms.filter.body_model import POINT_NAMES
from bpms.filter.centre_of_mass import centre_of_mass
from bpms.io.closing import Closing
from bpms.io.names import BALL_NAMES, HINGE_NAMES, JOINT_ANGLE_NAMES

#: NED → the C3D lab frame (X north, Y west, Z up).
NED_TO_C3D = np.diag([1.0, -1.0, -1.0])
MM_PER_M = 1000.0
#: Joints in the order of their angle points.
ANGLE_JOINTS: tuple[str, ...] = (*HINGE_NAMES, *BALL_NAMES)
_J = {name: k for k, name in enumerate(JOINT_ANGLE_NAMES)}


COM_LABEL = "centre_of_mass"


def angle_label(joint: str) -> str:
    """The angle point of ``joint``: ``knee_r`` → ``knee_r_angles``."""
    return f"{joint}_angles"


def point_labels() -> list[str]:
    """Every point label in file order: the 21 joint centres, the 12 angle points, then the
    centre of mass."""
    return [*POINT_NAMES, *(angle_label(j) for j in ANGLE_JOINTS), COM_LABEL]


def angle_points(joint_angles: np.ndarray) -> np.ndarray:
    """``[N, 12, 3]`` degrees (X flexion, Y abduction, Z rotation) from ``[N, 28]`` rad."""
    deg = np.degrees(np.asarray(joint_angles, dtype=np.float64))
    out = np.zeros((len(deg), len(ANGLE_JOINTS), 3))
    for k, joint in enumerate(ANGLE_JOINTS):
        out[:, k, 0] = deg[:, _J[f"{joint}.flexion"]]
        if joint in BALL_NAMES:
            out[:, k, 1] = deg[:, _J[f"{joint}.abduction"]]
            out[:, k, 2] = deg[:, _J[f"{joint}.rotation"]]
        else:
            out[:, k, 1:] = np.where(np.isfinite(out[:, k, :1]), 0.0, np.nan)
    return out


class C3dWriter(Closing):
    """Collects chunks (:meth:`write`), writes the C3D at :meth:`close` (ezc3d).

    rate_hz: frames per second; meta: ``(key, value)`` pairs stated in the ``BPMS`` group
    (:meth:`bpms.analysis.stamp.Stamp.items`); convention: the joint angles' convention name."""

    def __init__(self, path: str | Path, rate_hz: float = 50.0,
                 meta: Sequence[tuple[str, str]] = (), source: str = "") -> None:
        from bpms.extras import require

        self._ezc3d = require("ezc3d")
        self.path = Path(path)
        self.rate_hz = float(rate_hz)
        self.meta = list(meta)
        self.source = source
        self.frames = 0
        self._positions: list[np.ndarray] = []
        self._angles: list[np.ndarray] = []
        self.path.write_bytes(b"")  # fail early (folder missing, no permission)

    def write(self, joint_positions: np.ndarray, joint_angles: np.ndarray) -> None:
        """``joint_positions[N, 21, 3]`` m NED and ``joint_angles[N, 28]`` rad."""
        positions = np.asarray(joint_positions, dtype=np.float64)
        positions = np.concatenate([positions, centre_of_mass(positions)[:, None]], axis=1)
        self._positions.append(positions @ NED_TO_C3D.T * MM_PER_M)
        self._angles.append(angle_points(joint_angles))
        self.frames += len(joint_positions)

    def close(self) -> None:
        ezc3d = self._ezc3d
        n = self.frames
        pos = np.concatenate([np.zeros((0, len(POINT_NAMES) + 1, 3)), *self._positions])
        ang = np.concatenate([np.zeros((0, len(ANGLE_JOINTS), 3)), *self._angles])
        xyz = np.concatenate([pos[:, :-1], ang, pos[:, -1:]], axis=1)  # [N, P, 3]
        labels = point_labels()
        points = np.ones((4, len(labels), n))
        points[:3] = np.transpose(xyz, (2, 1, 0))
        valid = np.isfinite(xyz).all(axis=-1).T  # [P, N]
        points[:3, ~valid] = np.nan
        c3d = ezc3d.c3d()
        p = c3d["parameters"]["POINT"]
        p["RATE"]["value"] = [self.rate_hz]
        p["UNITS"]["value"] = ["mm"]
        p["LABELS"]["value"] = labels
        p["DESCRIPTIONS"]["value"] = (
            [f"joint centre {name}, mm, X north Y west Z up" for name in POINT_NAMES]
            + [f"{joint} angles, deg: X flexion, Y abduction, Z rotation"
               for joint in ANGLE_JOINTS]
            + ["whole-body centre of mass, mm, X north Y west Z up"])
        c3d["data"]["points"] = points
        c3d["data"]["meta_points"]["residuals"] = np.where(valid, 0.0, -1.0)[None]
        c3d["data"]["meta_points"]["camera_masks"] = np.zeros((7, len(labels), n), dtype=bool)
        c3d.add_parameter("POINT", "ANGLES", [angle_label(j) for j in ANGLE_JOINTS])
        c3d.add_parameter("POINT", "ANGLE_UNITS", ["deg"])
        c3d.add_parameter("POINT", "X_SCREEN", ["+X"])
        c3d.add_parameter("POINT", "Y_SCREEN", ["+Z"])
        c3d.add_parameter("MANUFACTURER", "COMPANY", ["BPMS Suite"])
        c3d.add_parameter("MANUFACTURER", "SOFTWARE", ["bpms"])
        for key, value in [*self.meta, ("axes", "X north, Y west, Z up (NED turned 180 deg "
                                                "about north)"), ("source", self.source)]:
            c3d.add_parameter("BPMS", key.upper()[:32], [str(value)[:255] or "-"])
        c3d.write(str(self.path))
        self._positions.clear()
        self._angles.clear()
