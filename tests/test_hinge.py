"""The hinge-joint heading constraint (bpms.filter.hinge, issue 30.3) on the simulated suit.

Truth is the simulator's: its sensor attitudes and the magnet it placed. The constraint runs as
a stage after the filter bank, fed by the disturbance flags (bpms.filter.disturbance).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from bpms.filter.hinge import HINGES, HingeConstraint, vertical_turn
from bpms.filter.rotations import heading_error
from bpms.firmware.sim.session import simulate

REPO = Path(__file__).resolve().parents[1]


def _bench():
    spec = importlib.util.spec_from_file_location("bench_accuracy_h",
                                                  REPO / "bench" / "accuracy.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_a_known_heading_error_of_one_segment_is_taken_out():
    """The true attitudes with a 20° heading error put on the right forearm from 20 s to 28 s
    (and its magnetometer flagged with that deviation): the constraint turns it back to within
    2° of the truth (the elbow moves in that window; the axes start from Reset Zero's guess),
    and turns nothing anywhere else."""
    rec = simulate(40.0, seed=2)
    R_true = rec.truth.R
    t = rec.t
    window = (t >= 20.0) & (t < 28.0)
    err = np.where(window, np.radians(20.0), 0.0)
    R = R_true.copy()
    R[:, 5] = vertical_turn(err) @ R_true[:, 5]
    # Reset Zero by hand: the calibration pose at 1 s, the hip's heading (docs/body-model.md)
    R0 = R[50]
    yaw0 = np.arctan2(R0[6, 1, 0], R0[6, 0, 0])
    C = R @ np.swapaxes(R0, -1, -2) @ vertical_turn(np.array(yaw0))
    flags = np.zeros(R.shape[:2], np.bool_)
    flags[window, 5] = True
    heading = np.where(flags, 20.0, 0.0)
    gyr = rec.truth.sensors.gyr
    R2, _ = HingeConstraint(0.02).apply(R, C, gyr, flags, heading)
    after = np.degrees(np.abs(heading_error(R2[:, 5], R_true[:, 5])))
    settled = window & (t >= 21.5)
    assert np.sqrt(np.mean(after[settled] ** 2)) < 2.0
    others = [i for i in range(18) if i not in (4, 5)]
    np.testing.assert_array_equal(R2[:, others], R[:, others])


def test_no_flag_no_turn():
    rec = simulate(20.0, seed=3)
    R = rec.truth.R
    turns = HingeConstraint(0.02).turns(R, R, rec.truth.sensors.gyr,
                                        np.zeros(R.shape[:2], np.bool_),
                                        np.zeros(R.shape[:2]))
    assert not turns.any()
    assert HINGES.tolist() == [[4, 5], [10, 11], [0, 2], [12, 14]]


@pytest.mark.parametrize("algorithm", ["mahony", "vqf"])
def test_the_constraint_halves_the_errors_in_the_magnet_window(algorithm):
    """The default magnet beside the right forearm, a filter whose heading follows the
    disturbed field: the forearm's heading error and the elbow's error (its relative
    orientation, sensor to sensor) in the magnet window at least halve; outside the window,
    and on the same script without a magnet, they rise by no more than 0.1°."""
    f = _bench().hinge_figures(algorithm)
    print(algorithm, f)
    assert f.head_in[1] <= 0.5 * f.head_in[0]
    assert f.elbow_in[1] <= 0.5 * f.elbow_in[0]
    assert f.head_out[1] <= f.head_out[0] + 0.1
    assert f.elbow_out[1] <= f.elbow_out[0] + 0.1
    assert f.clean_head[1] <= f.clean_head[0] + 0.1
