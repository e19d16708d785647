"""bpms.filter.rotations against independent constructions (axis-angle, elementary products),
including exactly-180° rotations, where a sign-from-differences quaternion fails."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bpms.filter.rotations import (
    dcm_to_euler,
    dcm_to_quaternion,
    euler_to_dcm,
    quaternion_to_dcm,
)

unit = st.floats(-1.0, 1.0, allow_nan=False)
axes = st.tuples(unit, unit, unit).filter(lambda v: np.linalg.norm(v) > 1e-3)


def rodrigues(axis: np.ndarray, angle: float) -> np.ndarray:
    """R = cos θ I + sin θ [k]× + (1 - cos θ) k kᵀ, by hand."""
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.cos(angle) * np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * np.outer(k, k)


def same_rotation(q: np.ndarray, p: np.ndarray) -> float:
    """Angle (rad) between the rotations of two unit quaternions."""
    return 2 * np.arccos(np.clip(abs(float(q @ p)), 0.0, 1.0))


@settings(max_examples=300, deadline=None)
@given(axes, st.floats(0.0, np.pi))
def test_quaternion_of_axis_angle(axis, angle):
    axis = np.asarray(axis) / np.linalg.norm(axis)
    expected = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])
    q = dcm_to_quaternion(rodrigues(axis, angle))
    assert q[0] >= 0
    assert abs(np.linalg.norm(q) - 1) < 1e-12
    assert same_rotation(q, expected) < 1e-6


@settings(max_examples=300, deadline=None)
@given(axes)
def test_quaternion_at_exactly_180_degrees(axis):
    axis = np.asarray(axis) / np.linalg.norm(axis)
    R = 2 * np.outer(axis, axis) - np.eye(3)  # 180° about axis, exactly symmetric
    q = dcm_to_quaternion(R)
    assert abs(q[0]) < 1e-7
    assert abs(abs(q[1:] @ axis) - 1) < 1e-9  # the axis, either sign
    np.testing.assert_allclose(quaternion_to_dcm(q), R, atol=1e-9)


def test_quaternion_180_examples_by_hand():
    # 180° about (1, -1, 0)/√2: x and y have opposite signs.
    R = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    q = dcm_to_quaternion(R)
    np.testing.assert_allclose(np.abs(q), [0, 2**-0.5, 2**-0.5, 0], atol=1e-12)
    assert q[1] * q[2] < 0
    # batch shape is kept
    assert dcm_to_quaternion(np.stack([R, np.eye(3)])).shape == (2, 4)


@settings(max_examples=200, deadline=None)
@given(st.floats(-np.pi, np.pi), st.floats(-1.5, 1.5), st.floats(-np.pi, np.pi))
def test_euler_matches_elementary_product(roll, pitch, yaw):
    def rx(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    def ry(a):
        return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    def rz(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    R = rz(yaw) @ ry(pitch) @ rx(roll)
    np.testing.assert_allclose(euler_to_dcm(roll, pitch, yaw), R, atol=1e-12)
    np.testing.assert_allclose(dcm_to_euler(R), [roll, pitch, yaw], atol=1e-9)
