"""Rotation helpers and joint-angle conventions against matrices and signs written out by hand
(the survivors of docs/testing.md's mutation run that change a number a user reads: a
quaternion's off-diagonal signs, NaN at the clip edges, batches normalised as a whole, the
ISB sign table)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bpms.filter.body_model import SEGMENT_AXIS
from bpms.filter.joints import ISB_SIGNS, convert, joint_angles
from bpms.filter.rotations import (
    dcm_to_euler,
    dcm_to_quaternion,
    euler_to_dcm,
    quaternion_to_dcm,
    rot_x,
    rotation_vector,
)
from bpms.io.names import JOINT_ANGLE_NAMES

H = math.sqrt(0.5)
#: 90° about x, y, z: (w, x, y, z) and the matrix written out (R maps body to world).
QUARTER_TURNS = {
    "x": ((H, H, 0.0, 0.0), [[1, 0, 0], [0, 0, -1], [0, 1, 0]]),
    "y": ((H, 0.0, H, 0.0), [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]),
    "z": ((H, 0.0, 0.0, H), [[0, -1, 0], [1, 0, 0], [0, 0, 1]]),
}


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_quaternion_and_matrix_of_a_quarter_turn(axis):
    q, R = QUARTER_TURNS[axis]
    np.testing.assert_allclose(quaternion_to_dcm(np.array(q)), R, atol=1e-15)
    np.testing.assert_allclose(quaternion_to_dcm(3.0 * np.array(q)), R, atol=1e-15)  # any norm
    np.testing.assert_allclose(dcm_to_quaternion(np.array(R, float)), q, atol=1e-15)


def test_batches_are_one_rotation_per_row():
    """[N, 4] and [N, 3, 3] batches: each row on its own (its own norm)."""
    qs = np.array([q for q, _ in QUARTER_TURNS.values()] + [(1.0, 0.0, 0.0, 0.0)])
    Rs = np.array([R for _, R in QUARTER_TURNS.values()] + [np.eye(3)], float)
    np.testing.assert_allclose(quaternion_to_dcm(qs * [[1.0], [2.0], [0.5], [7.0]]), Rs,
                               atol=1e-15)
    got = dcm_to_quaternion(Rs)
    np.testing.assert_allclose(np.linalg.norm(got, axis=-1), 1.0, atol=1e-15)
    np.testing.assert_allclose(got, qs, atol=1e-15)


def test_rot_x_by_hand():
    c, s = math.cos(0.3), math.sin(0.3)
    np.testing.assert_allclose(rot_x(0.3), [[1, 0, 0], [0, c, -s], [0, s, c]], atol=1e-15)


def test_euler_at_the_pitch_limit_and_into_a_given_array():
    """R[2][0] a rounding step beyond 1 (pitch −90°) reads −90°, not NaN; ``out`` is filled."""
    R = euler_to_dcm(0.0, -math.pi / 2, 0.0)
    R[2, 0] = 1.0 + 2e-16 * 4
    euler = dcm_to_euler(R)
    assert euler[1] == pytest.approx(-math.pi / 2) and np.isfinite(euler).all()
    R[2, 0] = -1.0 - 2e-16 * 4
    assert dcm_to_euler(R)[1] == pytest.approx(math.pi / 2)
    out = np.full((2, 3), np.nan)
    back = dcm_to_euler(euler_to_dcm(np.array([0.1, -0.2]), np.array([0.3, 0.4]),
                                     np.array([-1.0, 2.0])), out=out)
    np.testing.assert_allclose(out, [[0.1, 0.3, -1.0], [-0.2, 0.4, 2.0]], atol=1e-12)
    assert back is out


def test_isb_signs_by_the_documented_rule():
    """docs/joint-angles.md: ISB = original × sign, column by column: hinges unchanged; right
    side abduction −roll, rotation +yaw; left side abduction +roll, rotation −yaw; midline
    (torso, head) flexion −pitch, rotation −yaw."""
    rule = []
    for name in JOINT_ANGLE_NAMES:
        joint, what = name.split(".")
        side = joint[-2:] if joint[-2:] in ("_r", "_l") else "mid"
        sign = {("_r", "abduction"): -1, ("_l", "rotation"): -1, ("mid", "flexion"): -1,
                ("mid", "rotation"): -1}.get((side, what), 1)
        rule.append(sign if joint not in ("elbow_r", "elbow_l", "knee_r", "knee_l") else 1)
    np.testing.assert_array_equal(ISB_SIGNS, rule)
    original = np.linspace(-1.0, 1.0, 28)
    np.testing.assert_array_equal(convert(original, "original", "isb"), original * rule)
    np.testing.assert_array_equal(convert(original, "isb", "original"), original * rule)
    np.testing.assert_array_equal(convert(original, "isb", "isb"), original)


def test_hinges_fully_straight_and_fully_folded_are_finite():
    """A hinge whose two segments are parallel (the calibration pose: 0) or antiparallel
    (folded: π) reads exactly that for any orientation of the limb, never NaN from a cosine
    a rounding step beyond ±1."""
    rng = np.random.default_rng(4)
    angles = rng.uniform(-math.pi, math.pi, (400, 3))
    R = euler_to_dcm(angles[:, 0], angles[:, 1], angles[:, 2])
    C = np.broadcast_to(R[:, None], (400, 18, 3, 3)).copy()
    straight = joint_angles(C)[:, :4]
    assert np.isfinite(straight).all()
    np.testing.assert_allclose(straight, 0.0, atol=2e-7)
    # folded: every distal segment turned 180° about an axis across it (long axes
    # antiparallel): about x for a segment along y or z, about y for one along x
    folded = C.copy()
    for distal in (5, 11, 2, 14):
        along_x = abs(SEGMENT_AXIS[distal][0]) == 1
        turn = euler_to_dcm(0.0, math.pi, 0.0) if along_x else rot_x(math.pi)
        folded[:, distal] = R @ turn
    hinge = joint_angles(folded)[:, :4]
    assert np.isfinite(hinge).all()
    np.testing.assert_allclose(hinge, math.pi, atol=2e-7)


def _axis_angle(axis, angle: float) -> np.ndarray:
    """Rodrigues' formula written out: R = I + sin θ K + (1 − cos θ) K²."""
    x, y, z = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


@pytest.mark.parametrize(("axis", "angle"), [((1, 0, 0), 0.3), ((0, 1, 0), -0.7),
                                             ((0, 0, 1), 2.0), ((1, 2, 2), 1.0),
                                             ((2, -1, 2), 3.1), ((0, 0, 1), 1e-14)])
def test_rotation_vector_is_axis_times_angle(axis, angle):
    """The rotation vector (gait events' angular rate, the heading error) of a rotation built
    by hand about ``axis`` by ``angle``: the unit axis × the angle."""
    unit = np.asarray(axis, float) / np.linalg.norm(axis)
    np.testing.assert_allclose(rotation_vector(_axis_angle(axis, angle)), unit * angle,
                               atol=1e-12, rtol=1e-9)
    batch = rotation_vector(np.stack([_axis_angle(axis, angle), np.eye(3)]))
    np.testing.assert_allclose(batch, [unit * angle, [0.0, 0.0, 0.0]], atol=1e-12, rtol=1e-9)


def test_a_straight_hinge_in_any_orientation_is_finite():
    """Two segments whose long axes are parallel but whose matrices differ (turned about the
    long axis): flexion 0 within rounding, never NaN from a cosine a rounding step above 1."""
    rng = np.random.default_rng(12)
    angles = rng.uniform(-math.pi, math.pi, (2000, 3))
    R = euler_to_dcm(angles[:, 0], angles[:, 1], angles[:, 2])
    C = np.broadcast_to(R[:, None], (2000, 18, 3, 3)).copy()
    twist = rng.uniform(-math.pi, math.pi, 2000)
    for distal in (5, 11, 2, 14):
        axis = np.asarray(SEGMENT_AXIS[distal], float)
        C[:, distal] = R @ np.stack([_axis_angle(axis, t) for t in twist])
    hinge = joint_angles(C)[:, :4]
    assert np.isfinite(hinge).all()
    np.testing.assert_allclose(hinge, 0.0, atol=1e-6)
