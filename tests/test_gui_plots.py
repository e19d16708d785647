"""Plot windows: the ring buffer, curve labels, pause/resume, legend click, view reset."""

from __future__ import annotations

import numpy as np
from PyQt6.QtCore import QPoint, Qt
from PyQt6.QtTest import QTest
from PyQt6.QtWidgets import QApplication

from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.gui.columns import human_joint_name
from bpms.gui.plot_data import RingBuffer, TickBlock, joint_angle_groups
from bpms.gui.plots import cells_plot


def _block(t0: float, n: int) -> TickBlock:
    t = t0 + np.arange(n) * 0.02
    raw = np.zeros((n, 18, 9), np.int16)
    raw[:, 0, 0] = np.arange(n)
    euler = np.zeros((n, 18, 3))
    euler[:, 8, 0] = np.radians(10.0)
    return TickBlock(t, raw, raw.astype(float), euler, np.zeros((n, 28)))


def test_ring_buffer_keeps_the_newest_rows_in_order():
    ring = RingBuffer(7, 2)
    everything = []
    rng = np.random.default_rng(1)
    for _ in range(40):
        n = int(rng.integers(0, 12))
        rows = rng.normal(size=(n, 2))
        everything.extend(rows)
        ring.extend(rows)
        expected = np.array(everything[-7:]).reshape(-1, 2)
        np.testing.assert_array_equal(ring.view(), expected)
    ring.clear()
    assert len(ring) == 0 and ring.view().shape == (0, 2)


def test_joint_angle_groups_hold_all_28_angles_once():
    labels = [spec.label for _, specs in joint_angle_groups("deg") for spec in specs]
    assert sorted(labels) == sorted(f"{human_joint_name(n)} [deg]" for n in JOINT_ANGLE_NAMES)
    assert len(set(labels)) == 28
    assert human_joint_name("hip_r.abduction") == "Right hip abduction"
    assert human_joint_name("torso.flexion") == "Torso flexion"


def test_plot_window_pause_legend_and_reset(qtbot):
    window = cells_plot([(0, 13), (8, 0)], "deg", history_s=2.0)  # raw acc x, roll
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    window.append(_block(0.0, 50))
    x, y = window.curves[1].getData()
    assert len(x) == 50 and np.allclose(y, 10.0)  # Euler in the window's unit (deg)
    window.pause_button.click()
    window.append(_block(1.0, 150))  # beyond the 2 s history while paused
    assert len(window.curves[0].getData()[0]) == 50  # drawing frozen
    window.pause_button.click()
    x, _ = window.curves[0].getData()
    assert len(x) == 100 and x[-1] == 1.0 + 149 * 0.02  # newest 2 s after resume
    window.append(_block(0.5, 5))  # time went back (seek): the history starts again
    assert len(window.buffer) == 5
    # legend click hides the curve
    legend = window.plots[0].legend
    sample, _label = legend.items[0]
    view = window.graphics
    centre = view.mapFromScene(sample.sceneBoundingRect().center())
    QTest.mouseClick(view.viewport(), Qt.MouseButton.LeftButton, pos=QPoint(centre.x(),
                                                                            centre.y()))
    qtbot.waitUntil(lambda: not window.curves[0].isVisible(), timeout=2000)
    # zoom, then double-click resets to auto-range
    box = window.plots[0].getViewBox()
    box.setRange(xRange=(0.0, 0.01), yRange=(0.0, 0.01))
    assert not box.autoRangeEnabled()[1]
    mid = view.mapFromScene(box.sceneBoundingRect().center())
    at = QPoint(mid.x(), mid.y())
    # the event sequence of a real double click: press, release, double-click, release
    QTest.mouseClick(view.viewport(), Qt.MouseButton.LeftButton, pos=at)
    QTest.mouseDClick(view.viewport(), Qt.MouseButton.LeftButton, pos=at)
    QTest.mouseRelease(view.viewport(), Qt.MouseButton.LeftButton, pos=at)
    qtbot.waitUntil(lambda: box.autoRangeEnabled()[1], timeout=2000)
    x_range = box.viewRange()[0]
    assert x_range[0] <= 0.5 and x_range[1] >= 0.5 + 4 * 0.02  # the data in view again


def test_peak_decimation_keeps_every_extreme_and_the_newest_row():
    from bpms.gui.plot_data import peak_decimate

    rng = np.random.default_rng(5)
    n = 3000
    data = np.column_stack([np.arange(n) * 0.02, rng.normal(size=n), rng.normal(size=n)])
    data[1234, 1] = 50.0  # a one-sample spike
    data[2000:2010, 2] = np.nan  # a gap
    out = peak_decimate(data, 400)
    assert len(out) <= 800
    assert out[:, 1].max() == 50.0 and np.nanmin(out[:, 1]) == data[:, 1].min()
    assert out[-1, 0] == data[-1, 0]  # the newest time is kept
    assert np.isnan(out[:, 2]).any()  # a bin fully inside the gap stays a gap
    assert np.all(np.diff(out[:, 0]) >= 0)
    assert len(peak_decimate(data[:500], 400)) == 500  # few rows: unchanged


def test_legend_name_click_toggles_and_view_all_keeps_following(qtbot):
    window = cells_plot([(8, 0), (8, 1)], "deg", history_s=20.0)
    qtbot.addWidget(window)
    window.resize(700, 400)
    window.show()
    qtbot.waitExposed(window)
    window.append(_block(0.0, 100))
    # a click on the legend's *name* (not its swatch) hides the curve, a second shows it
    legend = window.plots[0].legend
    _sample, label = legend.items[1]
    view = window.graphics
    centre = view.mapFromScene(label.sceneBoundingRect().center())
    at = QPoint(centre.x(), centre.y())
    QTest.mouseClick(view.viewport(), Qt.MouseButton.LeftButton, pos=at)
    qtbot.waitUntil(lambda: not window.curves[1].isVisible(), timeout=2000)
    assert window.curves[0].isVisible()
    qtbot.wait(QApplication.doubleClickInterval() + 50)
    QTest.mouseClick(view.viewport(), Qt.MouseButton.LeftButton, pos=at)
    qtbot.waitUntil(lambda: window.curves[1].isVisible(), timeout=2000)
    # zooming stops following; View All (the view menu) follows the new data again
    box = window.plots[0].getViewBox()
    box.setRange(xRange=(0.5, 0.6))
    window._manual_range()
    assert not window.follow and not window.follow_button.isChecked()
    box.menu.viewAll.trigger()
    assert window.follow and window.follow_button.isChecked()
    window.append(_block(2.0, 1000))  # 20 s later
    x_range = box.viewRange()[0]
    assert x_range[0] <= 21.9 <= x_range[1]  # the newest data are in view


def test_four_plots_tile_on_a_1920_by_1080_screen(qtbot):
    plots = [cells_plot([(k, 0), (k, 4)], "deg") for k in range(4)]
    for plot in plots:
        qtbot.addWidget(plot)
        # a quarter of the screen, less window decorations
        assert plot.minimumSizeHint().width() <= 1920 // 4
        assert plot.minimumSizeHint().height() <= (1080 - 80) // 2
