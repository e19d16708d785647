"""Windows that fit the screen they open on.

The main window opens inside the *available* geometry of its screen (the screen less its task
bar or dock): maximised on a screen smaller than :data:`MAXIMISE_BELOW` (1366 × 768 with a
40-px task bar gives 1366 × 728), else at :data:`PREFERRED_SIZE` or less, centred. A saved
geometry is restored only when it fits the available geometry of the screen it names (a
window saved on a larger or a detached monitor opens as if nothing were saved). Dialogs
(the F1 page, the options) are never taller or wider than the available geometry; their
content scrolls.

:func:`plan_geometry` is the rule, Qt-geometry only (no window, no screen): tests give it any
available geometry. :func:`place_window` applies it to a window.
"""

from __future__ import annotations

from dataclasses import dataclass

from PyQt6.QtCore import QByteArray, QDataStream, QRect, QSize, Qt
from PyQt6.QtGui import QGuiApplication
from PyQt6.QtWidgets import QWidget

#: The window opens maximised on a screen whose available geometry is narrower or lower.
MAXIMISE_BELOW = QSize(1600, 900)
#: The window's size on a larger screen, px (less when the screen is smaller).
PREFERRED_SIZE = QSize(1500, 860)
#: Room kept for the window manager's title bar and frame when a window is not maximised,
#: px (a dialog's frame is not counted in its size).
FRAME_ALLOWANCE = QSize(16, 40)


@dataclass(frozen=True)
class Placement:
    """Where a window opens: its frame ``geometry`` (screen coordinates) and whether it is
    ``maximised`` (then ``geometry`` is the available geometry, kept as its normal size)."""

    geometry: QRect
    maximised: bool
    restored: bool  # the saved geometry is used


def plan_geometry(available: QRect, saved: QRect | None = None,
                  saved_maximised: bool = False) -> Placement:
    """Where a main window opens on a screen with ``available`` geometry (px, screen
    coordinates): the ``saved`` frame geometry when it lies inside ``available`` (or the
    saved window was maximised), else maximised below :data:`MAXIMISE_BELOW`, else
    :data:`PREFERRED_SIZE` (at most ``available``) centred."""
    if saved is not None and saved.isValid():
        if saved_maximised:
            return Placement(QRect(available), True, True)
        if available.contains(saved):
            return Placement(QRect(saved), False, True)
    if available.width() < MAXIMISE_BELOW.width() \
            or available.height() < MAXIMISE_BELOW.height():
        return Placement(QRect(available), True, False)
    size = PREFERRED_SIZE.boundedTo(available.size())
    rect = QRect(0, 0, size.width(), size.height())
    rect.moveCenter(available.center())
    return Placement(rect, False, False)


#: ``QWidget.saveGeometry()``'s first word.
_GEOMETRY_MAGIC = 0x1D9D0CB


def saved_frame(saved: QByteArray) -> tuple[QRect, bool] | None:
    """(frame geometry, maximised) as written by ``QWidget.saveGeometry()`` — read as saved,
    not as ``restoreGeometry`` would clamp it to a screen — or None for other bytes."""
    if saved.size() < 4 + 2 + 2 + 16 + 16 + 4 + 1:
        return None
    stream = QDataStream(saved)
    stream.setByteOrder(QDataStream.ByteOrder.BigEndian)
    if stream.readUInt32() != _GEOMETRY_MAGIC:
        return None
    stream.readUInt16()  # major version
    stream.readUInt16()  # minor version
    frame = QRect()
    stream >> frame
    normal = QRect()
    stream >> normal
    stream.readInt32()  # screen number
    maximised = bool(stream.readUInt8())
    if stream.status() != QDataStream.Status.Ok or not frame.isValid():
        return None
    return frame, maximised


def available_geometry(widget: QWidget | None = None) -> QRect:
    """The available geometry of the screen ``widget`` is on (else the primary screen)."""
    screen = widget.screen() if widget is not None else None
    screen = screen or QGuiApplication.primaryScreen()
    return screen.availableGeometry() if screen is not None else QRect(0, 0, 1366, 728)


def place_window(window: QWidget, saved: QByteArray | None = None,
                 available: QRect | None = None) -> Placement:
    """Open ``window`` where :func:`plan_geometry` says (before it is shown): on its screen
    (``available`` overrides the screen's available geometry, as tests do), from the
    ``saved`` bytes of ``saveGeometry()`` when they fit."""
    area = QRect(available) if available is not None else None
    saved_rect, saved_max = None, False
    read = saved_frame(saved) if saved is not None else None
    if read is not None:
        saved_rect, saved_max = read
        if area is None and (screen := QGuiApplication.screenAt(saved_rect.center())):
            area = screen.availableGeometry()
    if area is None:
        area = available_geometry(window)
    plan = plan_geometry(area, saved_rect, saved_max)
    if plan.restored and not plan.maximised and saved is not None:
        window.restoreGeometry(saved)  # (the frame where it was saved)
    elif plan.maximised:
        window.setGeometry(plan.geometry)  # the normal size, and the layout's size at once
        window.setWindowState(window.windowState() | Qt.WindowState.WindowMaximized)
    else:
        window.setWindowState(window.windowState() & ~Qt.WindowState.WindowMaximized)
        window.setGeometry(plan.geometry)
    return plan


def fit_dialog(dialog: QWidget, width: int, height: int,
               available: QRect | None = None) -> QSize:
    """Size ``dialog`` to ``width`` × ``height`` px, at most the available geometry of its
    screen less :data:`FRAME_ALLOWANCE`; its content must scroll. Returns the size set."""
    area = available if available is not None else available_geometry(dialog.parentWidget())
    limit = area.size() - FRAME_ALLOWANCE
    size = QSize(width, height).boundedTo(limit)
    dialog.setMaximumSize(limit)
    dialog.resize(size)
    return size
