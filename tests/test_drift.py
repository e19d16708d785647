"""Drift check (issue 19.5): the pauses are found, and a known gyro bias gives the drift
computed by hand (bias × time between the pauses, for a sensor that does not move)."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.analysis.drift import drift_report
from bpms.cli import main
from bpms.filter.calibration import GYRO_RAD_S_PER_COUNT
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.motion import Move, Still
from bpms.firmware.sim.session import simulate
from bpms.io.frames import encode_frames
from bpms.io.options import Options, save_options

BIAS_COUNTS = 10  # added to one raw gyro axis: 10 × 0.06957 °/s = 0.696 °/s
LEFT_THIGH, RIGHT_FOREARM = 12, 5
SCRIPT = [
    Still("still (start)", 4.0),
    Move("right arm forward raise", 2.0, {"sh_r_flex": 60}, hold=0.5),
    Move("right arm down", 2.0, hold=0.3),
    Move("elbow flexion", 1.5, {"elbow_r": 100, "elbow_l": 100}, hold=0.5),
    Move("elbows extended", 1.5, hold=0.3),
    Move("trunk twist", 2.0, {"torso_rot": 30}, hold=0.3),
    Move("trunk neutral", 2.0, hold=0.5),
    Still("still (end)", 4.0),
]


def _gyro_only() -> Options:
    """The original filter with every gain 0: pure gyro integration, so that nothing corrects
    the drift and the truth is bias × time."""
    options = Options()
    options.filter.kp_rollpitch = options.filter.ki_rollpitch = 0.0
    options.filter.kp_yaw = options.filter.ki_yaw = 0.0
    return options


@pytest.fixture(scope="module")
def biased():
    rec = simulate(seed=4, script=SCRIPT)
    raw = rec.raw.copy()
    raw[:, [LEFT_THIGH, RIGHT_FOREARM], 8] += BIAS_COUNTS  # gyro z counts of two IMUs
    rec.raw = raw
    rec.frames = encode_frames(raw, rec.errors)  # what save_raw writes
    return rec


def test_pauses_found_and_drift_equals_bias_times_time(biased):
    rec = biased
    proc = BodyPoseProcessor(rec.calibration, _gyro_only())
    res = proc.process(rec.raw, rec.errors)
    acc, _, gyr = proc.calibrate(rec.raw)
    report = drift_report(res.t, res.R, acc, gyr, proc.sensor_calibration.gravity, rec.errors)
    assert report.ok, report.problem
    # the pauses: the script's still phases (0–4 s and the last 4 s) and the slow first and
    # last instants of the neighbouring moves (minimum-jerk starts and holds)
    t_end_phase = rec.t[-1] - 4.0
    assert 3.0 < report.t_start <= 4.5
    assert t_end_phase - 1.0 <= report.t_end < t_end_phase + 2.0
    # by hand: a still sensor whose gyro reads b too much turns by |b| × T about a fixed axis
    truth = np.degrees(BIAS_COUNTS * GYRO_RAD_S_PER_COUNT) * (report.t_end - report.t_start)
    assert report.total_deg[LEFT_THIGH] == pytest.approx(truth, rel=0.05)
    # the moving forearm drifts by about as much (its bias axis tilts while the arm moves)
    assert report.total_deg[RIGHT_FOREARM] == pytest.approx(truth, rel=0.25)
    others = np.delete(report.total_deg, [LEFT_THIGH, RIGHT_FOREARM])
    assert np.nanmax(others) < 0.2 * truth  # gyro noise only
    assert np.allclose(report.total_deg ** 2, report.heading_deg ** 2
                       + report.inclination_deg ** 2, rtol=0.05, atol=0.05)
    # a filter that corrects with the accelerometer and magnetometer drifts far less
    options = Options()
    options.filter.algorithm = "observer"
    proc = BodyPoseProcessor(rec.calibration, options)
    res = proc.process(rec.raw, rec.errors)
    corrected = drift_report(res.t, res.R, acc, gyr, proc.sensor_calibration.gravity,
                             rec.errors)
    assert corrected.total_deg[LEFT_THIGH] < 0.5 * report.total_deg[LEFT_THIGH]


def test_drift_command_prints_and_writes_the_report(biased, tmp_path, capsys):
    path = tmp_path / "Raw_drift_001.bpmsraw"
    biased.save_raw(path)
    options = tmp_path / "gyro_only.toml"
    save_options(_gyro_only(), options)
    out = tmp_path / "drift.csv"
    assert main(["drift", str(path), "--options", str(options), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "start pause ends" in printed and "left" in printed.lower()
    rows = [line.split(",") for line in out.read_text().splitlines()[1:]]
    assert len(rows) == 18
    proc = BodyPoseProcessor(biased.calibration, _gyro_only())
    res = proc.process(biased.raw, biased.errors)
    acc, _, gyr = proc.calibrate(biased.raw)
    report = drift_report(res.t, res.R, acc, gyr, proc.sensor_calibration.gravity,
                          biased.errors)
    assert float(rows[LEFT_THIGH][2]) == pytest.approx(report.total_deg[LEFT_THIGH], abs=0.01)


def test_no_end_pause_is_one_clear_line(tmp_path, capsys):
    rec = simulate(seed=4, script=SCRIPT[:-1])  # ends while moving
    path = tmp_path / "Raw_nopause_001.bpmsraw"
    rec.save_raw(path)
    assert main(["drift", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    # where calibration and options came from (as every analysis command says), then one error
    assert err[0] == "bpms drift: calibration: recording header; options: factory"
    assert len(err) == 2 and "no still period near the end" in err[1]


def test_gui_drift_panel_after_playback_shows_the_hand_computed_drift(biased, tmp_path, qtbot):
    """The panel after playback (Data ▸ Drift check…): the left thigh's drift is bias × time
    (by hand, as above), the same figures as ``bpms drift``."""
    from bpms.gui.main_window import MainWindow
    from bpms.gui.modes import ModeConfig, SessionRunner

    path = tmp_path / "Raw_drift_gui_001.bpmsraw"
    biased.save_raw(path)
    runner = SessionRunner(ModeConfig(mode="file", path=str(path)), options=_gyro_only())
    runner.playback_options = _gyro_only()  # explicit, as the start-up window's options
    runner.prepare()
    window = MainWindow(runner, restore_last=False)
    qtbot.addWidget(window)
    panel = window.mode.open_drift_check()
    assert panel is not None
    qtbot.waitUntil(lambda: panel.report is not None or "no drift" in panel.summary.text(),
                    timeout=60000)
    report = panel.report
    assert report is not None and report.ok, panel.summary.text()
    truth = np.degrees(BIAS_COUNTS * GYRO_RAD_S_PER_COUNT) * (report.t_end - report.t_start)
    assert report.total_deg[LEFT_THIGH] == pytest.approx(truth, rel=0.05)
    shown = float(panel.table.item(LEFT_THIGH, 1).text())
    assert shown == pytest.approx(report.total_deg[LEFT_THIGH], abs=0.01)
    assert "start pause ends" in panel.summary.text()
    window.close()
