"""Every key and mouse input of the 3D view's help table (``VIEW3D_BINDINGS``, what F1 shows)
applied to one view, and the framing of the whole body (run from run_3d_windows.py, under
Xvfb with QT_QPA_PLATFORM=xcb).

:func:`press_all` records per binding and press the camera and view state before and after
(and pixel counts of the frame after), and for views of several shapes the rows and columns
the figure covers; tests/test_gui_3d_gl.py judges them against the table's documented
effects.
"""

from __future__ import annotations

import sys
from pathlib import Path

from PyQt6.QtCore import QPoint, QPointF, Qt
from PyQt6.QtGui import QMouseEvent, QWheelEvent
from PyQt6.QtTest import QTest
from PyQt6.QtWidgets import QApplication

sys.path.insert(0, str(Path(__file__).parent))
from gl_pixels import extent, measure, pump

from bpms.gui.view3d_keys import VIEW3D_BINDINGS


def state(window) -> dict:
    view = window.view
    c = view.opts["center"]
    return {"center": [c.x(), c.y(), c.z()], "distance": view.opts["distance"],
            "elevation": view.opts["elevation"], "azimuth": view.opts["azimuth"],
            "fov": view.opts["fov"], "aligned": view.aligned, "axes": view.show_axes,
            "trail": view.trail_joint, "pelvis": [float(v) for v in view.last_points[0]],
            "resets": window.resets}


def mouse(window, kind: str) -> None:
    """One mouse gesture on the view's image: a drag (left, middle, Ctrl + left) or a wheel
    step (with or without Ctrl), as the events a real mouse sends."""
    target = window.image_view
    centre = QPointF(target.rect().center())
    if "wheel" in kind:
        mods = Qt.KeyboardModifier.ControlModifier if kind.startswith("Ctrl") \
            else Qt.KeyboardModifier.NoModifier
        event = QWheelEvent(centre, target.mapToGlobal(centre), QPoint(0, 0), QPoint(0, 240),
                            Qt.MouseButton.NoButton, mods, Qt.ScrollPhase.NoScrollPhase, False)
        QApplication.sendEvent(target, event)
        return
    button = Qt.MouseButton.MiddleButton if kind == "middle" else Qt.MouseButton.LeftButton
    mods = Qt.KeyboardModifier.ControlModifier if kind == "ctrl-left" \
        else Qt.KeyboardModifier.NoModifier
    end = centre + QPointF(40, 25)
    for etype, pos, buttons in ((QMouseEvent.Type.MouseButtonPress, centre, button),
                                (QMouseEvent.Type.MouseMove, end, button),
                                (QMouseEvent.Type.MouseButtonRelease, end,
                                 Qt.MouseButton.NoButton)):
        event = QMouseEvent(etype, pos, target.mapToGlobal(pos), button, buttons, mods)
        QApplication.sendEvent(target, event)


#: Keys pressed before the one under test, so that its effect shows (0 after a wider field
#: of view, r after another camera).
PREPARE = {Qt.Key.Key_0: (Qt.Key.Key_Minus,), Qt.Key.Key_R: (Qt.Key.Key_X, Qt.Key.Key_Equal,
                                                            Qt.Key.Key_Left)}
#: Commands whose effect the test reads from the image.
PIXELS = {"toggle_axes", "axis_view", "reset_view"}
#: Mouse rows of the table → the gestures that exercise them.
MOUSE = {"left drag": ("left",), "middle drag, or Ctrl + left drag": ("middle", "ctrl-left"),
         "wheel": ("wheel",), "Ctrl + wheel": ("Ctrl wheel",)}


def press_all(app: QApplication, window, out: Path) -> dict:
    """Every binding of the table on ``window`` (a shown 3D view with a pose), each from the
    home view; then ``r`` in views of other shapes. Returns {"presses": [...], "framing":
    [...]} and saves the framed views as OUTDIR/framed_*.png."""
    window.resets = 0
    window.resetZeroRequested.connect(lambda: setattr(window, "resets", window.resets + 1))
    view = window.view
    if view.show_axes:  # start from a plain view
        view.toggle_axes()
    window.resize(260, 330)  # small: each key renders a frame (software GL)
    pump(app, 0.2)
    window.view_resized()
    window.activateWindow()
    window.image_view.setFocus()
    pump(app, 0.1)
    results: dict = {"framing": [{"when": "first pose", **extent(view.grabFramebuffer())}]}
    presses = []
    for k, binding in enumerate(VIEW3D_BINDINGS):
        gestures = [(p, shift) for p, shift in binding.presses] or MOUSE[binding.inputs]
        for press in gestures:
            QTest.keyClick(window.image_view, "r")  # each press starts from the home view
            for key in PREPARE.get(press[0], ()) if isinstance(press, tuple) else ():
                QTest.keyClick(window.image_view, key)
            pump(app, 0.02)
            before = state(window)
            if isinstance(press, tuple):
                key, shift = press
                mods = Qt.KeyboardModifier.ShiftModifier if shift \
                    else Qt.KeyboardModifier.NoModifier
                QTest.keyClick(window.image_view, key, mods)
                name = f"{Qt.Key(key).name}{'+shift' if shift else ''}"
            else:
                mouse(window, press)
                name = press
            pump(app, 0.02)
            record = {"binding": k, "command": binding.command, "inputs": binding.inputs,
                      "press": name, "before": before, "after": state(window)}
            if binding.command in PIXELS:  # pixel counts only where the effect is in them
                image = view.grabFramebuffer()
                record.update(pixels=measure(image), extent=extent(image))
            presses.append(record)
            if binding.command in ("toggle_axes", "toggle_alignment"):
                QTest.keyClick(window.image_view, key)  # back as it was
            while view.trail_joint is not None:
                view.cycle_trail()
    results["presses"] = presses
    for width, height in ((600, 220), (220, 560)):
        window.resize(width, height)
        pump(app, 0.3)
        window.view_resized()
        QTest.keyClick(window.image_view, "r")
        pump(app, 0.1)
        image = view.grabFramebuffer()
        image.save(str(out / f"framed_{width}x{height}.png"))
        results["framing"].append({"when": f"r at {width}x{height}", **extent(image)})
    return results
