"""Dock widgets of the main window: Qt's QDockWidget, which moves, tabs, floats and closes
natively. Fixed panels keep their dock when closed (View menu brings them back); plots and 3D
views are dynamic: closing one deletes it.
"""

from __future__ import annotations

from PyQt6.QtCore import Qt
from PyQt6.QtWidgets import QDockWidget, QScrollArea, QWidget

_FEATURES = (QDockWidget.DockWidgetFeature.DockWidgetMovable
             | QDockWidget.DockWidgetFeature.DockWidgetFloatable
             | QDockWidget.DockWidgetFeature.DockWidgetClosable)


def make_dock(title: str, name: str, widget: QWidget, *, dynamic: bool = False,
              scroll: bool = False) -> QDockWidget:
    """A dock titled ``title`` holding ``widget``; ``name`` is its objectName (what saved
    layouts refer to). ``dynamic``: closing the dock deletes it (plots, 3D views).
    ``scroll``: the widget sits in a scroll area (side panels) that scrolls up and down only;
    the dock is never narrower than the widget's least width."""
    dock = QDockWidget(title)
    dock.setObjectName(name)
    dock.setFeatures(_FEATURES)
    dock.setAllowedAreas(Qt.DockWidgetArea.AllDockWidgetAreas)
    if scroll:
        area = QScrollArea()
        area.setWidget(widget)
        area.setWidgetResizable(True)
        area.setFrameShape(QScrollArea.Shape.NoFrame)
        # never sideways: the dock keeps the panel's least width (a layout saved in another
        # mode, whose panels are narrower, cannot squeeze it), and scrolls only up and down
        area.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        area.setMinimumWidth(widget.minimumSizeHint().width()
                             + area.verticalScrollBar().sizeHint().width() + 2)
        dock.setWidget(area)
    else:
        dock.setWidget(widget)
    if dynamic:
        dock.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
    return dock


def inner(dock: QDockWidget) -> QWidget | None:
    """The dock's own widget (inside the scroll area when there is one)."""
    widget = dock.widget()
    if isinstance(widget, QScrollArea):
        return widget.widget()
    return widget
