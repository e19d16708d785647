"""One door into a recording (issue 12.2): a recording made with a site calibration gives the
same angles through ``bpms filter``, ``bpms export matlab``, the Python API and GUI playback,
equal to the result with that calibration passed explicitly and unlike the factory result;
each path says which calibration it used."""

from __future__ import annotations

import numpy as np
import pytest
from waiting import wait_until

from bpms.cli import main
from bpms.filter.door import process_file
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from bpms.io.calib_file import FIELDS, load_factory_calibration, save_legacy
from bpms.io.filtered_file.reader import read_filtered

TOL = 1e-9  # rad


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """A suit whose IMU 0 magnetometer offset moved by 60 counts and IMU 5's gyro zero by 40:
    the simulated suit is built with that true calibration, its recording stores it."""
    table = load_factory_calibration().copy()
    table.values[0, FIELDS.index("MxMin")] += 60
    table.values[0, FIELDS.index("MxMax")] += 60
    table.values[5, FIELDS.index("GzAvg")] += 40
    table.source = "site"
    rec = simulate(duration_s=12.0, seed=7, calibration=table)
    folder = tmp_path_factory.mktemp("door")
    raw = rec.save_raw(folder / "Raw_site_001.bpmsraw")
    cfg = folder / "Calib_site.cfg"
    save_legacy(table, cfg)
    explicit = BodyPoseProcessor(table).process(rec.raw, rec.errors)  # reference: no door
    factory = BodyPoseProcessor().process(rec.raw, rec.errors)
    return rec, raw, cfg, explicit, factory


def _matlab(path):
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("%")]
    cols = lines[0].split(",")
    data = np.array([[float(c) for c in ln.split(",")] for ln in lines[1:]])
    euler = np.stack([data[:, [cols.index(f"imu{i}_{n}_sensor_{e}_rad") for e in
                               ("roll", "pitch", "yaw")]]
                      for i, n in enumerate(_imu_slugs())], axis=1)
    joints = data[:, cols.index("joint_elbow_r_flexion_rad"):]
    return euler, joints


def _imu_slugs():
    from bpms.io.frames import IMU_NAMES
    from bpms.io.names import slug

    return [slug(n) for n in IMU_NAMES]


def _close(got_euler, got_joints, ref, output=False):
    """``output``: the filtered file's angles, the output angles (segment angles after Reset
    Zero); else the sensor angles (the API's ``euler``, the MATLAB export)."""
    want = ref.euler_output if output else ref.euler
    np.testing.assert_allclose(got_euler, want, rtol=0, atol=TOL, equal_nan=True)
    np.testing.assert_allclose(got_joints, ref.joint_angles, rtol=0, atol=TOL, equal_nan=True)


def test_the_site_calibration_matters(site):
    _, _, _, explicit, factory = site
    yaw0 = np.abs(np.angle(np.exp(1j * (explicit.euler[:, 0, 2] - factory.euler[:, 0, 2]))))
    assert np.nanmax(yaw0) > np.radians(0.5)  # ≫ the 1e-9 rad agreement asked below
    assert np.nanmax(np.abs(explicit.joint_angles - factory.joint_angles)) > np.radians(0.1)


def test_bpms_filter_uses_the_header_and_says_so(site, tmp_path, capsys):
    _, raw, cfg, explicit, _ = site
    out = tmp_path / "f.csv"
    assert main(["filter", str(raw), "--joints", "-o", str(out)]) == 0
    assert "calibration: recording header; options: factory" in capsys.readouterr().err
    data = read_filtered(out)
    _close(data.euler, data.joint_angles, explicit, output=True)
    out2 = tmp_path / "f2.csv"
    assert main(["filter", str(raw), "--joints", "-o", str(out2), "--calibration",
                 str(cfg)]) == 0
    assert f"calibration: given ({cfg})" in capsys.readouterr().err
    data2 = read_filtered(out2)
    _close(data2.euler, data2.joint_angles, explicit, output=True)


def test_bpms_export_matlab_uses_the_header_and_says_so(site, tmp_path, capsys):
    _, raw, _, explicit, _ = site
    out = tmp_path / "m.csv"
    assert main(["export", "matlab", str(raw), "--radians", "-o", str(out)]) == 0
    assert "calibration: recording header" in capsys.readouterr().err
    _close(*_matlab(out), explicit)


def test_python_api_uses_the_header_and_says_so(site):
    _, raw, cfg, explicit, factory = site
    res = process_file(raw)
    assert res.calibration_source == "recording header"
    assert res.options_source == "factory"
    _close(res.euler, res.joint_angles, explicit)
    given = process_file(raw, cfg)  # explicit beats the header
    assert given.calibration_source == f"given ({cfg})"
    _close(given.euler, given.joint_angles, explicit)
    from bpms.io.calib_file import load_factory_calibration as factory_table

    forced = process_file(raw, factory_table())
    assert forced.calibration_source.startswith("given")
    _close(forced.euler, forced.joint_angles, factory)


def test_gui_playback_uses_the_header_and_says_so(site, tmp_path):
    """Playback as the GUI's file mode runs it (bpms.gui.modes.SessionRunner), with a
    filtered recording during playback."""
    from bpms.gui.modes import ModeConfig, SessionRunner
    from bpms.io.options import Options

    rec, raw, _, explicit, _ = site
    runner = SessionRunner(ModeConfig(mode="file", path=str(raw), recording_dir=str(tmp_path)),
                           Options())
    session = runner.prepare()
    assert runner.calibration_source == "recording header"
    status = session.start_logging(raw=False, filtered=True, name="play")
    runner.replay.set_speed(None)
    session.start()
    runner.replay.play()
    assert wait_until(lambda: session.status().processed >= len(rec.raw), 60)
    session.stop()
    data = read_filtered(status.filtered_path)
    assert len(data.t) == len(rec.raw) and not data.hole.any()
    _close(data.euler, data.joint_angles, explicit, output=True)


def test_gui_window_playback_uses_the_header(site, qtbot, tmp_path):
    """The same through the GUI's widgets (pytest-qt): file mode, filtered recording during
    playback at maximum speed from the first frame."""
    from bpms.gui.startup import StartupWindow

    rec, raw, _, explicit, _ = site
    startup = StartupWindow(recording_dir=str(tmp_path))
    qtbot.addWidget(startup)
    startup.select_mode("file")
    startup.file_edit.setText(str(raw))
    with qtbot.waitSignal(startup.mainWindowOpened, timeout=20000) as blocker:
        startup.go_button.click()
    window = blocker.args[0]
    qtbot.addWidget(window)
    assert window.runner.calibration_source == "recording header"
    window.panels.playback_panel.speed_combo.setCurrentIndex(6)  # as fast as possible
    panel = window.panels.file_panel
    panel.filtered_box.setChecked(True)
    panel.name_edit.setText("door")
    panel.log_button.click()
    if not window.runner.data_on:
        window.panels.status_panel.data_button.click()  # play
    session = window.runner.session
    qtbot.waitUntil(lambda: session.status().processed >= len(rec.raw), timeout=60000)
    panel.toggle_logging()  # stop (a click within 0.5 s of the last one would be ignored)
    qtbot.waitUntil(lambda: panel.last_recording is not None, timeout=15000)
    data = read_filtered(panel.last_recording.filtered_path)
    window.close()
    assert len(data.t) == len(rec.raw)
    _close(data.euler, data.joint_angles, explicit, output=True)
