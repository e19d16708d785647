"""Playback against an optical file (docs/compare.md, "In the app"): the menu entry, and the
dock's curves — the chosen segment's angle by BPMS and by the optical export, and their
difference — equal the comparison's own figures; the optical curve is the sample's truth seen
through the estimated frames, so it follows the BPMS curve within the reported error."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

SAMPLES = Path(__file__).resolve().parents[1] / "docs" / "samples"
RAW = SAMPLES / "Raw_simulated_arm_raise.bpmsraw"
OPTICAL = SAMPLES / "optical_simulated_arm_raise.csv"

pytest.importorskip("pytestqt")


def test_playback_compares_with_an_optical_file(tmp_path, qtbot):
    from bpms.gui.compare_panel import open_comparison
    from bpms.gui.main_window import MainWindow
    from bpms.gui.modes import ModeConfig, SessionRunner
    from bpms.io.options import Options

    path = tmp_path / RAW.name
    shutil.copy(RAW, path)
    runner = SessionRunner(ModeConfig(mode="file", path=str(path)), options=Options())
    runner.playback_options = Options()
    runner.prepare()
    window = MainWindow(runner, restore_last=False)
    qtbot.addWidget(window)
    from PyQt6.QtWidgets import QMenu

    names = [a.text() for menu in window.menuBar().findChildren(QMenu) for a in menu.actions()]
    assert "Compare with optical file…" in names
    panel = open_comparison(window, str(OPTICAL))
    assert panel is not None
    qtbot.waitUntil(lambda: panel.result is not None or "no comparison" in panel.summary.text(),
                    timeout=60000)
    result = panel.result
    assert result is not None, panel.summary.text()
    assert abs(result.offset_s - 0.73) < 0.02
    assert panel.segment.count() == 6
    panel.segment.setCurrentIndex([imu for _, imu in result.pairs].index(4))  # right arm
    panel.angle.setCurrentIndex(1)  # pitch: the forward raise
    t, a, b, d = panel.series()
    shown_t, shown_a = panel.curves["bpms"].getData()
    np.testing.assert_array_equal(shown_t, t)
    np.testing.assert_array_equal(shown_a[np.isfinite(shown_a)], a[np.isfinite(a)])
    ok = np.isfinite(a) & np.isfinite(b)
    np.testing.assert_allclose(d[ok], a[ok] - b[ok], atol=1e-9)
    assert np.ptp(b[ok]) > 40  # the arm is raised by about 60°
    seg = result.segments[[imu for _, imu in result.pairs].index(4)]
    assert np.sqrt(np.mean(d[ok] ** 2)) <= seg.rmse_total + 0.5
    window.close()
