"""Angles that read right (issue 27.6): in the simulated script's elbow-flexion phase (the
forearms pass pitch 90°) no angle column the window shows by default jumps by more than 90°
between frames, and the readout is the same rotation as the filters' own angles."""

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
    assert _jumps_deg(shown[window]).max() < 90  # roll, pitch, yaw of all 18 IMUs
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
