"""Pinned conventions: every IMU's board mounting, pre-rotation and sign vectors, checked with
raw counts built by hand in this file (not by the simulated suit, not by the filter).

What the specification's tables say, in words (X forward, Y right, Z down: the body's axes,
which are every segment's axes in the calibration pose, standing, arms down, feet forward):

- "pitch 90°" IMUs (0 2 3 4 5 6 7 8 9 10 11 12 14: thighs, shanks, hands, arms, forearms,
  hip, neck, mid spine): the sensor stick lies along the segment, board x points UP, board y
  RIGHT, board z FORWARD. Pre-rotation R* = [[0,0,1],[0,1,0],[-1,0,0]]: filter x = board z,
  filter y = board y, filter z = -board x.
- "roll 90°" IMUs (15 16: shoulders): board x FORWARD, board y DOWN, board z LEFT.
  R* = [[1,0,0],[0,0,-1],[0,1,0]]: filter x = board x, filter y = -board z, filter z = board y.
- "identity" IMUs (1 13 17: feet, head): board x FORWARD, y RIGHT, z DOWN. R* = I.
- Sign vectors (raw chip axes → board axes): accelerometer (+1, +1, +1): an axis reads its
  table maximum (+1 g) when it points DOWN; magnetometer (+1, -1, -1): the chip's y and z read
  the opposite of the field's board y and z; gyroscope (-1, -1, -1).
- Calibration table: an accelerometer axis reads (min+max)/2 ± (max-min)/2 at ±1 g; a
  magnetometer axis the same at ± the full field; the gyro reads its average at rest.

Poses (every IMU of the suit in the same orientation; the Earth's field points north and 60°
down, the subject faces north): level rest; a +90° turn about the body's X (right side down),
about Y (nose up) and about Z (turned to face east). Each must read the expected roll, pitch
and yaw within 0.5° after the filter's static initialisation and a second of still frames.
"""

from __future__ import annotations

import numpy as np
import pytest

from bpms.filter.processor import BodyPoseProcessor
from bpms.io.calib_file import CalibrationTable

S60, C60 = np.sin(np.radians(60)), np.cos(np.radians(60))

#: Board axes (x, y, z) as filter-frame unit vectors, per mounting kind (rows).
MOUNTINGS = {
    "pitch 90°": np.array([[0, 0, -1], [0, 1, 0], [1, 0, 0]]),  # x up, y right, z forward
    "roll 90°": np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]]),  # x forward, y down, z left
    "identity": np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]]),  # x fwd, y right, z down
}
IMUS = [  # (id, name, mounting)
    (0, "right thigh", "pitch 90°"), (1, "right foot", "identity"),
    (2, "right shank", "pitch 90°"), (3, "right hand", "pitch 90°"),
    (4, "right arm", "pitch 90°"), (5, "right forearm", "pitch 90°"),
    (6, "hip", "pitch 90°"), (7, "neck", "pitch 90°"), (8, "mid spine", "pitch 90°"),
    (9, "left hand", "pitch 90°"), (10, "left arm", "pitch 90°"),
    (11, "left forearm", "pitch 90°"), (12, "left thigh", "pitch 90°"),
    (13, "left foot", "identity"), (14, "left shank", "pitch 90°"),
    (15, "right shoulder", "roll 90°"), (16, "left shoulder", "roll 90°"),
    (17, "head", "identity"),
]
ACCEL_SIGNS = np.array([1, 1, 1])
MAG_SIGNS = np.array([1, -1, -1])

#: (name, gravity direction in the IMU's filter frame, Earth's field in it (unit),
#:  expected roll, pitch, yaw in degrees). Worked out by hand from R = Rx/Ry/Rz(90°):
#:  a vector's filter-frame components are Rᵀ times its world components, down = (0, 0, 1),
#:  field = (cos 60°, 0, sin 60°).
POSES = [
    ("level", (0, 0, 1), (C60, 0, S60), (0, 0, 0)),
    ("90° about X", (0, 1, 0), (C60, S60, 0), (90, 0, 0)),
    ("90° about Y", (-1, 0, 0), (-S60, 0, C60), (None, 90, None)),  # gimbal lock: see below
    ("90° about Z", (0, 0, 1), (0, -C60, S60), (0, 0, 90)),
]

# A hand-made calibration table: the same numbers for every IMU, offsets off zero and
# ranges unequal per axis so that a swapped axis or a wrong offset shows.
ACC_MIN_MAX = np.array([[-270.0, 250.0], [-262.0, 260.0], [-240.0, 270.0]])
MAG_MIN_MAX = np.array([[-400.0, 480.0], [-390.0, 380.0], [-460.0, 500.0]])
GYRO_AVG = np.array([-40.0, 50.0, 7.0])


def table() -> CalibrationTable:
    half = (ACC_MIN_MAX[:, 1] - ACC_MIN_MAX[:, 0]) / 2
    row = np.concatenate([[half.mean()], ACC_MIN_MAX.ravel(), MAG_MIN_MAX.ravel(), GYRO_AVG])
    return CalibrationTable(values=np.tile(row, (18, 1)), source="hand-made test table")


def counts(mounting: str, down, field) -> np.ndarray:
    """The 9 raw counts of one IMU at rest, by the rules in the module docstring."""
    board_down = MOUNTINGS[mounting] @ np.asarray(down, float)  # g along board x, y, z
    board_field = MOUNTINGS[mounting] @ np.asarray(field, float)  # fraction of full field
    acc = ACC_MIN_MAX.mean(1) + ACCEL_SIGNS * board_down * np.diff(ACC_MIN_MAX)[:, 0] / 2
    mag = MAG_MIN_MAX.mean(1) + MAG_SIGNS * board_field * np.diff(MAG_MIN_MAX)[:, 0] / 2
    return np.rint(np.concatenate([acc, mag, GYRO_AVG]))


def test_the_hand_rules_by_example():
    """Two IMUs worked fully by hand, so the rules above are pinned as numbers too."""
    # Right thigh (pitch 90°), level: gravity is along -board x (x points up): ax reads its
    # minimum -270; ay, az read their offsets -1, 15. Field (0.5, 0, 0.866): board x = -0.866,
    # y = 0, z = 0.5 → mx = 40 - 0.866·440 = -341, my = -5 - 0 = -5,
    # mz = 20 - 0.5·480 = -220 (sign -1).
    np.testing.assert_array_equal(counts("pitch 90°", (0, 0, 1), (C60, 0, S60)),
                                  [-270, -1, 15, -341, -5, -220, -40, 50, 7])
    # Right shoulder (roll 90°), level: gravity along +board y (y points down): ay = 260,
    # ax, az read their offsets -10, 15.
    # Field: board x = 0.5, y = 0.866, z = 0 → mx = 40 + 220 = 260,
    # my = -5 - 0.866·385 = -338, mz = 20.
    np.testing.assert_array_equal(counts("roll 90°", (0, 0, 1), (C60, 0, S60)),
                                  [-10, 260, 15, 260, -338, 20, -40, 50, 7])


def run_pose(down, field) -> np.ndarray:
    """Euler angles (deg) of all 18 IMUs after 50 still frames of one pose."""
    frame = np.stack([counts(m, down, field) for _, _, m in IMUS]).astype(np.int16)
    result = BodyPoseProcessor(calibration=table()).process(np.tile(frame, (50, 1, 1)))
    return np.degrees(result.euler[-1]), result.R[-1]


def angle_between(R: np.ndarray, Q: np.ndarray) -> np.ndarray:
    cos = (np.trace(np.swapaxes(R, -1, -2) @ Q, axis1=-2, axis2=-1) - 1) / 2
    return np.degrees(np.arccos(np.clip(cos, -1, 1)))


@pytest.mark.parametrize(("name", "down", "field", "expected"), POSES,
                         ids=["level", "X90", "Y90", "Z90"])
def test_each_imu_reads_the_hand_built_pose(name, down, field, expected):
    euler, R = run_pose(down, field)
    roll, pitch, yaw = expected
    for imu, label, mounting in IMUS:
        msg = f"IMU {imu} ({label}, {mounting}) in pose {name}: {np.round(euler[imu], 2)}"
        assert abs(euler[imu, 1] - pitch) < 0.5, msg
        if roll is not None:
            assert abs(euler[imu, 0] - roll) < 0.5, msg
            assert abs((euler[imu, 2] - yaw + 180) % 360 - 180) < 0.5, msg
    if roll is None:
        # At pitch 90° roll and yaw are one degree of freedom: check the whole orientation,
        # R = Ry(90°): body x points up, z points north.
        expected_R = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])
        assert angle_between(R, expected_R).max() < 0.5, np.round(angle_between(R, expected_R), 2)
