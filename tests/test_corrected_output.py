"""Reset Zero corrects the per-segment outputs (issue 12.5): after Reset Zero the per-IMU Euler
angles given out are segment orientations relative to the calibration pose; the sensor angles
stay available; a switch (option and the run-time toggle) chooses."""

from __future__ import annotations

import numpy as np
import pytest
from waiting import wait_until

from bpms.filter.door import process_file
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.motion import Move, Still
from bpms.firmware.sim.session import simulate
from bpms.io.options import Options
from bpms.io.rawfile import read_raw
from bpms.io.replay import ReplaySource
from bpms.pipeline.session import LiveSession

TURN_DEG = 90.0


@pytest.fixture(scope="module")
def turn():
    # The subject stands in the calibration pose facing north, then turns the whole body
    # 90° to the right about the vertical and stands still; the IMUs carry mounting errors.
    script = [Still("calibration pose", 3.0),
              Move("turn right", 2.0, {"pelvis_turn": TURN_DEG}, hold=3.0)]
    return simulate(seed=3, script=script, heading_deg=0.0)


def _options(**pose) -> Options:
    options = Options()
    options.pose.heading_reference = "mean"  # averages the mounting yaw errors
    for key, value in pose.items():
        setattr(options.pose, key, value)
    return options


def test_segment_yaw_is_the_turn_while_sensor_angles_differ(turn):
    result = BodyPoseProcessor(options=_options()).process(turn.raw, turn.errors)
    end = slice(len(result) - 50, len(result))  # the last second, standing turned
    out = np.degrees(result.euler_output[end])
    # every segment: level (roll, pitch ≈ 0) and turned by 90° from the calibration heading 0
    assert np.abs(out[..., :2]).max() < 1.0
    assert np.abs(out[..., 2] - TURN_DEG).max() < 3.0
    assert result.corrected[end].all()
    np.testing.assert_array_equal(result.euler_output, np.where(
        result.corrected[:, None, None], result.euler_segment, result.euler_sensor))
    # the sensor angles (uncorrected) carry the mounting errors: several degrees off
    sensor = np.degrees(result.euler_sensor[end])
    assert np.abs(sensor[..., :2]).max() > 3.0
    assert result.euler is result.euler_sensor


def test_option_off_gives_sensor_angles(turn):
    result = BodyPoseProcessor(options=_options(corrected_output=False)).process(
        turn.raw, turn.errors)
    assert not result.corrected.any()
    np.testing.assert_array_equal(result.euler_output, result.euler_sensor)


def test_toggle_at_run_time_applies_from_the_next_frame(turn):
    proc = BodyPoseProcessor(options=_options())
    first = proc.process(turn.raw[:200], turn.errors[:200])
    assert proc.set_corrected_output() is False  # the 'v' key: off
    second = proc.process(turn.raw[200:300], turn.errors[200:300])
    assert proc.set_corrected_output() is True  # and on again
    third = proc.process(turn.raw[300:], turn.errors[300:])
    assert first.corrected[-1] and not second.corrected.any() and third.corrected.all()
    np.testing.assert_array_equal(second.euler_output, second.euler_sensor)



def test_corrected_from_the_capture_frame_on_even_where_every_imu_fails(turn):
    # docs/filter.md: true from the first Reset Zero capture on; a frame whose outputs are
    # all NaN (every sensor failing since the stream started) is no exception
    proc = BodyPoseProcessor(options=_options(), auto_zero=False)
    before = proc.process(turn.raw[:40], turn.errors[:40])
    assert not before.corrected.any()
    failing = np.ones_like(turn.errors[40:60])
    dead = BodyPoseProcessor(options=_options(), auto_zero=False)
    dead.reset_zero()
    nothing = dead.process(turn.raw[40:60], failing)
    assert np.isnan(nothing.euler_output).all() and nothing.corrected.all()
    proc.reset_zero()  # captured at the next frame: the first of this batch
    after = proc.process(turn.raw[40:80], turn.errors[40:80])
    assert after.corrected.all() and len(after.zeros) == 1

def test_live_session_gives_corrected_angles_and_toggles_through_the_queue(turn, tmp_path):
    path = turn.save_raw(tmp_path / "Raw_turn_1.bpmsraw")
    recording = read_raw(path)
    session = LiveSession(ReplaySource(recording, speed=None), _options())
    sub = session.subscribe(maxlen=len(recording))
    with session:
        assert wait_until(lambda: session.status().processed == len(recording), 60)
    samples = sub.drain()
    reference = process_file(path, options=_options())
    np.testing.assert_array_equal(np.array([s.euler_output for s in samples]),
                                  reference.euler_output)
    np.testing.assert_array_equal(np.array([s.euler for s in samples]), reference.euler_sensor)
    session.set_corrected_output(False)
    session.settings.apply(session.processor)
    assert session.processor.corrected_output is False
