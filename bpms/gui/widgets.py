"""The widget set-up that windows, panels and wizard pages share: a push button with its slot
and tooltip, a label that wraps, a spin box with its range, a row of widgets."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from PyQt6.QtCore import Qt
from PyQt6.QtWidgets import QDoubleSpinBox, QHBoxLayout, QLabel, QPushButton, QSpinBox, QWidget


def button(text: str, slot: Callable[..., Any] | None = None, tip: str = "", *,
           checkable: bool = False, checked: bool = False) -> QPushButton:
    """A push button: ``clicked`` goes to ``slot``, ``tip`` is its tooltip; a ``checkable``
    one starts ``checked``."""
    widget = QPushButton(text)
    if checkable:
        widget.setCheckable(True)
        widget.setChecked(checked)
    if tip:
        widget.setToolTip(tip)
    if slot is not None:
        widget.clicked.connect(slot)
    return widget


def label(text: str = "", *, wrap: bool = True, selectable: bool = False, style: str = "",
          tip: str = "") -> QLabel:
    """A label, word-wrapped unless ``wrap`` is False; ``selectable``: its text can be
    selected with the mouse (and copied); ``style`` its style sheet, ``tip`` its tooltip."""
    widget = QLabel(text)
    widget.setWordWrap(wrap)
    if selectable:
        widget.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
    if style:
        widget.setStyleSheet(style)
    if tip:
        widget.setToolTip(tip)
    return widget


def spin_box(low: float, high: float, value: float | None = None,
             suffix: str = "") -> QSpinBox | QDoubleSpinBox:
    """A spin box from ``low`` to ``high`` (of floats when ``low`` is a float) at ``value``,
    ``suffix`` after the number."""
    box = QDoubleSpinBox() if isinstance(low, float) else QSpinBox()
    box.setRange(low, high)
    if value is not None:
        box.setValue(value)
    if suffix:
        box.setSuffix(suffix)
    return box


def row(*items: QWidget | None, grow: QWidget | None = None) -> QHBoxLayout:
    """The ``items`` side by side (None: a stretch); ``grow`` takes the width left over."""
    layout = QHBoxLayout()
    for item in items:
        if item is None:
            layout.addStretch(1)
        else:
            layout.addWidget(item, 1 if item is grow else 0)
    return layout
