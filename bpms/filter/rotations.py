"""Rotation-matrix helpers in the filter's conventions (docs/filter.md).

A DCM ``R`` maps body-frame vectors to the world frame (north-east-down): ``v_w = R v_b``.
Euler angles are roll φ (about X), pitch θ (about Y), yaw ψ (about Z), with
``R = Rz(ψ) Ry(θ) Rx(φ)``; all angles in radians.
"""

from __future__ import annotations

import numpy as np


def euler_to_dcm(roll: np.ndarray | float, pitch: np.ndarray | float,
                 yaw: np.ndarray | float) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)``, shape ``[..., 3, 3]`` (docs/units.md)."""
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


def dcm_to_euler(R: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """``[..., 3, 3]`` → ``[..., 3]`` (roll, pitch, yaw) in radians (docs/filter.md step 5),
    into ``out`` when given."""
    R = np.asarray(R, dtype=np.float64)
    euler = np.empty(R.shape[:-1]) if out is None else out
    np.arctan2(R[..., 2, 1], R[..., 2, 2], out=euler[..., 0])
    np.arcsin(np.clip(R[..., 2, 0], -1.0, 1.0), out=euler[..., 1])
    np.negative(euler[..., 1], out=euler[..., 1])
    np.arctan2(R[..., 1, 0], R[..., 0, 0], out=euler[..., 2])
    return euler


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
    """``[..., 3, 3]`` → unit quaternions ``[..., 4]`` (w, x, y, z), w ≥ 0.

    Shepperd's method: the largest of ``4w², 4x², 4y², 4z²`` (from the trace and the diagonal)
    gives one component accurately; the other three come from sums and differences of the
    off-diagonal pairs divided by it. Exact at 180° (w = 0), where the sign-from-differences
    shortcut cannot tell the axis components' relative signs.
    """
    R = np.asarray(R, dtype=np.float64)
    d0, d1, d2 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    s21, s12 = R[..., 2, 1], R[..., 1, 2]
    s02, s20 = R[..., 0, 2], R[..., 2, 0]
    s10, s01 = R[..., 1, 0], R[..., 0, 1]
    four = np.stack([1 + d0 + d1 + d2, 1 + d0 - d1 - d2, 1 - d0 + d1 - d2,
                     1 - d0 - d1 + d2], -1)  # 4w², 4x², 4y², 4z²
    pick = np.argmax(four, axis=-1)
    # Each row: 4·q·q_pick for (w, x, y, z) given the picked component.
    cand = np.stack([
        np.stack([four[..., 0], s21 - s12, s02 - s20, s10 - s01], -1),  # w largest
        np.stack([s21 - s12, four[..., 1], s01 + s10, s02 + s20], -1),  # x largest
        np.stack([s02 - s20, s01 + s10, four[..., 2], s12 + s21], -1),  # y largest
        np.stack([s10 - s01, s02 + s20, s12 + s21, four[..., 3]], -1),  # z largest
    ], -2)
    q = np.take_along_axis(cand, pick[..., None, None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def finite_dcm_to_quaternion(R: np.ndarray) -> np.ndarray:
    """:func:`dcm_to_quaternion` where ``R[..., 3, 3]`` is finite; NaN ``[4]`` where a matrix
    holds NaN (a segment or IMU without data)."""
    R = np.asarray(R, dtype=np.float64)
    ok = np.isfinite(R).all(axis=(-1, -2))
    out = np.full((*R.shape[:-2], 4), np.nan)
    if ok.any():
        out[ok] = dcm_to_quaternion(R[ok])
    return out


def quaternion_to_dcm(q: np.ndarray) -> np.ndarray:
    """Quaternions ``[..., 4]`` (w, x, y, z; normalised here) → ``[..., 3, 3]``; NaN rows give
    NaN matrices."""
    q = np.asarray(q, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        q = q * (np.sqrt(2.0) / np.sqrt((q * q).sum(axis=-1)))[..., None]  # √2·unit: 2x² etc.
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty((*q.shape[:-1], 3, 3))
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz, wx, wy, wz = x * y, x * z, y * z, w * x, w * y, w * z
    out[..., 0, 0] = 1.0 - (yy + zz)
    out[..., 0, 1] = xy - wz
    out[..., 0, 2] = xz + wy
    out[..., 1, 0] = xy + wz
    out[..., 1, 1] = 1.0 - (xx + zz)
    out[..., 1, 2] = yz - wx
    out[..., 2, 0] = xz - wy
    out[..., 2, 1] = yz + wx
    out[..., 2, 2] = 1.0 - (xx + yy)
    return out


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """Rotation vectors ``[..., 3]`` (axis × angle, rad) of rotation matrices ``[..., 3, 3]``."""
    R = np.asarray(R, dtype=np.float64)
    v = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                        R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    s = np.linalg.norm(v, axis=-1)
    angle = np.arctan2(s, 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0))
    factor = np.where(s > 1e-12, angle / np.maximum(s, 1e-300), 1.0)
    return v * factor[..., None]


def inclination_error(R_est: np.ndarray, R_true: np.ndarray) -> np.ndarray:
    """Angle ``[...]`` rad between the estimated and true down vectors seen in body axes
    (row 2 of the DCMs): the roll/pitch error, free of Euler singularities."""
    d_est = np.asarray(R_est)[..., 2, :]
    d_true = np.asarray(R_true)[..., 2, :]
    cross = np.linalg.norm(np.cross(d_est, d_true), axis=-1)
    return np.arctan2(cross, np.sum(d_est * d_true, axis=-1))


def heading_error(R_est: np.ndarray, R_true: np.ndarray) -> np.ndarray:
    """Signed heading error ``[...]`` rad: the vertical (world z) component of the rotation
    vector of ``R_est R_trueᵀ``, free of Euler singularities (pitch ±90°)."""
    err = np.asarray(R_est) @ np.swapaxes(np.asarray(R_true), -1, -2)
    return rotation_vector(err)[..., 2]
