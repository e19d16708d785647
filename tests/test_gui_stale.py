"""The stale-data veil's lifetime (issue 46.6) and its caption's place (issue 44.9).

`pytest tests/test_analysis_extract.py tests/test_gui_table.py` crashed: the data table sat
in a reference cycle (a lambda on its model's signal), so only a garbage collection freed it,
and one ran while Qt delivered an event to the table's viewport: the veil's event filter then
ran on deleted objects (RuntimeError, then a segmentation fault). The views now go when their
last reference does, and the filter leaves an event alone when its objects are going."""

from __future__ import annotations

import gc
import weakref

import numpy as np
from PyQt6 import sip
from PyQt6.QtCore import QEvent, QSize
from PyQt6.QtGui import QResizeEvent
from PyQt6.QtWidgets import QApplication, QWidget

from bpms.filter.calibration import SensorCalibration
from bpms.gui.data_table import DataTable, ImuTableModel, JointAngleModel, JointTable
from bpms.gui.plots import cells_plot, joint_angle_plot
from bpms.gui.stale import StaleOverlay
from bpms.io.calib_file import load_factory_calibration


def _made_and_dropped(make) -> list[weakref.ref]:
    """Weak references to what ``make()`` returns (a view and its veil), the view dropped."""
    view = make()
    refs = [weakref.ref(view), weakref.ref(view.stale)]
    view.stale.show_text("STOPPED · last frame 2 s ago")
    QApplication.processEvents()
    del view
    return refs


def test_views_go_with_their_last_reference_not_in_a_collection(qapp):
    calibration = SensorCalibration.from_table(load_factory_calibration())
    makers = {
        "data table": lambda: DataTable(ImuTableModel(calibration)),
        "joint-angle list": lambda: JointTable(JointAngleModel()),
        "joint-angle plot": joint_angle_plot,
        "cell plot": lambda: cells_plot([(5, 0), (5, 1)]),
    }
    enabled = gc.isenabled()
    gc.disable()  # what frees them must be their last reference going
    try:
        for name, make in makers.items():
            refs = _made_and_dropped(make)
            assert [r() is None for r in refs] == [True, True], name
    finally:
        if enabled:
            gc.enable()


def test_an_event_reaching_a_going_veil_is_left_alone(qtbot):
    view = QWidget()
    qtbot.addWidget(view)
    overlay = StaleOverlay(view)
    overlay.show_text("NO DATA")
    event = QResizeEvent(QSize(300, 200), QSize(100, 100))
    sip.delete(overlay)  # the C++ veil gone, its wrapper still called
    assert StaleOverlay.eventFilter(overlay, view, event) is False
    gone = QWidget()
    sip.delete(gone)
    live = StaleOverlay(QWidget())
    assert live.eventFilter(gone, event) is False
    assert live.eventFilter(view, QEvent(QEvent.Type.Polish)) is False


def test_the_caption_leaves_the_first_row_and_the_titles_free(qtbot):
    calibration = SensorCalibration.from_table(load_factory_calibration())
    table = DataTable(ImuTableModel(calibration))
    qtbot.addWidget(table)
    table.resize(900, 500)
    table.show()
    qtbot.waitExposed(table)
    table.stale.show_text("STOPPED · last frame 12 s ago")
    row0 = table.visualRect(table.model().index(0, 0))
    box = table.stale.box_rect()  # in the viewport's coordinates, as the row
    assert not box.intersects(row0.adjusted(-2000, 0, 2000, 0))
    assert box.bottom() <= table.viewport().height()
    plot = joint_angle_plot()
    qtbot.addWidget(plot)
    plot.resize(900, 600)
    plot.show()
    qtbot.waitExposed(plot)
    plot.stale.show_text("STOPPED")
    box = plot.stale.box_rect()
    viewport = plot.graphics.viewport()
    for item in plot.plots:  # each subplot's title row
        title = item.titleLabel.mapRectToScene(item.titleLabel.boundingRect())
        top = plot.graphics.mapFromScene(title).boundingRect()
        assert not box.intersects(top), item
    assert np.isfinite(box.width()) and box.bottom() <= viewport.height()
