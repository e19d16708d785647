"""Heel strikes per foot and the gyroscope gait-event detector on ±2 g-clipped data (19.3).

Truth: the simulated suit's scripted walk (heel strikes at known times, the pelvis path).
The simulated suit is set to ±2 g (older firmware's range), so its accelerometer counts saturate
at −512..511 (256 counts/g) as the chip does.
"""

from __future__ import annotations

import numpy as np
import pytest

from bpms.analysis.gait_events import (
    accel_detector_usable,
    accel_range_g,
    gyro_heel_strikes,
)
from bpms.analysis.track import FOOT_IMUS, heel_strikes, walked_path
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.motion import Still, Walk
from bpms.firmware.sim.sensors import SensorModel
from bpms.firmware.sim.session import simulate
from bpms.io.options import Options

STEP_S = 0.35
TOLERANCE_S = 0.1  # under a third of the step period: no strike can match its neighbour


@pytest.fixture(scope="module")
def fast_walk():
    script = [Still("still (start)", 3.0), Walk(steps=12, step_period=STEP_S),
              Still("still (end)", 3.0)]
    # the simulated suit saturates its accelerometers at ±2 g, as suits with older firmware
    rec = simulate(seed=1, script=script, model=SensorModel(accel_range_g=2))
    clipped = rec.raw
    assert clipped[..., 0:3].max() == 511  # the heel strikes did saturate
    p = rec.truth.pelvis_position
    start = rec.t.searchsorted(rec.truth.heel_strikes[0][0] - 0.5)
    walked = float(np.linalg.norm(p[-1, :2] - p[start, :2]))
    return rec, clipped, walked


def _recall(times, sides, truth) -> float:
    found = sum(any(abs(t - ts) <= TOLERANCE_S and s == side
                    for t, s in zip(times, sides, strict=True)) for ts, side in truth)
    return found / len(truth)


def _run(rec, raw, algorithm):
    options = Options()
    options.filter.algorithm = algorithm
    proc = BodyPoseProcessor(rec.calibration, options)
    res = proc.process(raw, rec.errors)
    acc, _, gyr = proc.calibrate(raw)
    accel_g = {side: np.linalg.norm(acc[:, i], axis=-1) / proc.sensor_calibration.gravity[i]
               for side, i in FOOT_IMUS.items()}
    return res, accel_g, gyr


def test_accel_detector_keeps_both_feet_at_fast_steps():
    """The minimum gap applies per foot: strikes 0.35 s apart alternating feet (0.7 s per
    foot, hand-built impacts of 2.5 g on a 1 g background) are all found with the 0.4 s gap;
    one gap across both feet (the old rule) kept every other strike."""
    dt, n = 0.02, 400
    t = np.arange(n) * dt
    accel_g = {"right": np.ones(n), "left": np.ones(n)}
    truth = []
    for k in range(12):
        ts = 1.0 + k * STEP_S
        side = "right" if k % 2 == 0 else "left"
        i = round(ts / dt)
        accel_g[side][i - 1:i + 2] = (1.8, 2.5, 1.8)
        truth.append((t[i], side))
    idx, sides, peaks = heel_strikes(accel_g, t, 2.0, 0.4)
    assert list(zip(t[idx], sides, strict=True)) == truth
    assert (peaks == 2.5).all()


def test_gyro_detector_on_2g_clipped_walk_and_walked_distance(fast_walk, capsys):
    rec, clipped, walked = fast_walk
    truth = rec.truth.heel_strikes
    figures = {}
    for algorithm in ("observer", "mahony"):
        res, accel_g, gyr = _run(rec, clipped, algorithm)
        # the accelerometer detector for comparison (peaks clip at the 2 g threshold; the
        # simulated fast swing also passes 2 g away from the strikes)
        idx, sides, _ = heel_strikes(accel_g, res.t, 2.0, 0.4)
        accel_recall = _recall(res.t[idx], sides, truth)
        ev = gyro_heel_strikes(res.t, res.C, res.R, gyr)
        recall = _recall(ev.times, ev.sides, truth)
        track = walked_path(res.t, accel_g, res.joint_positions,
                            strikes=(ev.index, ev.sides, ev.swing_peak))
        figures[algorithm] = (accel_recall, recall, track.length_m / walked - 1.0)
        assert recall >= 0.95, algorithm
    # the walked distance with the observer filter within 5 % of the truth
    assert abs(figures["observer"][2]) <= 0.05
    with capsys.disabled():
        for name, (a, g, e) in figures.items():
            print(f"\n±2 g walk, 0.35 s steps, {name}: accel detector {a:.0%}, gyro detector "
                  f"{g:.0%}, distance {e:+.1%} of {walked:.2f} m")


def test_accelerometer_range_from_header_and_options():
    options = Options()
    assert accel_range_g({"options": {"sensors": {"accel_range_g": 16.0}}}) == 16.0
    assert accel_range_g({"accel_range_g": 8}) == 8.0
    assert accel_range_g({"options": {"filter": {}}}) == 2.0  # a recording from before
    assert accel_range_g(None, options) == options.sensors.accel_range_g == 16.0
    assert not accel_detector_usable(2.0, 2.0)
    assert accel_detector_usable(16.0, 2.0)
