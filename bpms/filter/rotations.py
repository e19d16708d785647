"""Rotation-matrix helpers in the filter's conventions (SPEC §5).

A DCM ``R`` maps body-frame vectors to the world frame (north-east-down): ``v_w = R v_b``.
Euler angles are roll φ (about X), pitch θ (about Y), yaw ψ (about Z), with
``R = Rz(ψ) Ry(θ) Rx(φ)``; all angles in radians.
"""

from __future__ import annotations

import numpy as np


def euler_to_dcm(roll: np.ndarray | float, pitch: np.ndarray | float,
                 yaw: np.ndarray | float) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)``, shape ``[..., 3, 3]`` (SPEC §5 initialisation matrix)."""
    roll, pitch, yaw = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64)
                                             for v in (roll, pitch, yaw)))
    c1, s1 = np.cos(roll), np.sin(roll)
    c2, s2 = np.cos(pitch), np.sin(pitch)
    c3, s3 = np.cos(yaw), np.sin(yaw)
    out = np.empty((*roll.shape, 3, 3))
    out[..., 0, 0] = c2 * c3
    out[..., 0, 1] = c3 * s1 * s2 - c1 * s3
    out[..., 0, 2] = s1 * s3 + c1 * c3 * s2
    out[..., 1, 0] = c2 * s3
    out[..., 1, 1] = c1 * c3 + s1 * s2 * s3
    out[..., 1, 2] = c1 * s2 * s3 - c3 * s1
    out[..., 2, 0] = -s2
    out[..., 2, 1] = c2 * s1
    out[..., 2, 2] = c1 * c2
    return out


def dcm_to_euler(R: np.ndarray) -> np.ndarray:
    """``[..., 3, 3]`` → ``[..., 3]`` (roll, pitch, yaw) in radians (SPEC §5 step 5)."""
    R = np.asarray(R, dtype=np.float64)
    pitch = -np.arcsin(np.clip(R[..., 2, 0], -1.0, 1.0))
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def rot_x(angle: float) -> np.ndarray:
    """Rotation about X by ``angle`` rad."""
    return euler_to_dcm(angle, 0.0, 0.0)


def rot_y(angle: float) -> np.ndarray:
    """Rotation about Y by ``angle`` rad."""
    return euler_to_dcm(0.0, angle, 0.0)


def rot_z(angle: float) -> np.ndarray:
    """Rotation about Z by ``angle`` rad."""
    return euler_to_dcm(0.0, 0.0, angle)


def dcm_to_quaternion(R: np.ndarray) -> np.ndarray:
    """``[..., 3, 3]`` → unit quaternions ``[..., 4]`` (w, x, y, z), w ≥ 0."""
    R = np.asarray(R, dtype=np.float64)
    m = R
    t = np.stack([
        1 + m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2],
        1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2],
        1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2],
        1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2],
    ], axis=-1)
    k = np.argmax(t, axis=-1)
    s = np.sqrt(np.maximum(np.take_along_axis(t, k[..., None], -1)[..., 0], 1e-300)) * 2
    cand = np.stack([
        np.stack([s / 4, (m[..., 2, 1] - m[..., 1, 2]) / s, (m[..., 0, 2] - m[..., 2, 0]) / s,
                  (m[..., 1, 0] - m[..., 0, 1]) / s], -1),
        np.stack([(m[..., 2, 1] - m[..., 1, 2]) / s, s / 4, (m[..., 0, 1] + m[..., 1, 0]) / s,
                  (m[..., 0, 2] + m[..., 2, 0]) / s], -1),
        np.stack([(m[..., 0, 2] - m[..., 2, 0]) / s, (m[..., 0, 1] + m[..., 1, 0]) / s, s / 4,
                  (m[..., 1, 2] + m[..., 2, 1]) / s], -1),
        np.stack([(m[..., 1, 0] - m[..., 0, 1]) / s, (m[..., 0, 2] + m[..., 2, 0]) / s,
                  (m[..., 1, 2] + m[..., 2, 1]) / s, s / 4], -1),
    ], axis=-2)
    q = np.take_along_axis(cand, k[..., None, None], -2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def quaternion_to_dcm(q: np.ndarray) -> np.ndarray:
    """Unit quaternions ``[..., 4]`` (w, x, y, z) → ``[..., 3, 3]``."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)
