"""Data ▸ Pose calibration… in the desktop app (docs/gui.md, docs/pose-calibration.md): the
declared posture on the live simulated suit standing in the pressure-suit posture, and the
functional calibration (Start, Stop, its quality report) on a simulated recording played back;
both recorded by the session as ``reset_zero`` events, and the angles after each compared with
the simulated suit's own joint angles (10° rms mounting errors)."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.firmware.sim.session import simulate
from bpms.gui.layouts import LayoutStore
from bpms.gui.main_window import MainWindow
from bpms.gui.modes import ModeConfig, SessionRunner
from bpms.gui.pose_calibration_panel import CUSTOM, PoseCalibrationDialog
from bpms.io.options import Options

SIM = {"posture": "suit", "mounting_error_deg": 10.0}
ELBOW = JOINT_ANGLE_NAMES.index("elbow_r.flexion")


def _window(qtbot, tmp_path, config: ModeConfig) -> MainWindow:
    runner = SessionRunner(config, Options())
    runner.prepare()
    window = MainWindow(runner, layout_store=LayoutStore(tmp_path / "layouts"),
                        restore_last=False)
    qtbot.addWidget(window)
    window.show()
    return window


def _menu_dialog(window: MainWindow) -> PoseCalibrationDialog:
    """Data ▸ Pose calibration… as the user finds it."""
    data = next(a.menu() for a in window.menuBar().actions() if a.text() == "&Data")
    next(a for a in data.actions() if a.text() == "Pose calibration…").trigger()
    return window.menus.pose_calibration_dialog


def _rms_deg(samples, truth: np.ndarray) -> np.ndarray:
    """Per joint angle, the rms difference (°) between the samples and ``truth[index]``."""
    mine = np.array([s.joint_angles for s in samples])
    return np.degrees(np.sqrt(np.mean((mine - truth) ** 2, axis=0)))


def _adopted(events, source: str) -> int:
    """The frame the ``source`` calibration's adopted zero holds from (its recorded event)."""
    slots = [e.frame for e in events.drain() if e.kind == "reset_zero"
             and e.data.get("source") == source and e.data.get("adopt")]
    assert slots, f"no adopted {source} reset_zero event"
    return slots[-1]


def test_declared_posture_on_the_live_simulated_suit(qtbot, tmp_path):
    window = _window(qtbot, tmp_path, ModeConfig(mode="sim", sim_options=SIM,
                                                 recording_dir=str(tmp_path)))
    session = window.runner.session
    samples = session.subscribe(maxlen=5000, lossless=True)
    events = session.events.subscribe()
    dialog = _menu_dialog(window)
    panel = dialog.panel
    assert dialog.isVisible() and window.menus.pose_calibration_dialog is dialog
    # joint angles typed in: a bad name is refused in one line, nothing is asked of the session
    panel.preset_combo.setCurrentText(CUSTOM)
    panel.angles_edit.setText("elbow_x.flexion=15")
    panel.posture_button.click()
    assert "unknown joint angle" in panel.status
    panel.preset_combo.setCurrentText("suit")
    assert "elbow_r.flexion=15" in panel.angles_edit.text()
    window.panels.status_panel.data_button.click()  # Start Data
    # the subject stands still in the posture for the script's first 3 s; the automatic Reset
    # Zero (the neutral pose assumed) comes at 1 s
    qtbot.waitUntil(lambda: session.status().processed >= 70, timeout=20000)
    panel.posture_button.click()
    pressed_at = session.status().processed
    assert "declared posture (suit)" in panel.status
    qtbot.waitUntil(lambda: session.status().processed >= pressed_at + 60, timeout=20000)
    got = samples.drain()
    slot = _adopted(events, "posture")
    motion = window.runner.sim.arbiter.source
    first = next(j for j in range(len(motion)) if motion.frame(j) == got[0].frame)
    truth = simulate(seed=0, **SIM).truth.joint_angles  # the arbiter's whole (looped) motion

    def true(chosen):
        return truth[[(first + s.index) % len(truth) for s in chosen]]

    before = [s for s in got if s.index < slot - 30 and np.isfinite(s.joint_angles).all()]
    after = [s for s in got if slot <= s.index]
    assert len(before) > 5 and len(after) > 20
    rz = _rms_deg(before, true(before))
    assert rz[ELBOW] > 10.0, rz  # Reset Zero: off by the posture (15°)
    err = _rms_deg(after, true(after))
    assert err.max() < 2.5, dict(zip(JOINT_ANGLE_NAMES, err.round(2), strict=True))


@pytest.fixture(scope="module")
def functional_recording(tmp_path_factory):
    rec = simulate(seed=3, functional=True, duration_s=50.0, **SIM)
    return rec, rec.save_raw(tmp_path_factory.mktemp("functional") / "Raw_f_1.bpmsraw")


def test_functional_calibration_start_stop_and_report(qtbot, tmp_path, functional_recording):
    rec, raw = functional_recording
    window = _window(qtbot, tmp_path, ModeConfig(mode="file", path=str(raw)))
    session = window.runner.session
    samples = session.subscribe(maxlen=5000, lossless=True)
    events = session.events.subscribe()
    panel = _menu_dialog(window).panel
    panel.start_button.click()  # no data yet: it says so and waits
    assert "start the data first" in panel.status and panel.start_button.isEnabled()
    window.panels.status_panel.data_button.click()  # play (1×): the subject stands still 3 s
    qtbot.waitUntil(lambda: window.runner.data_on, timeout=5000)
    panel.seconds_spin.setValue(60.0)
    panel.start_button.click()
    assert panel.stop_button.isEnabled() and not panel.start_button.isEnabled()
    qtbot.waitUntil(lambda: session.functional_progress is not None, timeout=10000)
    window.runner.replay.set_speed(8.0)  # the movements 8× faster than they were made
    # the knee and elbow flexions and the arm swing are over ~28 s after the start
    qtbot.waitUntil(lambda: session.status().processed >= 31 * 50, timeout=30000)
    panel.stop_button.click()
    stopped_at = session.status().processed
    qtbot.waitUntil(lambda: panel.report_view.toPlainText() != "", timeout=20000)
    report = panel.report_view.toPlainText()
    assert "knee_r" in report and "elbow_l" in report and "missing" not in report
    assert "adopted" in panel.status and panel.start_button.isEnabled()
    qtbot.waitUntil(lambda: window.runner.replay.ended
                    and session.status().processed == len(rec), timeout=30000)
    slot = _adopted(events, "functional")
    assert 31 * 50 <= slot < stopped_at + 100  # Stop ended the movements (60 s allowed)
    after = [s for s in samples.drain() if s.index >= slot]
    assert len(after) > 100
    err = _rms_deg(after, rec.truth.joint_angles[[s.index for s in after]])
    assert err.max() < 3.0, dict(zip(JOINT_ANGLE_NAMES, err.round(2), strict=True))


def test_gui_refuses_a_bad_simulated_posture_in_one_line(capsys):
    """``bpms gui --sim --calibration-posture suit`` runs the simulated subject in the suit
    posture (ModeConfig.sim_options, as above); a posture it does not know: exit 2, one line."""
    from bpms.cli import main

    assert main(["gui", "--sim", "--calibration-posture", "bent"]) == 2
    err = capsys.readouterr().err
    assert "posture 'bent'" in err and "Traceback" not in err and len(err.splitlines()) == 1
    assert main(["gui", "--sim", "--subject", "height=1.8"]) == 2  # docs/subject.md
    err = capsys.readouterr().err
    assert "id is needed" in err and "Traceback" not in err and len(err.splitlines()) == 1
