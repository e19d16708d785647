"""The calibration wizard walked through gyro, accel and mag with the simulated suit holding
the poses asked for (frames produced in-process, faster than real time)."""

from __future__ import annotations

import numpy as np
from PyQt6.QtGui import QFontMetrics
from PyQt6.QtWidgets import QStyle, QWizard

from bpms.firmware.sim.calibration_poses import (
    CalibrationSuit,
    ScriptedCalibrationSource,
    changed_table,
)
from bpms.gui.calibration_wizard import (
    PAGE_ACCEL,
    PAGE_GYRO,
    PAGE_MAG,
    PAGE_SUMMARY,
    CalibrationWizard,
)
from bpms.io.calib_file import load_calibration, load_factory_calibration, save_legacy
from bpms.io.calib_modern import load_modern, modern_path
from bpms.io.options import Options

IMUS = [2, 7]


def test_wizard_walks_through_all_three_steps(qtbot, tmp_path):
    out = tmp_path / "Calib.cfg"
    existing = load_factory_calibration()
    save_legacy(existing, out)
    truth = changed_table()
    source = ScriptedCalibrationSource(CalibrationSuit(truth, seed=2), speed=0, burst=100)
    wizard = CalibrationWizard(Options(), source=source, output=out, poll_ms=5)
    qtbot.addWidget(wizard)
    wizard.sim_move_gyro = True
    setup = wizard.setup
    for i, box in enumerate(setup.imu_boxes):
        box.setChecked(i in IMUS)
    setup.gyro_samples.setValue(200)
    setup.accel_samples.setValue(100)
    setup.sweep_s.setValue(60.0)
    setup.ellipsoid.setChecked(True)
    wizard.show()
    wizard.next()
    assert wizard.currentId() == PAGE_GYRO
    gyro = wizard.gyro_page
    assert not gyro.isComplete()
    gyro.start.click()  # the simulated suit is moved: refused
    qtbot.waitUntil(lambda: gyro.proc.state == "rejected", timeout=10_000)
    assert "Refused" in gyro.message.text() and gyro.start.isEnabled()
    gyro.start.click()
    qtbot.waitUntil(gyro.isComplete, timeout=10_000)
    wizard.next()
    assert wizard.currentId() == PAGE_ACCEL
    accel = wizard.accel_page
    assert "nan" not in accel.live.text() + accel.prompt.text()
    assert "IMU 2 Right Shank" in accel.prompt.text()
    while not accel.proc.done:
        step = accel.proc.index
        qtbot.waitUntil(lambda: accel.proc.at_extreme and accel.proc.still, timeout=10_000)
        accel.capture.click()
        qtbot.waitUntil(lambda s=step: accel.proc.index != s, timeout=10_000)
        assert "nan" not in accel.live.text()  # the next pose: nothing measured yet
    assert accel.isComplete() and accel.steps.count() == 12
    assert "counts" in accel.steps.item(0).text()
    wizard.next()
    assert wizard.currentId() == PAGE_MAG
    mag = wizard.mag_page
    _readable_headers(mag.table)
    mag.start.click()
    qtbot.waitUntil(mag.isComplete, timeout=20_000)
    assert mag.table.item(0, 4).text().endswith("%")
    assert mag.table.item(1, 0).text() == "7 Neck"
    wizard.next()
    assert wizard.currentId() == PAGE_SUMMARY
    summary = wizard.summary_page
    rows = summary.table.rowCount()  # changed values only (a value may come out the same)
    assert 2 * 12 <= rows <= 2 * 16
    assert {summary.table.item(r, 0).text() for r in range(rows)} == {"2 Right Shank",
                                                                      "7 Neck"}
    assert all("nan" not in summary.table.item(r, c).text() for r in range(rows)
               for c in range(5))
    _readable_headers(summary.table)
    assert "sphere residual" in summary.quality.text()
    wizard.button(QWizard.WizardButton.FinishButton).click()
    assert wizard.saved is not None
    new = load_calibration(out)
    others = [i for i in range(18) if i not in IMUS]
    assert np.array_equal(new.values[others], existing.values[others])
    for imu in IMUS:
        gravity = truth.values[imu, 0]
        assert abs(new.values[imu, 0] - gravity) < 0.01 * gravity
        assert np.abs(new.values[imu, 13:16] - truth.values[imu, 13:16]).max() < 2.0
    modern = load_modern(modern_path(out))
    assert set(modern.ellipsoids) == set(IMUS)


def _readable_headers(table) -> None:
    """Every header line fits its column with the style's margins (in bold when the header
    highlights the sections of selected cells)."""
    header = table.horizontalHeader()
    font = header.font()
    font.setBold(header.highlightSections())
    metrics = QFontMetrics(font)
    margin = header.style().pixelMetric(QStyle.PixelMetric.PM_HeaderMargin)
    for c in range(table.columnCount()):
        text = table.horizontalHeaderItem(c).text()
        width = max(metrics.horizontalAdvance(line) for line in text.split("\n"))
        assert width + 2 * margin <= header.sectionSize(c), (text, header.sectionSize(c))


def test_low_sphere_coverage_needs_a_sweep_again_or_a_confirmation(qtbot, tmp_path):
    source = ScriptedCalibrationSource(CalibrationSuit(changed_table(), seed=2), speed=0,
                                       burst=100)
    wizard = CalibrationWizard(Options(), source=source, output=tmp_path / "C.cfg", poll_ms=5)
    qtbot.addWidget(wizard)
    for name in ("gyro", "accel"):
        wizard.setup.sensor_boxes[name].setChecked(False)
    for i, box in enumerate(wizard.setup.imu_boxes):
        box.setChecked(i == 4)
    wizard.show()
    wizard.next()
    mag = wizard.mag_page
    next_button = wizard.button(QWizard.WizardButton.NextButton)
    mag.start.click()
    qtbot.waitUntil(lambda: mag.proc.frames > 100, timeout=10_000)
    mag.stop.click()  # stopped after 2 s of a 120 s sweep: a fraction of the sphere seen
    coverage = mag.proc.coverage()[4]
    assert coverage < mag.proc.min_coverage
    assert not mag.isComplete() and not next_button.isEnabled()
    assert mag.accept_low.isVisible()
    assert f"{100 * coverage:.0f} %" in mag.accept_low.text() and "80 %" in mag.accept_low.text()
    assert "4 Right Arm" in mag.accept_low.text()
    mag.accept_low.setChecked(True)  # the confirmation
    assert mag.isComplete() and next_button.isEnabled()
    mag.start.click()  # "Sweep again": a new sweep, the confirmation gone
    assert mag.proc.state == "sweeping" and mag.proc.frames == 0
    assert not mag.accept_low.isChecked() and not mag.accept_low.isVisible()
    assert not mag.isComplete()


def test_wizard_skips_unchosen_sensors(qtbot, tmp_path):
    source = ScriptedCalibrationSource(speed=0, burst=100)
    wizard = CalibrationWizard(Options(), source=source, output=tmp_path / "C.cfg", poll_ms=5)
    qtbot.addWidget(wizard)
    wizard.setup.sensor_boxes["gyro"].setChecked(False)
    wizard.setup.sensor_boxes["accel"].setChecked(False)
    for i, box in enumerate(wizard.setup.imu_boxes):
        box.setChecked(i == 0)
    wizard.show()
    wizard.next()
    assert wizard.currentId() == PAGE_MAG
    folder = tmp_path / "dir.cfg"
    folder.mkdir()
    wizard.back()
    wizard.setup.output.setText(str(folder))
    wizard.next()
    assert wizard.currentId() != PAGE_MAG and "folder" in wizard.setup.status.text()


def test_wizard_connects_in_the_background_and_reports_failure(qtbot, tmp_path):
    wizard = CalibrationWizard(Options(), output=tmp_path / "C.cfg", poll_ms=5)
    qtbot.addWidget(wizard)
    wizard.setup.use_sim.setChecked(True)
    wizard.show()
    wizard.next()
    qtbot.waitUntil(lambda: wizard.currentId() == PAGE_GYRO, timeout=10_000)
    assert isinstance(wizard.source, ScriptedCalibrationSource)
    wizard.reject()
    options = Options()
    options.serial.port = str(tmp_path / "no-such-port")
    bad = CalibrationWizard(options, output=tmp_path / "C.cfg", poll_ms=5)
    qtbot.addWidget(bad)
    bad.show()
    bad.next()
    assert "connecting" in bad.setup.status.text()
    qtbot.waitUntil(lambda: "Cannot connect" in bad.setup.status.text(), timeout=10_000)
    assert bad.currentId() == 0 and len(bad.setup.status.text().splitlines()) == 1


def test_every_page_can_be_entered_again_with_back_and_next(qtbot, tmp_path):
    """Issue 44.8: on each step, its action started, then Back and Next: the action is ready
    again (not grey) and the step can be completed; Back from the summary and Next again
    shows it again."""
    source = ScriptedCalibrationSource(CalibrationSuit(changed_table(), seed=3), speed=0,
                                       burst=100)
    wizard = CalibrationWizard(Options(), source=source, output=tmp_path / "Calib.cfg",
                               poll_ms=5)
    qtbot.addWidget(wizard)
    for i, box in enumerate(wizard.setup.imu_boxes):
        box.setChecked(i in IMUS)
    wizard.setup.gyro_samples.setValue(100)
    wizard.setup.accel_samples.setValue(50)
    wizard.setup.sweep_s.setValue(20.0)
    wizard.show()
    wizard.next()
    gyro, accel, mag = wizard.gyro_page, wizard.accel_page, wizard.mag_page

    def back_and_next(page_id: int) -> None:
        wizard.back()
        assert wizard.currentId() != page_id
        wizard.next()
        assert wizard.currentId() == page_id

    # gyro: Start pressed (collecting), Back, Next
    assert wizard.currentId() == PAGE_GYRO
    gyro.start.click()
    assert not gyro.start.isEnabled()
    back_and_next(PAGE_GYRO)
    assert gyro.start.isEnabled() and gyro.start.text() == "Start" and not gyro.isComplete()
    gyro.start.click()
    qtbot.waitUntil(gyro.isComplete, timeout=10_000)
    back_and_next(PAGE_GYRO)  # a done capture: entered again, it is measured again
    assert gyro.start.isEnabled()
    gyro.start.click()
    qtbot.waitUntil(gyro.isComplete, timeout=10_000)
    wizard.next()
    # accel: one pose captured, Back, Next: from the first pose again, Capture ready
    assert wizard.currentId() == PAGE_ACCEL
    qtbot.waitUntil(lambda: accel.proc.at_extreme and accel.proc.still, timeout=10_000)
    accel.capture.click()
    qtbot.waitUntil(lambda: accel.proc.index == 1, timeout=10_000)
    back_and_next(PAGE_ACCEL)
    assert accel.proc.index == 0 and accel.capture.isEnabled() and accel.skip.isEnabled()
    while not accel.proc.done:
        accel.skip.click()
    assert accel.isComplete()
    wizard.next()
    # mag: sweep under way, Back, Next: Start ready, Finish grey
    assert wizard.currentId() == PAGE_MAG
    mag.start.click()
    assert not mag.start.isEnabled() and mag.stop.isEnabled()
    back_and_next(PAGE_MAG)
    assert mag.start.isEnabled() and not mag.stop.isEnabled() and not mag.isComplete()
    mag.start.click()
    mag.stop.click()  # finish now
    qtbot.waitUntil(lambda: mag.proc.state == "done", timeout=10_000)
    if mag.low_coverage():
        mag.accept_low.setChecked(True)
    assert mag.isComplete()
    wizard.next()
    assert wizard.currentId() == PAGE_SUMMARY
    back_and_next(PAGE_SUMMARY)  # the mag page's result kept: Next is not blocked
    assert wizard.summary_page.table.rowCount() > 0
    assert wizard.button(QWizard.WizardButton.FinishButton).isEnabled()
    wizard.reject()
