"""Joint-angle sign conventions (docs/joint-angles.md) on the simulated suit's scripted motion.

Truth is geometry, not the Euler code under test: the direction a limb points in its parent
segment's axes (x forward, y right, z down) in the held pose of each named move of the script.
"""

from __future__ import annotations

import numpy as np
import pytest

from bpms.filter.joints import (
    JOINT_ANGLE_NAMES,
    OPENSIM_COORDINATES,
    convert,
    joint_angles,
    opensim_coordinates,
)
from bpms.firmware.sim.motion import generate_motion

J = {name: k for k, name in enumerate(JOINT_ANGLE_NAMES)}
DOWN = np.array([0.0, 0.0, 1.0])
FORWARD = np.array([1.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def motion():
    return generate_motion()


def held(motion, phase_name):
    """Index of the last sample of a named move (held at its target)."""
    for _t0, t1, name in motion.phases:
        if name == phase_name:
            return int(np.searchsorted(motion.t, t1) - 2)
    raise KeyError(phase_name)


def in_parent(C, child, parent, v):
    """Direction ``v`` of segment ``child`` in ``parent``'s axes."""
    return C[parent].T @ C[child] @ v


def deg(x):
    return float(np.degrees(x))


def test_side_raise_is_positive_abduction_on_both_sides(motion):
    k = held(motion, "both arms side raise")
    C = motion.C[k]
    isb = joint_angles(C)
    orig = joint_angles(C, "original")
    for side, arm, shoulder, outward in (("r", 4, 15, 1.0), ("l", 10, 16, -1.0)):
        v = in_parent(C, arm, shoulder, DOWN)
        truth = np.arctan2(outward * v[1], v[2])  # raised outward from hanging down
        assert deg(truth) == pytest.approx(80.0, abs=0.5)
        assert deg(isb[J[f"shoulder_{side}.abduction"]]) == pytest.approx(deg(truth), abs=0.5)
    # the original's raw Euler angles mirror: the issue's -80 / +80
    assert deg(orig[J["shoulder_r.abduction"]]) == pytest.approx(-80.0, abs=0.5)
    assert deg(orig[J["shoulder_l.abduction"]]) == pytest.approx(80.0, abs=0.5)
    osim = opensim_coordinates(isb)
    assert deg(osim["arm_add_r"]) == pytest.approx(-80.0, abs=0.5)
    assert deg(osim["arm_add_l"]) == pytest.approx(-80.0, abs=0.5)


def test_forward_raise_and_rotation_signs(motion):
    k = held(motion, "right arm forward raise")
    C = motion.C[k]
    v = in_parent(C, 4, 15, DOWN)
    assert deg(joint_angles(C)[J["shoulder_r.flexion"]]) == pytest.approx(
        deg(np.arctan2(v[0], v[2])), abs=0.5)
    k = held(motion, "shoulder rotation + elbows")
    C = motion.C[k]
    isb = joint_angles(C)
    for side, fore, shoulder, outward in (("r", 5, 15, 1.0), ("l", 11, 16, -1.0)):
        f = in_parent(C, fore, shoulder, DOWN)  # the forearm, elbow bent 90°
        truth = np.arctan2(outward * f[1], f[0])  # forearm swung outward = external rotation
        assert deg(truth) == pytest.approx(40.0, abs=1.0)
        assert deg(isb[J[f"shoulder_{side}.rotation"]]) == pytest.approx(deg(truth), abs=1.0)
        assert deg(isb[J[f"elbow_{side}.flexion"]]) == pytest.approx(90.0, abs=0.5)


def test_trunk_signs_and_lumbar_coordinates(motion):
    up = -DOWN
    C = motion.C[held(motion, "trunk bend forward")]
    s = in_parent(C, 8, 6, up)
    flex = np.arctan2(s[0], -s[2])
    assert deg(flex) == pytest.approx(40.0, abs=0.5)
    isb = joint_angles(C)
    assert deg(isb[J["torso.flexion"]]) == pytest.approx(deg(flex), abs=0.5)
    assert deg(opensim_coordinates(isb)["lumbar_extension"]) == pytest.approx(-40.0, abs=0.5)
    C = motion.C[held(motion, "trunk bend right")]
    s = in_parent(C, 8, 6, up)
    assert deg(joint_angles(C)[J["torso.abduction"]]) == pytest.approx(
        deg(np.arctan2(s[1], -s[2])), abs=0.5)
    C = motion.C[held(motion, "trunk twist")]
    f = in_parent(C, 8, 6, FORWARD)
    to_left = np.arctan2(-f[1], f[0])
    assert abs(deg(to_left)) == pytest.approx(30.0, abs=0.5)
    assert deg(joint_angles(C)[J["torso.rotation"]]) == pytest.approx(deg(to_left), abs=0.5)


def test_walk_hip_and_knee_follow_the_scripted_legs(motion):
    walk = next((t0, t1) for t0, t1, name in motion.phases if name == "walk")
    sel = (motion.t >= walk[0]) & (motion.t < walk[1])
    C = motion.C[sel]
    isb = joint_angles(C)
    osim = opensim_coordinates(isb)
    for side, thigh in (("r", 0), ("l", 12)):
        v = np.einsum("nji,nj->ni", C[:, 6], np.einsum("nij,j->ni", C[:, thigh], DOWN))
        truth = np.arctan2(v[:, 0], v[:, 2])  # thigh forward of vertical
        assert np.ptp(np.degrees(truth)) > 15
        np.testing.assert_allclose(isb[:, J[f"hip_{side}.flexion"]], truth, atol=1e-6)
        np.testing.assert_allclose(osim[f"hip_flexion_{side}"], truth, atol=1e-6)
        assert np.abs(osim[f"hip_adduction_{side}"]).max() < 1e-6
        assert osim[f"knee_angle_{side}"].max() > np.radians(10)
        assert osim[f"knee_angle_{side}"].min() >= 0.0


def test_convert_round_trip_and_every_coordinate_has_a_column():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(5, len(JOINT_ANGLE_NAMES)))
    np.testing.assert_allclose(convert(convert(a, "original", "isb"), "isb", "original"), a)
    assert all(col in J for col, _ in OPENSIM_COORDINATES.values())
    with pytest.raises(ValueError, match="isb, original"):
        joint_angles(np.tile(np.eye(3), (18, 1, 1)), "clinical")


def test_the_option_reaches_the_processor_outputs():
    """``joints.convention = "original"`` in the options: the processor's joint angles are
    the raw Euler ones, and the result says so."""
    from bpms.filter.processor import BodyPoseProcessor
    from bpms.firmware.sim.session import simulate
    from bpms.io.options import Options

    rec = simulate(4.0, seed=7)
    options = Options()
    options.joints.convention = "original"
    isb = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors)
    orig = BodyPoseProcessor(rec.calibration, options).process(rec.raw, rec.errors)
    assert isb.convention == "isb" and orig.convention == "original"
    ok = np.isfinite(isb.joint_angles).all(axis=1)
    assert ok.sum() > 100
    np.testing.assert_allclose(orig.joint_angles[ok], joint_angles(isb.C[ok], "original"))
    # right-side abduction flips sign, left-side does not
    k_r, k_l = J["shoulder_r.abduction"], J["shoulder_l.abduction"]
    np.testing.assert_allclose(orig.joint_angles[ok, k_r], -isb.joint_angles[ok, k_r])
    np.testing.assert_allclose(orig.joint_angles[ok, k_l], isb.joint_angles[ok, k_l])
