"""Angles that read right (issue 27.6, 44.6): in the simulated script's elbow-flexion phase
(the forearms pass pitch 90°) no angle column the window shows by default jumps by more than
90° between frames except where it returns to the standard range on leaving the singularity;
the readout is the same rotation as the filters' own angles and never piles up whole turns."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.filter.processor import BodyPoseProcessor
from bpms.filter.rotations import euler_to_dcm
from bpms.firmware.sim.session import simulate
from bpms.gui.angle_readout import ContinuousAngles, poorly_defined

PHASES = ("both arms down", "elbow flexion", "elbows extended", "shoulder rotation + elbows")


@pytest.fixture(scope="module")
def trial():
    rec = simulate(duration_s=24.0, seed=2)
    result = BodyPoseProcessor().process(rec.raw, rec.errors)
    start = next(a for a, _b, name in rec.phases if name == PHASES[0])
    end = next(b for _a, b, name in rec.phases if name == PHASES[-1])
    window = (rec.t >= start) & (rec.t < end)
    return result, window


def _jumps_deg(angles: np.ndarray) -> np.ndarray:
    """Largest frame-to-frame change of each column ``[..., k]`` over the frames, degrees."""
    return np.degrees(np.nanmax(np.abs(np.diff(angles, axis=0)), axis=0))


def test_the_filters_own_angles_do_jump_there(trial):
    result, window = trial  # the phase is a real test: the standard ranges flip
    assert _jumps_deg(result.euler_output[window]).max() > 150


def test_no_default_angle_column_jumps_more_than_90_degrees(trial):
    result, window = trial
    shown = ContinuousAngles().feed(result.euler_output, np.arange(len(result.euler_output)))
    # roll, pitch, yaw of all 18 IMUs: a jump only where the readout leaves the marked region
    # (pitch within 15° of ±90°) and returns to the filters' own standard triple
    steps = np.degrees(np.abs(np.diff(shown[window], axis=0))).max(axis=2)  # [n-1, 18]
    marked_before = poorly_defined(shown[window][:-1, :, 1])
    for k, imu in zip(*np.nonzero(steps >= 90), strict=True):
        assert marked_before[k, imu]
        np.testing.assert_allclose(shown[window][k + 1, imu],
                                   result.euler_output[window][k + 1, imu], atol=1e-12)
    assert (steps >= 90).sum() <= 8  # a few returns, not a flickering
    assert _jumps_deg(np.asarray(result.joint_angles)[window]).max() < 90  # joint angles
    # the same rotations: only the choice among equivalent triples differs
    finite = np.isfinite(result.euler_output).all(axis=2)
    np.testing.assert_allclose(euler_to_dcm(*np.moveaxis(shown[finite], -1, 0)),
                               euler_to_dcm(*np.moveaxis(result.euler_output[finite], -1, 0)),
                               atol=1e-9)
    # where roll and yaw sweep fast (the forearms near pitch 90°) they are marked as poorly
    # defined; elsewhere in the phase they change slowly
    marked = poorly_defined(shown[window][..., 1])
    assert marked[:, [5, 11]].any()
    fast = np.zeros_like(marked)
    fast[1:] = np.degrees(np.abs(np.diff(shown[window][..., 0], axis=0))) > 10
    assert (fast <= marked | np.roll(marked, 1, axis=0)).all()


def test_a_jump_back_in_time_or_a_gap_restarts_the_readout():
    readout = ContinuousAngles()
    turn = np.radians(np.linspace(170, 190, 21))  # yaw passing south
    euler = np.zeros((21, 18, 3))
    euler[:, :, 2] = np.angle(np.exp(1j * turn))[:, None]  # wrapped as the filter gives it
    shown = readout.feed(euler, np.arange(21))
    np.testing.assert_allclose(np.degrees(shown[:, 0, 2]), np.degrees(turn), atol=1e-9)
    again = readout.feed(euler[-1:], np.array([5]))  # a seek back: standard range again
    assert np.degrees(again[0, 0, 2]) == pytest.approx(-170.0)


def _standard(euler: np.ndarray) -> np.ndarray:
    """The triple with pitch in [-90, 90] and roll, yaw in (-180, 180] (rad), by hand."""
    roll, pitch, yaw = np.moveaxis(np.asarray(euler, np.float64), -1, 0)
    flip = np.cos(pitch) < 0
    roll = np.where(flip, roll + np.pi, roll)
    yaw = np.where(flip, yaw + np.pi, yaw)
    pitch = np.where(flip, np.pi - pitch, pitch)
    pitch = np.angle(np.exp(1j * pitch))
    pitch = np.where(pitch > np.pi / 2, np.pi - pitch, np.where(pitch < -np.pi / 2,
                                                                  -np.pi - pitch, pitch))
    return np.stack([np.angle(np.exp(1j * roll)), pitch, np.angle(np.exp(1j * yaw))], -1)


def test_many_whole_turns_never_pile_up():
    """Roll and yaw turning 100° a frame for 2,000 frames (555 turns, more than an hour of
    any segment's turning), pitch 20°: the readout stays within 20° of the standard range and
    reads the standard angle whenever that is more than 20° from ±180°."""
    n = 2000
    roll = np.radians(100.0 * np.arange(n))
    yaw = -np.radians(70.0 * np.arange(n))
    euler = np.zeros((n, 18, 3))
    euler[:, :, 0] = np.angle(np.exp(1j * roll))[:, None]
    euler[:, :, 1] = np.radians(20.0)
    euler[:, :, 2] = np.angle(np.exp(1j * yaw))[:, None]
    shown = ContinuousAngles().feed(euler, np.arange(n))
    assert np.abs(np.degrees(shown[..., [0, 2]])).max() <= 200.0 + 1e-9
    clear = np.abs(np.degrees(euler[..., [0, 2]])) < 160.0
    np.testing.assert_allclose(shown[..., [0, 2]][clear], euler[..., [0, 2]][clear],
                               atol=1e-12)


def test_a_slow_turn_through_south_is_carried_then_wrapped():
    """Yaw 170° → 230° → 150°, 1° a frame: carried past 180° up to 199°, then the standard
    −159°...; back through south carried down to −199° (161°), then the standard 159° (values
    worked by hand)."""
    path = np.concatenate([np.arange(170.0, 231.0), np.arange(229.0, 149.0, -1.0)])
    euler = np.zeros((len(path), 18, 3))
    euler[:, :, 2] = np.angle(np.exp(1j * np.radians(path)))[:, None]
    shown = np.degrees(ContinuousAngles().feed(euler, np.arange(len(path)))[:, 0, 2])
    assert shown[list(path).index(195.0)] == pytest.approx(195.0)
    assert shown[list(path).index(199.0)] == pytest.approx(199.0)
    assert shown[list(path).index(201.0)] == pytest.approx(-159.0)
    assert shown[60] == pytest.approx(-130.0)  # 230°
    back = 61  # the first frame of the way back (229°)
    assert shown[back + 229 - 170] == pytest.approx(-190.0)  # 170° on the way back
    assert shown[back + 229 - 161] == pytest.approx(-199.0)
    assert shown[back + 229 - 159] == pytest.approx(159.0)
    assert shown[-1] == pytest.approx(150.0)
    assert np.abs(shown).max() <= 200.0 + 1e-9


def test_the_elbow_flexion_returns_to_the_standard_range(trial):
    """After the forearms pass the vertical, away from it (pitch more than 15° from ±90°)
    every IMU reads its standard triple (up to the 20° band at ±180°)."""
    result, window = trial
    shown = ContinuousAngles().feed(result.euler_output, np.arange(len(result.euler_output)))
    standard = _standard(result.euler_output)
    finite = np.isfinite(standard).all(axis=2)
    away = finite & ~poorly_defined(standard[..., 1])
    clear = away & (np.abs(np.degrees(standard[..., [0, 2]])) < 160).all(axis=2)
    np.testing.assert_allclose(shown[clear], standard[clear], atol=1e-9)
    assert np.abs(np.degrees(shown[away][:, 1])).max() <= 90.0
    assert np.abs(np.degrees(shown[away][:, [0, 2]])).max() <= 200.0 + 1e-9
    assert clear[window][:, [5, 11]].sum() > 100  # the forearms come back from the vertical


def test_the_table_greys_roll_and_yaw_near_pitch_90(qtbot):
    from PyQt6.QtCore import Qt

    from bpms.filter.calibration import SensorCalibration
    from bpms.gui.data_table import VAGUE_TIP, ImuTableModel
    from bpms.io.calib_file import load_factory_calibration
    from bpms.pipeline.session import PoseSample

    model = ImuTableModel(SensorCalibration.from_table(load_factory_calibration()))
    euler = np.zeros((18, 3))
    euler[5, 1] = np.radians(84.0)  # the right forearm 6° from the vertical
    euler[4, 1] = np.radians(60.0)
    eye = np.broadcast_to(np.eye(3), (18, 3, 3))
    model.update(PoseSample(1, 0.0, b"", np.zeros((18, 9), np.int16), np.zeros((18, 3), bool),
                            euler, eye, eye, np.zeros(28), np.zeros((21, 3)), 0.0))
    tip, fg = Qt.ItemDataRole.ToolTipRole, Qt.ItemDataRole.ForegroundRole
    for col in (0, 2):  # roll, yaw
        assert model.data(model.index(5, col), tip) == VAGUE_TIP
        assert model.data(model.index(5, col), fg) is not None
        assert model.data(model.index(4, col), tip) is None
    assert model.data(model.index(5, 1), tip) is None  # pitch itself is well defined
