"""Reset Zero, joint angles on known poses, live vs batch pose calibration."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.filter.body_model import POINT_INDEX, joint_positions
from bpms.filter.joints import JOINT_ANGLE_NAMES, joint_angles
from bpms.filter.pose import PoseCalibrator, average_dcm, capture_zero, segment_orientations
from bpms.filter.rotations import dcm_to_euler, euler_to_dcm, rot_x, rot_y, rot_z
from bpms.io.options import BodyOptions

J = {name: k for k, name in enumerate(JOINT_ANGLE_NAMES)}
RNG = np.random.default_rng(11)


def _random_rotations(n: int, scale: float = 3.0) -> np.ndarray:
    return euler_to_dcm(*RNG.uniform(-scale / 2, scale / 2, (3, n)))


def test_average_dcm_is_a_rotation_near_the_inputs():
    base = _random_rotations(18)
    jitter = euler_to_dcm(*RNG.normal(scale=0.01, size=(3, 25, 18)))
    window = base @ jitter
    mean = average_dcm(window)
    np.testing.assert_allclose(mean @ np.swapaxes(mean, -1, -2), np.tile(np.eye(3), (18, 1, 1)),
                               atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(mean), 1.0, atol=1e-12)
    angle = np.arccos(np.clip((np.trace(np.swapaxes(mean, -1, -2) @ base, axis1=-2, axis2=-1)
                               - 1) / 2, -1, 1))
    assert np.degrees(angle).max() < 0.5
    window[:, 3] = np.nan  # an IMU without data
    assert np.isnan(average_dcm(window)[3]).all()


def test_calibration_pose_reads_heading_and_zero_joint_angles():
    """In the calibration pose, after Reset Zero every segment reads Rz(ψ0), joint angles 0."""
    heading = np.radians(37.0)
    mounting = _random_rotations(18, scale=0.6)  # IMU frames misaligned with the segments
    R_pose = rot_z(heading) @ mounting
    zero = capture_zero(np.repeat(R_pose[None], 10, axis=0))
    psi0 = dcm_to_euler(R_pose[6])[2]
    C = segment_orientations(R_pose, zero)
    np.testing.assert_allclose(C, np.broadcast_to(rot_z(psi0), C.shape), atol=1e-12)
    np.testing.assert_allclose(joint_angles(C), 0.0, atol=1e-6)
    pos = joint_positions(C)
    assert pos[..., 2].max() == pytest.approx(0.0, abs=1e-12)  # lowest foot on the ground
    # the figure stands upright: head top above the pelvis by the spine, neck and head lengths
    b = BodyOptions()
    height = pos[POINT_INDEX["pelvis"], 2] - pos[POINT_INDEX["head_top"], 2]
    assert height == pytest.approx(b.low_spine + b.mid_spine + b.neck + b.head)


def _pose_with(rotations: dict[int, np.ndarray], heading: float = 0.4) -> np.ndarray:
    """Segment orientations of a posture: each listed segment rotated (segment axes) relative
    to the body heading; children inherit as given explicitly."""
    C = np.tile(rot_z(heading), (18, 1, 1))
    for imu, rel in rotations.items():
        C[imu] = rot_z(heading) @ rel
    return C


def test_joint_angles_of_known_poses_through_reset_zero():
    """Mounting errors + heading + Reset Zero: each known joint angle comes back within 1°.

    The hip IMU gets no yaw mounting error: ψ0 is its yaw, so a yaw error δ there turns every
    segment frame by δ about the vertical and mixes ball-joint roll and pitch (docs/filter.md).
    """
    mounting = _random_rotations(18, scale=0.5)
    mounting[6] = rot_y(-0.15) @ rot_x(0.2)  # ZYX yaw of Rz(h) @ this is exactly h
    heading = 0.4
    C_cal = _pose_with({}, heading)
    zero = capture_zero((C_cal @ mounting)[None])
    d = np.radians
    cases = [
        # (segment rotations, {joint: expected angle rad})
        ({0: rot_y(d(40)), 2: rot_y(d(40)) @ rot_y(d(-70))},
         {"hip_r.flexion": d(40), "knee_r.flexion": d(70)}),
        ({4: rot_x(d(-60)), 5: rot_x(d(-60)) @ rot_y(d(30))},
         {"shoulder_r.abduction": d(-60), "elbow_r.flexion": d(30)}),
        ({8: rot_y(d(-25)), 7: rot_y(d(-25)), 17: rot_y(d(-25)) @ rot_z(d(50))},
         {"torso.flexion": d(-25), "head.rotation": d(50)}),
        ({13: rot_y(d(15))}, {"ankle_l.flexion": d(15)}),
        ({10: euler_to_dcm(0.0, d(80), d(20))},
         {"shoulder_l.flexion": d(80), "shoulder_l.rotation": d(20)}),
    ]
    for rotations, expected in cases:
        C_true = _pose_with(rotations, heading)
        C_est = segment_orientations(C_true @ mounting, zero)
        angles = joint_angles(C_est, "original")  # the cases are raw Euler angles
        for name, value in expected.items():
            assert abs(angles[J[name]] - value) < d(1), (name, np.degrees(angles[J[name]]))
        others = [k for n, k in J.items() if n not in expected]
        truth = joint_angles(C_true, "original")
        np.testing.assert_allclose(angles[others], truth[others], atol=d(1))


def test_pose_calibrator_live_equals_batch_and_captures_on_schedule():
    n = 120
    R = np.tile(_random_rotations(18)[None], (n, 1, 1, 1))
    # jitter of a still subject (0.3° rms): the automatic capture does not wait
    R = R @ euler_to_dcm(*RNG.normal(scale=0.005, size=(3, n, 18)))
    R[:3, 5] = np.nan  # IMU 5 initialises late
    batch = PoseCalibrator(window=10, settle=20)
    C_batch = batch.apply(R, zero_at=[90])
    assert [z.frame for z in batch.captures] == [3, 29, 90]
    live = PoseCalibrator(window=10, settle=20)
    C_live = []
    for k in range(n):
        if k == 90:
            live.request()
        C_live.append(live.apply(R[k:k + 1])[0])
    np.testing.assert_array_equal(np.array(C_live), C_batch)
    assert np.isnan(C_batch[:3]).all()  # nothing before all IMUs are initialised
    # after the capture at 90, the averaged window 81..90 is the zero
    zero = capture_zero(R[81:91], frame=90)
    np.testing.assert_allclose(C_batch[100], segment_orientations(R[100], zero), atol=1e-12)
    # in chunks, too
    chunks = PoseCalibrator(window=10, settle=20)
    parts = [chunks.apply(R[lo:lo + 7], zero_at=[90 - lo] if lo <= 90 < lo + 7 else [])
             for lo in range(0, n, 7)]
    np.testing.assert_array_equal(np.concatenate(parts), C_batch)


def test_body_heading_hip_or_mean_of_all_imus():
    import pytest

    from bpms.filter.pose import body_heading
    from bpms.filter.rotations import euler_to_dcm

    rng = np.random.default_rng(4)
    psi = np.radians(170.0)  # near ±180°: the mean must be circular
    errors = np.radians(rng.normal(0.0, 3.0, 18))
    errors -= errors.mean()
    R0 = euler_to_dcm(np.radians(rng.normal(0, 2, 18)), np.radians(rng.normal(0, 2, 18)),
                      psi + errors)
    assert body_heading(R0, "hip") == pytest.approx(psi + errors[6])
    assert body_heading(R0, "mean") == pytest.approx(psi, abs=1e-3)
    R0[6] = np.nan
    assert body_heading(R0, "hip") is None
    assert body_heading(R0, "mean") == pytest.approx(psi, abs=0.02)
    with pytest.raises(ValueError):
        body_heading(R0, "north")
