"""Minimal rotation helpers of the simulated suit, written apart from the filter's.

The simulated suit is the test suite's independent truth, so it shares no code with
the filter package (the code under test). Conventions are the specification's: a DCM ``R`` maps
body-frame vectors to the world frame (north-east-down), ``v_w = R v_b``; Euler angles are
roll φ about X, pitch θ about Y, yaw ψ about Z with ``R = Rz(ψ) Ry(θ) Rx(φ)``; radians.
"""

from __future__ import annotations

import numpy as np


def _elementary(axis: int, angle: np.ndarray) -> np.ndarray:
    """``[..., 3, 3]`` right-handed rotations by ``angle`` (rad) about coordinate ``axis``."""
    angle = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros((*angle.shape, 3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]  # the plane turned: i → j by +90°
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., j, i] = s
    out[..., i, j] = -s
    return out


def zyx(roll: np.ndarray | float, pitch: np.ndarray | float,
        yaw: np.ndarray | float) -> np.ndarray:
    """``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` as a product of the three elementary rotations,
    ``[..., 3, 3]`` (broadcast over the angles' shapes)."""
    roll, pitch, yaw = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64)
                                             for v in (roll, pitch, yaw)))
    return _elementary(2, yaw) @ _elementary(1, pitch) @ _elementary(0, roll)


def skew(w: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[..., 3, 3]`` of vectors ``w [..., 3]``."""
    w = np.asarray(w, dtype=np.float64)
    K = np.zeros((*w.shape[:-1], 3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
    return K


def expm(w: np.ndarray) -> np.ndarray:
    """Rotation matrices ``[..., 3, 3]`` of rotation vectors ``w [..., 3]`` (Rodrigues)."""
    w = np.asarray(w, dtype=np.float64)
    angle = np.linalg.norm(w, axis=-1)[..., None, None]
    K = skew(w / np.maximum(angle[..., 0], 1e-300))
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def logm(R: np.ndarray) -> np.ndarray:
    """Rotation vectors ``[..., 3]`` (axis × angle, rad) of rotations ``R [..., 3, 3]`` with
    angles below 180° (the simulated suit's sample-to-sample rotations)."""
    R = np.asarray(R, dtype=np.float64)
    v = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                        R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    s = np.linalg.norm(v, axis=-1)
    angle = np.arctan2(s, 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0))
    factor = np.where(s > 1e-12, angle / np.maximum(s, 1e-300), 1.0)
    return v * factor[..., None]


def random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """``[n, 3, 3]`` uniformly random rotations (normalised Gaussian quaternions)."""
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=1)
