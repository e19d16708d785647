"""``bpms track --detector accel|gyro|auto`` (issue 19.3 wiring): on a simulated ±2 g walk
(accelerometer counts saturate as the chip does) the default picks the gyroscope detector from
the recording's header and finds the scripted heel strikes; the streamed gyro detector gives
the same strikes as the whole-array one."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.analysis.gait_events import SHANK_IMUS, gyro_heel_strikes, lateral_gyro_rate
from bpms.analysis.track import GyroTrackAccumulator
from bpms.cli import main
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.motion import Still, Walk
from bpms.firmware.sim.sensors import SensorModel
from bpms.firmware.sim.session import simulate
from bpms.io.options import Options

TOLERANCE_S = 0.1


@pytest.fixture(scope="module")
def walk_2g(tmp_path_factory):
    script = [Still("still (start)", 3.0), Walk(steps=12, step_period=0.35),
              Still("still (end)", 3.0)]
    rec = simulate(seed=1, script=script, model=SensorModel(accel_range_g=2))
    assert rec.raw[..., 0:3].max() == 511  # the heel strikes saturate the accelerometers
    path = tmp_path_factory.mktemp("walk2g") / "Raw_walk2g_001.bpmsraw"
    rec.save_raw(path)  # its header states the ±2 g range
    return rec, path


def _rows(path):
    lines = path.read_text().splitlines()
    return lines[0].split(","), [ln.split(",") for ln in lines[1:]]


def _recall(times, sides, truth) -> float:
    found = sum(any(abs(t - ts) <= TOLERANCE_S and s == side
                    for t, s in zip(times, sides, strict=True)) for ts, side in truth)
    return found / len(truth)


def test_auto_picks_the_gyro_detector_on_a_2g_recording(walk_2g, tmp_path, capsys):
    rec, path = walk_2g
    out = tmp_path / "auto.csv"
    assert main(["track", str(path), "--filter", "observer", "-o", str(out),
                 "--no-figure"]) == 0
    assert "gyroscope detector, recording at ±2 g" in capsys.readouterr().err
    cols, rows = _rows(out)
    assert cols[3] == "swing_peak_rad_s"
    truth = rec.truth.heel_strikes
    assert _recall([float(r[1]) for r in rows], [r[2] for r in rows], truth) >= 0.95
    assert len(rows) <= len(truth) + 2  # the stops of the first and last swing may count
    # the accelerometer detector on the same clipped recording finds fewer
    acc_out = tmp_path / "accel.csv"
    assert main(["track", str(path), "--filter", "observer", "--detector", "accel", "-o",
                 str(acc_out), "--no-figure"]) == 0
    acc_cols, acc_rows = _rows(acc_out)
    assert acc_cols[3] == "peak_g"
    assert (_recall([float(r[1]) for r in acc_rows], [r[2] for r in acc_rows], truth)
            < _recall([float(r[1]) for r in rows], [r[2] for r in rows], truth))


def test_streamed_gyro_strikes_equal_the_whole_array_detector(walk_2g):
    rec, _ = walk_2g
    options = Options()
    options.filter.algorithm = "observer"
    proc = BodyPoseProcessor(rec.calibration, options)
    res = proc.process(rec.raw, rec.errors)
    _, _, gyr = proc.calibrate(rec.raw)
    whole = gyro_heel_strikes(res.t, res.C, res.R, gyr)
    assert len(whole) >= 10
    for chunk in (7, 100, len(rec)):  # chunk borders everywhere, also inside a swing
        acc = GyroTrackAccumulator()
        for lo in range(0, len(rec), chunk):
            s = slice(lo, lo + chunk)
            rates = {side: lateral_gyro_rate(res.C[s, i], res.R[s, i], gyr[s, i])
                     for side, i in SHANK_IMUS.items()}
            acc.add(res.t[s], rates, res.joint_positions[s])
        track = acc.track()
        np.testing.assert_array_equal(track.times, whole.times)
        assert track.sides == whole.sides
        np.testing.assert_allclose(track.peaks, whole.swing_peak)
