"""The keys and mouse of the 3D views and the plots: one table each, read by the views (which
key runs which command) and by the F1 help page (what it says), so the two cannot disagree.

A :class:`Binding` is what the user does (``inputs``, as the help page shows it), what happens
(``action``), the command the view runs (``command``, a method name of the view, called with
the key; None for mouse input pyqtgraph handles itself) and the key presses that trigger it
(``presses``: ``(Qt key, Shift)`` pairs, Shift None = with or without; empty for mouse
input). docs/3d-views.md carries the same table
(tests/test_gui_keys.py compares them).
"""

from __future__ import annotations

from dataclasses import dataclass
from html import escape

from PyQt6.QtCore import Qt

K = Qt.Key


@dataclass(frozen=True)
class Binding:
    inputs: str
    action: str
    command: str | None = None
    presses: tuple[tuple[Qt.Key, bool | None], ...] = ()


def _keys(*keys: Qt.Key, shift: bool | None = None) -> tuple[tuple[Qt.Key, bool | None], ...]:
    return tuple((k, shift) for k in keys)


_ARROWS = (K.Key_Left, K.Key_Right, K.Key_Up, K.Key_Down)

#: The 3D view: mouse first, then keys (click the view first).
VIEW3D_BINDINGS: tuple[Binding, ...] = (
    Binding("left drag", "rotate the camera about its centre"),
    Binding("middle drag, or Ctrl + left drag", "pan"),
    Binding("wheel", "zoom (camera nearer / farther)"),
    Binding("Ctrl + wheel", "field of view"),
    Binding("arrow keys", "move the view 0.1 m left / right / up / down", "pan_step",
            _keys(*_ARROWS, shift=False)),
    Binding("Shift + arrow keys", "orbit: 5° about the vertical (left / right) or up / down",
            "orbit_step", _keys(*_ARROWS, shift=True)),
    Binding("c", "Reset Zero (stand in the calibration pose)", "reset_zero", _keys(K.Key_C)),
    Binding("v", "alignment off / on: the figure without / with Reset Zero", "toggle_alignment",
            _keys(K.Key_V)),
    Binding("p", "re-centre the camera on the pelvis", "recentre", _keys(K.Key_P)),
    Binding("= / - / 0", "narrower / wider / default (60°) field of view", "field_of_view",
            _keys(K.Key_Equal, K.Key_Plus, K.Key_Minus, K.Key_0)),
    Binding("x / y / z", "look along display x / along display y / down from above",
            "axis_view", _keys(K.Key_X, K.Key_Y, K.Key_Z)),
    Binding("d", "each IMU's axes on / off (x red, y green, z blue)", "toggle_axes",
            _keys(K.Key_D)),
    Binding("t", "trail of a joint: off → right wrist → left wrist → right toe → left toe → "
            "head", "cycle_trail", _keys(K.Key_T)),
    Binding("r", "reset the view: elevation 15°, azimuth 35°, 60° field of view, the whole body "
            "framed",
            "reset_view", _keys(K.Key_R)),
)

#: Plots (click the plot first for Space).
PLOT_BINDINGS: tuple[Binding, ...] = (
    Binding("Space", "pause / resume the drawing (the history keeps filling)", "toggle_pause",
            _keys(K.Key_Space)),
    Binding("double-click", "follow the newest data again (y auto-range)"),
    Binding("left drag", "zoom into a rectangle (Follow turns off)"),
    Binding("wheel", "zoom (Follow turns off)"),
    Binding("click a legend name", "hide / show that curve"),
    Binding("drag table cells onto a plot", "add them to it (onto empty space: a new plot)"),
)


def command_for(bindings: tuple[Binding, ...], key: int, shift: bool) -> str | None:
    """The command ``key`` (with or without Shift) runs, None when it is not bound."""
    for binding in bindings:
        for bound, with_shift in binding.presses:
            if bound == key and with_shift in (None, shift):
                return binding.command
    return None


def short_help(bindings: tuple[Binding, ...] = VIEW3D_BINDINGS) -> str:
    """One line for a tooltip: "arrows pan · c Reset Zero · …" (keys only)."""
    return " · ".join(f"{b.inputs} {b.action.split(':')[0].split(' (')[0]}"
                      for b in bindings if b.presses)


def help_html(title: str, bindings: tuple[Binding, ...]) -> str:
    """A titled two-column HTML table of ``bindings`` (the F1 page)."""
    rows = "".join(f"<tr><td><b>{escape(b.inputs, quote=False)}</b></td>"
                   f"<td>{escape(b.action, quote=False)}</td></tr>" for b in bindings)
    return (f"<h3>{escape(title, quote=False)}</h3><table cellspacing='2' cellpadding='2'>"
            f"{rows}</table>")
