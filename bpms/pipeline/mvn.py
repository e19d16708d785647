"""An MVN-compatible UDP stream (the Xsens "MVN real-time network streaming protocol").

Avatar plugins (Unity, Unreal, MotionBuilder) and research tools read this stream. BPMS sends
two datagram types per frame (docs/mvn.md has the mapping and the frames):

- ``MXTP02`` quaternion pose: 24-byte header, then per segment an int32 segment id (1-based,
  MVN's order) and 7 float32: position x, y, z (m, as MVN's manual states for this datagram) and
  orientation quaternion w, x, y, z;
  23 segments → 760 bytes.
- ``MXTP20`` joint angles: 24-byte header, then per joint a uint32 parent connection id and a
  uint32 child connection id (``256 * segment id + point id``) and 3 float32 rotations about
  x, y, z (degrees); 22 joints → 464 bytes.

The header (big-endian): 6 ASCII bytes ``MXTPnn``, uint32 sample counter, uint8 datagram
counter (0x80 set on the last datagram of a sample; BPMS sends each type in one datagram),
uint8 item count, uint32 time code (ms since the stream started), uint8 character id, uint8
body segment count, uint8 prop count, uint8 finger segment count, 2 reserved bytes, uint16
payload size (bytes after the header).

Frames: MVN's world is right-handed Z-up (x forward = magnetic north for BPMS, y left/west,
z up); BPMS's is north-east-down. The conversion ``P = diag(1, -1, -1)`` (a half turn about x)
gives ``p_mvn = P p_ned`` and ``C_mvn = P C P``, i.e. quaternion ``(w, x, -y, -z)``.
"""

from __future__ import annotations

import socket
import struct
from dataclasses import dataclass

import numpy as np

from bpms.filter.body_model import POINT_INDEX
from bpms.filter.joints import JOINT_ANGLE_NAMES

HEADER = struct.Struct(">6sIBBIBBBB2sH")
assert HEADER.size == 24
DEFAULT_PORT = 9763

#: MVN's 23 body segments, ids 1..23.
MVN_SEGMENTS: tuple[str, ...] = (
    "Pelvis", "L5", "L3", "T12", "T8", "Neck", "Head",
    "RightShoulder", "RightUpperArm", "RightForeArm", "RightHand",
    "LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand",
    "RightUpperLeg", "RightLowerLeg", "RightFoot", "RightToe",
    "LeftUpperLeg", "LeftLowerLeg", "LeftFoot", "LeftToe",
)


@dataclass(frozen=True)
class SegmentSource:
    """How an MVN segment is made from BPMS: orientation = slerp(IMU a, IMU b, f); origin =
    body point ``p`` + ``g`` × (point ``q`` − point ``p``)."""

    a: int
    b: int
    f: float
    p: str
    q: str
    g: float


def _s(imu: int, point: str) -> SegmentSource:
    return SegmentSource(imu, imu, 0.0, point, point, 0.0)


#: MVN segment (in :data:`MVN_SEGMENTS` order) ← BPMS IMU(s) and body points. The four lumbar
#: and thoracic segments interpolate between the hip IMU (6) and the spine IMU (8); the toes
#: repeat the foot IMU.
SEGMENT_SOURCES: tuple[SegmentSource, ...] = (
    _s(6, "pelvis"),
    SegmentSource(6, 8, 0.25, "pelvis", "spine_mid", 0.0),
    SegmentSource(6, 8, 0.5, "pelvis", "spine_mid", 0.5),
    SegmentSource(6, 8, 0.75, "spine_mid", "spine_mid", 0.0),
    SegmentSource(8, 8, 0.0, "spine_mid", "neck_base", 0.5),
    _s(7, "neck_base"), _s(17, "head_base"),
    _s(15, "neck_base"), _s(4, "shoulder_r"), _s(5, "elbow_r"), _s(3, "wrist_r"),
    _s(16, "neck_base"), _s(10, "shoulder_l"), _s(11, "elbow_l"), _s(9, "wrist_l"),
    _s(0, "hip_r"), _s(2, "knee_r"), _s(1, "ankle_r"), _s(1, "toe_r"),
    _s(12, "hip_l"), _s(14, "knee_l"), _s(13, "ankle_l"), _s(13, "toe_l"),
)

#: MVN joints (parent segment id, child segment id, BPMS joint or None → zeros).
MVN_JOINTS: tuple[tuple[int, int, str | None], ...] = (
    (1, 2, "torso"), (2, 3, None), (3, 4, None), (4, 5, None), (5, 6, None), (6, 7, "head"),
    (5, 8, None), (8, 9, "shoulder_r"), (9, 10, "elbow_r"), (10, 11, None),
    (5, 12, None), (12, 13, "shoulder_l"), (13, 14, "elbow_l"), (14, 15, None),
    (1, 16, "hip_r"), (16, 17, "knee_r"), (17, 18, "ankle_r"), (18, 19, None),
    (1, 20, "hip_l"), (20, 21, "knee_l"), (21, 22, "ankle_l"), (22, 23, None),
)
_J = {name: k for k, name in enumerate(JOINT_ANGLE_NAMES)}
_NED_TO_MVN = np.array([1.0, -1.0, -1.0])


def _joint_columns(joint: str | None) -> tuple[int, int, int] | None:
    """Indices of (x, y, z) = (abduction, rotation, flexion) in the ISB joint angles (hinges:
    flexion on z only)."""
    if joint is None:
        return None
    if f"{joint}.abduction" in _J:
        return _J[f"{joint}.abduction"], _J[f"{joint}.rotation"], _J[f"{joint}.flexion"]
    return -1, -1, _J[f"{joint}.flexion"]


def _slerp(qa: np.ndarray, qb: np.ndarray, f: float) -> np.ndarray:
    if f == 0.0:
        return qa
    if not (np.isfinite(qa).all() and np.isfinite(qb).all()):
        return np.full(4, np.nan)  # a segment without data: so is what it is made from
    dot = float(np.dot(qa, qb))
    if dot < 0:
        qb, dot = -qb, -dot
    if dot > 0.9995:
        q = qa + f * (qb - qa)
    else:
        th = np.arccos(dot)
        q = (np.sin((1 - f) * th) * qa + np.sin(f * th) * qb) / np.sin(th)
    return q / np.linalg.norm(q)


def mvn_pose(quaternions: np.ndarray, positions: np.ndarray,
             ) -> tuple[np.ndarray, np.ndarray]:
    """(positions ``[23, 3]`` m, quaternions ``[23, 4]`` w, x, y, z) in MVN's Z-up frame from
    BPMS segment quaternions ``[18, 4]`` (segment → NED) and joint positions ``[21, 3]`` m
    (NED, order ``POINT_NAMES``). NaN in, NaN out: an MVN segment made from a BPMS segment
    without data has NaN orientation (and position, when its points need it)."""
    pos = np.empty((len(SEGMENT_SOURCES), 3))
    quat = np.empty((len(SEGMENT_SOURCES), 4))
    for k, s in enumerate(SEGMENT_SOURCES):
        p, q = positions[POINT_INDEX[s.p]], positions[POINT_INDEX[s.q]]
        pos[k] = (p + s.g * (q - p)) * _NED_TO_MVN
        qq = _slerp(np.asarray(quaternions[s.a], float), np.asarray(quaternions[s.b], float), s.f)
        quat[k] = qq[0], qq[1], -qq[2], -qq[3]
    return pos, quat


def _header(kind: bytes, sample: int, items: int, time_ms: int, payload: int) -> bytes:
    return HEADER.pack(b"MXTP" + kind, sample & 0xFFFFFFFF, 0x80, items, time_ms & 0xFFFFFFFF,
                       0, len(MVN_SEGMENTS), 0, 0, b"\0\0", payload)


def pose_datagram(sample: int, time_ms: int, quaternions: np.ndarray,
                  positions: np.ndarray) -> bytes:
    """One ``MXTP02`` datagram (760 bytes); see :func:`mvn_pose` for the inputs."""
    pos, quat = mvn_pose(quaternions, positions)
    body = b"".join(struct.pack(">i7f", k + 1, *pos[k], *quat[k])
                    for k in range(len(MVN_SEGMENTS)))
    return _header(b"02", sample, len(MVN_SEGMENTS), time_ms, len(body)) + body


def joint_datagram(sample: int, time_ms: int, isb_angles: np.ndarray) -> bytes:
    """One ``MXTP20`` datagram (464 bytes) from BPMS joint angles ``[28]`` rad in the ISB
    convention (x = abduction, y = rotation, z = flexion, degrees; zeros where BPMS has no
    joint). Connection ids: parent ``256 * parent id + child id`` (the joint's point on the
    parent, numbered by the child), child ``256 * child id + 1`` (the child's origin)."""
    deg = np.degrees(np.asarray(isb_angles, dtype=np.float64))
    parts = []
    for parent, child, joint in MVN_JOINTS:
        cols = _joint_columns(joint)
        xyz = [0.0, 0.0, 0.0] if cols is None else [0.0 if c < 0 else deg[c] for c in cols]
        parts.append(struct.pack(">II3f", 256 * parent + child, 256 * child + 1, *xyz))
    body = b"".join(parts)
    return _header(b"20", sample, len(MVN_JOINTS), time_ms, len(body)) + body


class MvnSender:
    """Sends both datagram types to ``targets`` (``host:port``) over UDP, never blocking."""

    def __init__(self, targets: list[str]) -> None:
        self.targets = [_parse(t) for t in targets]
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.sent = 0
        self.errors = 0

    def send(self, sample: int, time_ms: int, quaternions: np.ndarray, positions: np.ndarray,
             isb_angles: np.ndarray) -> None:
        """One frame: segment quaternions ``[18, 4]``, joint positions ``[21, 3]`` m, joint
        angles ``[28]`` rad (ISB). Every frame is sent: what has no data (a failed IMU's
        segment, everything before the first Reset Zero) is NaN (docs/mvn.md)."""
        angles = np.asarray(isb_angles, dtype=np.float64)
        for data in (pose_datagram(sample, time_ms, quaternions, positions),
                     joint_datagram(sample, time_ms, angles)):
            for target in self.targets:
                try:
                    self.sock.sendto(data, target)
                    self.sent += 1
                except OSError:
                    self.errors += 1

    def close(self) -> None:
        self.sock.close()


def _parse(target: str) -> tuple[str, int]:
    host, _, port = target.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"'{target}' is not host:port")
    return host, int(port)
