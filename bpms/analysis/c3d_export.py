"""C3D export (``bpms export c3d``), for Vicon Nexus, Visual3D, Mokka and OpenSim (via ezc3d).

What the file holds (docs/analysis.md, "C3D"):

- **Points: the 21 joint centres** of the body model (``Result.joint_positions``,
  :data:`bpms.filter.body_model.POINT_NAMES`), in **millimetres**, in a Z-up lab frame:
  ``X = north, Y = west, Z = up`` (the suite's north-east-down turned half a turn about north,
  ``P = diag(1, -1, -1)``), lowest foot on the floor, pelvis above the origin (the figure does
  not travel) unless the walked path is given (``--walk``). Frames before the first Reset Zero
  are invalid points (residual -1).
- **Joint angles as Vicon writes its model outputs**: one 3-component "angle point" per joint
  (``knee_r_angles`` ...) listed in ``POINT:ANGLES`` with ``POINT:ANGLE_UNITS = deg``, as
  Plug-in Gait writes ``LKneeAngles``: X = flexion, Y = abduction, Z = rotation of the joint
  angles of :data:`bpms.filter.joints.JOINT_ANGLE_NAMES` in the convention in force (the
  hinges' Y and Z are 0: the body model's elbow and knee have one axis).
- **Analog channels**: each IMU's calibrated accelerometer (m/s²), gyroscope (rad/s) and
  magnetometer (gauss), x, y, z in its board axes
  (:meth:`bpms.filter.calibration.SensorCalibration.physical_units`), one sample per frame;
  ``ANALOG:LABELS`` ``imu0_acc_x`` ..., ``ANALOG:UNITS``, ``ANALOG:DESCRIPTIONS`` name the
  IMU's segment. None for a filtered file (no raw sensors).
- **Events** (``EVENT`` group, times in s from the first frame as ``TIMES`` minutes/seconds
  pairs): ``Foot Strike`` with context ``Right``/``Left`` (the heel strikes of ``bpms
  track``), ``Reset Zero`` and the session's typed markers (``Marker``, the text in
  ``DESCRIPTIONS``), context ``General``. At most 255 (a C3D dimension is one byte): more
  are left out and the command says how many.
- **The whole body's centre of mass**, the last point (``centre_of_mass``, mm, the same
  frame; :mod:`bpms.filter.centre_of_mass`).
- ``POINT:RATE`` (50 Hz), ``POINT:UNITS`` (mm), ``POINT:LABELS`` and ``POINT:DESCRIPTIONS``;
  a ``BPMS`` group states where the file came from (:mod:`bpms.analysis.stamp`).

Written here (:mod:`bpms.analysis.c3d_format`), frame chunk by frame chunk: constant memory,
and any length (beyond 65,535 frames the count is in ``TRIAL:ACTUAL_END_FIELD``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bpms.analysis.c3d_format import BLOCK, C3dStream, encode_parameters
from bpms.filter.body_model import POINT_NAMES
from bpms.filter.centre_of_mass import centre_of_mass
from bpms.io.closing import Closing
from bpms.io.frames import IMU_NAMES
from bpms.io.names import BALL_NAMES, HINGE_NAMES, JOINT_ANGLE_NAMES

#: NED → the C3D lab frame (X north, Y west, Z up).
NED_TO_C3D = np.diag([1.0, -1.0, -1.0])
MM_PER_M = 1000.0
#: Joints in the order of their angle points.
ANGLE_JOINTS: tuple[str, ...] = (*HINGE_NAMES, *BALL_NAMES)
_J = {name: k for k, name in enumerate(JOINT_ANGLE_NAMES)}
#: The EVENT group's limit (one dimension of a C3D parameter is one byte) and text widths.
MAX_EVENTS = 255
LABEL_WIDTH, DESC_WIDTH = 32, 64
#: Per IMU, in this order: the analog channels' sensor, unit.
SENSORS = (("acc", "m/s^2", "accelerometer"), ("gyro", "rad/s", "gyroscope"),
           ("mag", "G", "magnetometer"))


def analog_labels() -> list[str]:
    """``imu0_acc_x`` ... ``imu17_mag_z``: per IMU its acc, gyro, mag x, y, z."""
    return [f"imu{i}_{s}_{a}" for i in range(len(IMU_NAMES)) for s, _, _ in SENSORS
            for a in "xyz"]


def analog_units() -> list[str]:
    return [u for _ in IMU_NAMES for _, u, _ in SENSORS for _ in "xyz"]


def analog_descriptions() -> list[str]:
    return [f"{name} {what} {a} (board axes)" for name in IMU_NAMES for _, _, what in SENSORS
            for a in "xyz"]


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
    """Writes the C3D chunk by chunk (:meth:`write`, :meth:`add_event`, then :meth:`close`).

    rate_hz: frames per second; meta: ``(key, value)`` pairs stated in the ``BPMS`` group
    (:func:`bpms.analysis.stamp.provenance`); analog: write the IMU channels (give ``imu``
    to :meth:`write`)."""

    def __init__(self, path: str | Path, rate_hz: float = 50.0,
                 meta: Sequence[tuple[str, str]] = (), source: str = "",
                 analog: bool = True) -> None:
        self.path = Path(path)
        self.rate_hz = float(rate_hz)
        self.meta = [*meta, *([("source", source)] if source else [])]
        self.analog = analog
        self.events: list[tuple[str, str, float, str]] = []
        worst = [("x" * LABEL_WIDTH, "General", 0.0, "x" * DESC_WIDTH)] * MAX_EVENTS
        need = 4 + len(encode_parameters(self._groups(worst))) + 512  # + the layout's entries
        self._stream = C3dStream(path, rate_hz, len(point_labels()),
                                 len(analog_labels()) if analog else 0, -(-need // BLOCK))

    @property
    def frames(self) -> int:
        return self._stream.frames

    def write(self, joint_positions: np.ndarray, joint_angles: np.ndarray,
              imu: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
              walked: np.ndarray | None = None) -> None:
        """``joint_positions[N, 21, 3]`` m NED, ``joint_angles[N, 28]`` rad; ``imu``: (acc
        m/s², mag gauss, gyro rad/s) each ``[N, 18, 3]``; ``walked[N, 3]`` m NED added to
        every joint centre (the walked path)."""
        pos = np.asarray(joint_positions, dtype=np.float64)
        if walked is not None:
            pos = pos + np.asarray(walked, dtype=np.float64)[:, None, :]
        com = centre_of_mass(pos)[:, None]  # of the same (walked) joint centres
        xyz = np.concatenate([pos @ NED_TO_C3D.T * MM_PER_M, angle_points(joint_angles),
                              com @ NED_TO_C3D.T * MM_PER_M], axis=1)
        channels = None
        if self.analog:
            if imu is None:
                raise ValueError("this C3D writes analog channels: give imu")
            acc, mag, gyr = imu
            channels = np.concatenate([acc, gyr, mag], axis=-1).reshape(len(pos), -1)
        self._stream.write(xyz, channels)

    def add_event(self, label: str, context: str, time_s: float, description: str) -> None:
        """One event: ``label`` (``Foot Strike``, ``Reset Zero``, ``Marker``), ``context``
        (``Right``, ``Left``, ``General``), ``time_s`` from the first frame."""
        self.events.append((label[:LABEL_WIDTH], context, float(time_s),
                            description[:DESC_WIDTH]))

    @property
    def dropped_events(self) -> int:
        """Events beyond the 255 a C3D EVENT group holds (left out, the latest first)."""
        return max(0, len(self.events) - MAX_EVENTS)

    def _groups(self, events: list[tuple[str, str, float, str]]) -> list:
        labels = point_labels()
        groups = [("POINT", "3-D point parameters", [
            ("UNITS", "mm", "joint centres"),
            ("LABELS", labels, "joint centres, then angle points"),
            ("DESCRIPTIONS",
             [f"joint centre {name}, mm, X north Y west Z up" for name in POINT_NAMES]
             + [f"{joint} angles, deg: X flexion, Y abduction, Z rotation"
                for joint in ANGLE_JOINTS]
             + ["whole-body centre of mass, mm, X north Y west Z up"], ""),
            ("ANGLES", [angle_label(j) for j in ANGLE_JOINTS], "angle points"),
            ("ANGLE_UNITS", "deg", ""),
            ("X_SCREEN", "+X", ""), ("Y_SCREEN", "+Z", "")])]
        n_analog = len(analog_labels()) if self.analog else 0
        analog: list = [("USED", n_analog, "analog channels"),
                        ("RATE", self.rate_hz, "samples per second"),
                        ("GEN_SCALE", 1.0, ""), ("FORMAT", "SIGNED", "")]
        if n_analog:
            analog += [("LABELS", analog_labels(), ""),
                       ("DESCRIPTIONS", analog_descriptions(), ""),
                       ("UNITS", analog_units(), ""),
                       ("SCALE", np.ones(n_analog, np.float32), ""),
                       ("OFFSET", np.zeros(n_analog, np.int16), "")]
        groups.append(("ANALOG", "IMU channels", analog))
        kept = sorted(events, key=lambda e: e[2])[:MAX_EVENTS]
        event: list = [("USED", len(kept), "events")]
        if kept:
            minutes = np.floor(np.array([e[2] for e in kept]) / 60.0)
            seconds = np.array([e[2] for e in kept]) - 60.0 * minutes
            event += [("CONTEXTS", [e[1] for e in kept], ""),
                      ("LABELS", [e[0] for e in kept], ""),
                      ("DESCRIPTIONS", [e[3] for e in kept], ""),
                      ("SUBJECTS", ["bpms"] * len(kept), ""),
                      ("TIMES", np.stack([minutes, seconds], axis=1).astype(np.float32),
                       "minutes, seconds from the first frame"),
                      ("ICON_IDS", np.zeros(len(kept), np.int16), ""),
                      ("GENERIC_FLAGS", np.zeros(len(kept), np.int16), "")]
        groups.append(("EVENT", "events", event))
        groups.append(("EVENT_CONTEXT", "event contexts", [
            ("USED", 3, ""), ("LABELS", ["General", "Right", "Left"], ""),
            ("DESCRIPTIONS", ["for either side", "right side", "left side"], ""),
            ("ICON_IDS", np.zeros(3, np.int16), "")]))
        groups.append(("MANUFACTURER", "writer", [("COMPANY", "BPMS Suite", ""),
                                                   ("SOFTWARE", "bpms", "")]))
        bpms = [(key.upper()[:32], str(value).replace("\n", " ")[:255] or "-", "")
                for key, value in [*self.meta, ("axes", "X north, Y west, Z up (NED turned "
                                                        "180 deg about north)")]]
        groups.append(("BPMS", "where this file came from", bpms))
        return groups

    def close(self) -> None:
        if self._stream._file.closed:
            return
        self._stream.finish(self._groups(self.events))


def recorded_markers(path: str | Path) -> list[tuple[int, str]]:
    """(frame, text) of the markers typed during the session, from a native raw recording's
    event records (one pass over its records, no frame decoded); none for other files."""
    from bpms.io.raw_layout import RawFileError
    from bpms.io.raw_reader import RawFile

    try:
        raw = RawFile(path)
        pieces = [p for p in raw.pieces() if p[0] == "event" and p[2].kind == "marker"]
    except (RawFileError, OSError):  # a legacy or filtered file: no event records
        return []
    return [(p[2].frame if p[2].frame >= 0 else p[1], str(p[2].data.get("text", "")))
            for p in pieces]
