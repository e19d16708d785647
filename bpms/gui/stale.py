"""Data that is not live, marked as such: a translucent grey veil over a view with one line
on it — the state and the age of the last frame (:func:`bpms.gui.health.stale_text`).

The same overlay marks the data table, the joint-angle list, every plot and every 3D view, so
a frozen number never passes for a live one. The line sits at the bottom, off the table's first
row and the plots' titles. It ignores the mouse (the view underneath stays
usable: select, zoom, rotate) and goes away by itself when frames flow again.
"""

from __future__ import annotations

from PyQt6 import sip
from PyQt6.QtCore import QEvent, QObject, QRect, Qt
from PyQt6.QtGui import QColor, QPainter
from PyQt6.QtWidgets import QWidget

#: The veil: the view's own colours show through, lighter and greyer.
VEIL = QColor(225, 225, 225, 150)
BOX = QColor(60, 60, 60, 230)


class StaleOverlay(QWidget):
    """A veil over ``target`` (a child of it that follows its size). :meth:`show_text` with a
    line shows it, with None hides it."""

    def __init__(self, target: QWidget) -> None:
        super().__init__(target)
        self.setAttribute(Qt.WidgetAttribute.WA_TransparentForMouseEvents)
        self.setAttribute(Qt.WidgetAttribute.WA_NoSystemBackground)
        self.setFocusPolicy(Qt.FocusPolicy.NoFocus)
        self.text = ""
        target.installEventFilter(self)
        self.hide()

    @property
    def stale(self) -> bool:
        return bool(self.text)

    def show_text(self, text: str | None) -> None:
        if not text:
            if self.text:
                self.text = ""
                self.hide()
            return
        if text != self.text:
            self.text = text
            self.setToolTip("Not live: the values are the last ones received. "
                            "The marking goes away when frames arrive again.")
            self.update()
        if self.isHidden():
            parent = self.parentWidget()
            if parent is not None:
                self.setGeometry(parent.rect())
            self.show()
            self.raise_()

    def eventFilter(self, watched: QObject | None, event: QEvent | None) -> bool:
        # (the view and this veil may be on their way out: an event reaching the filter
        # then is left alone)
        if event is None or event.type() != QEvent.Type.Resize or sip.isdeleted(self) \
                or watched is None or sip.isdeleted(watched):
            return False
        parent = self.parentWidget()
        if watched is parent:
            self.setGeometry(parent.rect())
        return False

    def box_rect(self) -> QRect:
        """Where the line is drawn: bottom centre, clipped to the view's width (the top holds
        what is read first: the table's row 0, a plot's title)."""
        metrics = self.fontMetrics()
        width = min(self.width() - 8, metrics.horizontalAdvance(self.text) + 16)
        height = metrics.height() + 8
        return QRect((self.width() - width) // 2, max(0, self.height() - height - 4),
                     max(0, width), height)

    def paintEvent(self, event) -> None:
        painter = QPainter(self)
        painter.fillRect(self.rect(), VEIL)
        box = self.box_rect()
        painter.setPen(Qt.PenStyle.NoPen)
        painter.setBrush(BOX)
        painter.drawRoundedRect(box, 4, 4)
        painter.setPen(QColor("white"))
        text = self.fontMetrics().elidedText(self.text, Qt.TextElideMode.ElideRight,
                                             box.width() - 12)
        painter.drawText(box, Qt.AlignmentFlag.AlignCenter, text)
        painter.end()
