"""Reset Zero's building blocks (bpms.filter.pose) against values worked out by hand: the mean
of rotations, the motion during a capture window, the heading, what a capture keeps and what a
recording stores of it, and the outputs' defaults (docs/body-model.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bpms.filter.body_model import FOOT_POINTS, POINT_NAMES
from bpms.filter.joints import joint_angles
from bpms.filter.pose import (
    PoseCalibrator,
    Zero,
    average_dcm,
    body_heading,
    body_outputs,
    capture_zero,
    window_motion,
)
from bpms.filter.rotations import euler_to_dcm, rot_x, rot_z
from bpms.io.options import BodyOptions

HIP = 6  # SPEC §1: IMU 6 is the hip (pelvis)


def _still(R: np.ndarray, frames: int = 10) -> np.ndarray:
    """[frames, 18, 3, 3]: every IMU held at ``R[18, 3, 3]``."""
    return np.broadcast_to(R, (frames, 18, 3, 3)).copy()


def test_average_of_rotations_by_hand():
    """rot_z(+0.2) and rot_z(−0.2) average to the identity; a NaN frame is ignored; an IMU
    with no finite frame is NaN."""
    Rs = np.stack([_still(rot_z(0.2), 1)[0], _still(rot_z(-0.2), 1)[0],
                   np.full((18, 3, 3), np.nan)])
    Rs[:, 9] = np.nan
    mean = average_dcm(Rs)
    np.testing.assert_allclose(mean[np.arange(18) != 9], np.broadcast_to(np.eye(3), (17, 3, 3)),
                               atol=1e-12)
    assert np.isnan(mean[9]).all()
    # rotations not symmetric about the identity: rot_z(0.2) and rot_z(0.4) average to
    # rot_z(0.3) whatever a NaN frame beside them holds
    two = np.stack([rot_z(0.2), rot_z(0.4), np.full((3, 3), np.nan)])
    np.testing.assert_allclose(average_dcm(two), rot_z(0.3), atol=1e-12)
    # three frames, one of them counted once: rot_z(0.3) twice and rot_z(0.0) once → a
    # rotation about z by less than 0.3 (the chordal mean), still a rotation about z
    three = average_dcm(np.stack([rot_z(0.3), rot_z(0.3), np.eye(3)]))
    assert np.linalg.det(three) == pytest.approx(1.0)
    np.testing.assert_allclose(three[2], [0.0, 0.0, 1.0], atol=1e-12)
    assert 0.0 < math.atan2(three[1, 0], three[0, 0]) < 0.3


def test_window_motion_by_hand():
    rng = np.random.default_rng(8)
    base = euler_to_dcm(*rng.uniform(-3, 3, (3, 18)))
    window = _still(base, 11)
    for k in range(11):  # IMU 3 turns 0° → 10° about its x axis
        window[k, 3] = base[3] @ rot_x(math.radians(k))
    deg, imu = window_motion(window)
    assert imu == 3 and deg == pytest.approx(10.0, abs=1e-6)
    window[-1, 2] = base[2] @ rot_x(math.pi)  # IMU 2 turned half a turn: 180°, not NaN
    deg, imu = window_motion(window)
    assert imu == 2 and deg == pytest.approx(180.0, abs=1e-5)
    assert window_motion(np.full((5, 18, 3, 3), np.nan)) == (0.0, -1)


def test_a_still_imu_reads_zero_motion_whatever_its_attitude():
    """A still IMU (the same DCM every frame) reads 0°, never "no data" from a cosine a
    rounding step above 1."""
    rng = np.random.default_rng(9)
    for angles in rng.uniform(-3, 3, (200, 3)):
        window = np.full((6, 18, 3, 3), np.nan)
        window[:, 4] = euler_to_dcm(*angles)  # only IMU 4 has data
        deg, imu = window_motion(window)
        assert imu == 4 and deg == pytest.approx(0.0, abs=1e-5)


def test_heading_by_hand():
    R0 = np.stack([rot_z(0.1 * i) for i in range(18)])
    assert body_heading(R0) == pytest.approx(0.1 * HIP)  # "hip": the hip IMU's yaw
    # "mean": the circular mean of 0.0 … 1.7 rad = 0.85 rad
    assert body_heading(R0, "mean") == pytest.approx(0.85, abs=1e-12)
    R0[HIP] = np.nan
    assert body_heading(R0) is None
    with pytest.raises(ValueError, match="heading reference must be one of"):
        body_heading(R0, "north")


def test_capture_keeps_the_previous_where_data_are_missing():
    previous = Zero(np.stack([rot_z(0.4)] * 18), 0.4, frame=10)
    window = _still(np.stack([rot_z(-0.3)] * 18), 5)
    window[:, HIP] = np.nan  # no hip data in this window
    window[:, 12] = np.nan
    zero = capture_zero(window, previous, frame=99)
    assert zero.yaw0 == pytest.approx(0.4)  # the previous heading
    np.testing.assert_allclose(zero.R0[12], rot_z(0.4), atol=1e-12)  # the previous R0
    np.testing.assert_allclose(zero.R0[0], rot_z(-0.3), atol=1e-12)
    assert (zero.frame, zero.source, zero.window, zero.heading, zero.waited) == \
        (99, "automatic", 5, "hip", 0)
    assert zero.motion_deg == pytest.approx(0.0, abs=1e-6) and zero.motion_imu >= 0
    alone = capture_zero(window)  # no previous: heading 0
    assert alone.yaw0 == 0.0 and np.isnan(alone.R0[HIP]).all() and alone.frame == 0
    # a previous capture without hip data either: its heading stands
    no_hip = Zero(np.full((18, 3, 3), np.nan), 0.4, frame=10)
    assert capture_zero(window, no_hip).yaw0 == 0.4
    # the heading from another IMU, or from the mean of all
    other = _still(np.stack([rot_z(0.02 * i) for i in range(18)]), 3)
    assert capture_zero(other, hip=3).yaw0 == pytest.approx(0.06)
    mean = capture_zero(other, heading="mean")
    assert mean.heading == "mean" and mean.yaw0 == pytest.approx(0.17)


def test_a_capture_stored_in_a_recording_reads_back():
    import json

    from bpms.io.event_types import ResetZero

    R0 = np.stack([rot_z(0.05 * i) for i in range(18)])
    zero = Zero(R0, 0.3, 7, "manual", 25, 6.25, 11, 3, "mean")
    assert Zero(R0, 0.3, 7, motion_deg=6.23456).change().to_data()["motion_deg"] == 6.235
    data = zero.change().to_data()
    np.testing.assert_array_equal(data.pop("R0"), R0)
    assert data == {"source": "manual", "window": 25, "yaw0": 0.3,
                    "heading": "mean", "motion_deg": 6.25, "motion_imu": 11, "moved": True,
                    "waited": 3}

    def stored(values: dict) -> ResetZero:  # through the recording's JSON text
        return ResetZero.from_data(json.loads(json.dumps(values)))

    back = stored({**data, "R0": R0.tolist()}).zero
    assert back is not None
    np.testing.assert_array_equal(back[0], R0)
    assert back[1] == 0.3
    assert stored({"R0": R0.tolist()}).zero is None
    # an IMU without data is stored as nulls and reads back as NaN
    holes = R0.tolist()
    holes[2] = [[None] * 3] * 3
    back = stored({"R0": holes, "yaw0": 0.3}).zero
    assert back is not None and back[0].dtype == np.float64 and np.isnan(back[0][2]).all()
    for bad in ({"R0": [[1.0]], "yaw0": 0.0}, {"R0": R0.tolist(), "yaw0": "north"}):
        with pytest.raises(ValueError):
            stored(bad)
    with pytest.raises(ValueError):
        ResetZero.from_data({"R0": R0.tolist(), "yaw0": float("nan")})


def test_outputs_default_to_isb_with_the_feet_on_the_ground():
    C = np.broadcast_to(np.eye(3), (18, 3, 3)).copy()
    C[4] = rot_x(0.5)  # something to tell the conventions apart
    C[0] = euler_to_dcm(0.3, 0.2, 0.1)
    angles, points = body_outputs(C)
    longer = body_outputs(C, BodyOptions(thigh=0.53))[1]
    assert longer[:, 2].min() == pytest.approx(points[:, 2].min() - 0.10, abs=1e-9)
    np.testing.assert_array_equal(angles, joint_angles(C, "isb"))
    feet = [POINT_NAMES.index(n) for n in FOOT_POINTS]
    assert points[feet, 2].max() == pytest.approx(0.0, abs=1e-12)  # the lowest foot at z = 0
    assert (points[:, 2] <= 1e-12).all()  # z down: everything above the ground


def test_pose_calibrator_defaults_half_a_second():
    """docs/body-model.md: 0.5 s for the filters to settle, then a 0.5 s window (25 frames
    each at 50 Hz)."""
    calibrator = PoseCalibrator()
    assert (calibrator.window, calibrator.settle) == (25, 25)
    assert (PoseCalibrator(window=1, settle=0).window, PoseCalibrator(settle=0).settle) == (1, 0)
    assert (PoseCalibrator(window=-3).window, PoseCalibrator(settle=-3).settle) == (1, 0)
