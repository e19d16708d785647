"""3D stick-figure windows (pyqtgraph.opengl), any number of them, each independent.

Display frame: the body model works in world NED (x north, y east, z down, metres, lowest foot
on z = 0). OpenGL views want z up, so every point is drawn as ``(x, -y, -z)``: display x =
north, display y = west, display z = up. That is a 180° rotation about north, so the frame
stays right-handed and the figure stands on the display's ground grid (z = 0).

Keys: x, y, z look along that display axis (from +x, from +y, from above); d toggles each
IMU's axes (a small triad at its segment's mid-point: red = segment x/forward, green = y/right,
blue = z/down, in segment axes after Reset Zero); r resets the view. The mouse rotates (left
drag), pans (middle drag, or Ctrl + left drag) and zooms (wheel), as pyqtgraph's
``GLViewWidget`` does.

When OpenGL is unavailable (pyqtgraph.opengl or PyOpenGL cannot be imported, no GL context
can be made, or Qt runs on a platform without GL such as ``offscreen``) the window shows a
plain message instead, so 2D tests and remote sessions never crash on it.
"""

from __future__ import annotations

import contextlib
import logging
import time
import weakref

import numpy as np
from PyQt6.QtCore import QEvent, Qt, QTimer
from PyQt6.QtGui import QGuiApplication, QKeyEvent, QOffscreenSurface, QOpenGLContext
from PyQt6.QtWidgets import QLabel, QVBoxLayout, QWidget

from bpms.filter.body_model import SEGMENTS
from bpms.gui.model import SessionModel
from bpms.gui.view3d_geometry import (
    CALIBRATION_POSE,
    JOINT_COLOUR,
    WAITING_COLOUR,
    figure_lines,
    imu_axes_lines,
    to_display,
)
from bpms.pipeline.session import PoseSample

log = logging.getLogger(__name__)

#: Camera target: about the figure's mid-height, metres (display frame).
VIEW_CENTRE = (0.0, 0.0, 0.9)
VIEW_DISTANCE_M = 3.0
#: (elevation, azimuth) in degrees for the default view and the x/y/z keys.
HOME_VIEW = (15.0, 35.0)
AXIS_VIEWS = {"x": (0.0, 0.0), "y": (0.0, 90.0), "z": (90.0, 0.0)}

#: Share of the GUI thread all 3D windows together may spend painting. With hardware GL a
#: paint takes ~1 ms and this never bites; with software GL (llvmpipe, Xvfb, VMs) a paint takes
#: 10-20 ms and the windows then redraw less often than the display timer, newest pose first.
GL_TIME_BUDGET = 0.4

WAITING_TEXT = "Waiting for Reset Zero: grey figure = calibration pose"


_gl_problem: str | None = None
_OPEN_WINDOWS: weakref.WeakSet[QWidget] = weakref.WeakSet()
_gl_checked = False


def opengl_problem() -> str | None:
    """Why 3D views cannot be drawn here (one line), or None when OpenGL works. Cached."""
    global _gl_problem, _gl_checked
    if _gl_checked:
        return _gl_problem
    _gl_checked = True
    platform = QGuiApplication.platformName()
    if platform in {"offscreen", "minimal", "vnc"}:
        # Qt's offscreen platform has no usable GL surface; pyqtgraph GL would crash there.
        _gl_problem = f"the Qt platform '{platform}' has no OpenGL display"
        return _gl_problem
    try:
        import pyqtgraph.opengl  # noqa: F401
    except Exception as exc:  # ImportError, or PyOpenGL failing to find libGL
        _gl_problem = f"pyqtgraph.opengl cannot be loaded ({type(exc).__name__}: {exc})"
        return _gl_problem
    context = QOpenGLContext()
    surface = QOffscreenSurface()
    surface.create()
    if not context.create() or not context.isValid():
        _gl_problem = "no OpenGL context could be created (graphics driver?)"
    elif not context.makeCurrent(surface):
        _gl_problem = "the OpenGL context cannot be made current"
    else:
        fmt = context.format()
        context.doneCurrent()
        if (fmt.majorVersion(), fmt.minorVersion()) < (2, 0):
            _gl_problem = f"OpenGL {fmt.majorVersion()}.{fmt.minorVersion()} is older than 2.0"
    if _gl_problem:
        log.warning("3D views disabled: %s", _gl_problem)
    return _gl_problem


def _make_gl_view() -> QWidget:
    """The GLViewWidget subclass, defined lazily so importing this module never needs GL."""
    import pyqtgraph.opengl as gl
    from pyqtgraph.opengl.shaders import ShaderProgram

    # pyqtgraph caches compiled shader programs per class (process-wide), but each window has
    # its own GL context; unless the app shares contexts, a program from the first window is
    # invalid in the second. So each view keeps its own programs and swaps them in to paint.
    cached_classes = (gl.GLLinePlotItem, gl.GLScatterPlotItem)

    class StickFigureGL(gl.GLViewWidget):
        def __init__(self) -> None:
            super().__init__()
            self._programs: dict[object, object] = {}
            self.show_axes = False
            self.waiting = True
            grid = gl.GLGridItem()
            grid.setSize(4, 4)
            grid.setSpacing(0.5, 0.5)
            grid.setColor((110, 110, 110, 255))
            self.addItem(grid)
            self.bones = gl.GLLinePlotItem(mode="lines", width=4.0, antialias=True)
            self.joints = gl.GLScatterPlotItem(size=9.0, pxMode=True, color=JOINT_COLOUR)
            self.axes = gl.GLLinePlotItem(mode="lines", width=2.0, antialias=True)
            self.axes.setVisible(False)
            for item in (self.bones, self.joints, self.axes):
                self.addItem(item)
            self.reset_view()
            self.show_pose(None)

        # -- drawing ---------------------------------------------------------------------
        def show_pose(self, sample: PoseSample | None) -> None:
            C = None if sample is None else sample.C
            pos = None if sample is None else sample.joint_positions
            self.waiting = pos is None or not np.isfinite(pos).any()
            if self.waiting:
                points = to_display(CALIBRATION_POSE)
                lines, colours = figure_lines(
                    points, np.tile(WAITING_COLOUR, (len(SEGMENTS), 1)))
                self.joints.setData(pos=points, color=WAITING_COLOUR)
            else:
                points = to_display(pos)
                lines, colours = figure_lines(points)
                self.joints.setData(pos=points[np.isfinite(points).all(axis=1)],
                                    color=JOINT_COLOUR)
            self.bones.setData(pos=lines, color=colours)
            if C is not None and not self.waiting:
                axes, axis_colours = imu_axes_lines(points, np.asarray(C))
                self.axes.setData(pos=axes, color=axis_colours)
                self.axes.setVisible(self.show_axes and len(axes) > 0)
            else:
                self.axes.setVisible(False)

        # -- camera and keys -------------------------------------------------------------
        def reset_view(self) -> None:
            elevation, azimuth = HOME_VIEW
            self.look(elevation, azimuth)

        def look(self, elevation: float, azimuth: float) -> None:
            from pyqtgraph import Vector

            self.setCameraPosition(pos=Vector(*VIEW_CENTRE), distance=VIEW_DISTANCE_M,
                                   elevation=elevation, azimuth=azimuth)

        def toggle_axes(self) -> None:
            self.show_axes = not self.show_axes
            self.axes.setVisible(self.show_axes and not self.waiting)

        def keyPressEvent(self, ev: QKeyEvent | None) -> None:
            text = ev.text().lower() if ev is not None else ""
            if text in AXIS_VIEWS:
                self.look(*AXIS_VIEWS[text])
            elif text == "d":
                self.toggle_axes()
            elif text == "r":
                self.reset_view()
            else:
                super().keyPressEvent(ev)
                return
            ev.accept()

        def paintGL(self, *args: object, **kwargs: object) -> None:
            # Never draw without a valid context (e.g. a window torn down mid-frame).
            context = self.context()
            if not self.isValid() or context is None or not context.isValid():
                return
            shared = list(ShaderProgram.names.values())
            saved = [(k, k._shaderProgram) for k in cached_classes]
            saved_shared = [(p, p.prog) for p in shared]
            for k in cached_classes:
                k._shaderProgram = self._programs.get(k)
            for p in shared:
                p.prog = self._programs.get(p)
            try:
                super().paintGL(*args, **kwargs)
            finally:
                for k, old in saved:
                    self._programs[k] = k._shaderProgram
                    k._shaderProgram = old
                for p, old in saved_shared:
                    self._programs[p] = p.prog
                    p.prog = old

    return StickFigureGL()


class View3DWindow(QWidget):
    """A top-level 3D window following a :class:`SessionModel` (redrawn per display tick)."""

    def __init__(self, model: SessionModel, parent: QWidget | None = None) -> None:
        super().__init__(parent, Qt.WindowType.Window)
        self.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        self.setWindowTitle("BPMS 3D view")
        self.resize(440, 580)
        self.model = model
        self.view: QWidget | None = None
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self.status = QLabel(self)
        self.status.setAlignment(Qt.AlignmentFlag.AlignCenter)
        problem = opengl_problem()
        if problem is None:
            try:
                self.view = _make_gl_view()
            except Exception as exc:  # a broken driver must not take the app down
                problem = f"the 3D view could not be created ({type(exc).__name__}: {exc})"
                log.warning("3D view: %s", problem)
        if self.view is not None:
            self.view.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
            layout.addWidget(self.view, 1)
            self.status.setToolTip("Keys: x/y/z view along an axis, d IMU axes, r reset view")
            layout.addWidget(self.status)
            self.setFocusProxy(self.view)
        else:
            self.status.setWordWrap(True)
            self.status.setText(f"3D view unavailable: OpenGL is not available ({problem}).\n"
                                "Tables, plots and recording work as usual.")
            layout.addWidget(self.status, 1)
        self.fallback_message = None if self.view is not None else self.status.text()
        self._pending: PoseSample | None = model.latest
        self._last_draw = 0.0
        self.frame_s = 0.0  # smoothed cost of one redraw (GL paint + composition), s
        self._redraw = QTimer(self)
        self._redraw.setSingleShot(True)
        self._redraw.timeout.connect(self.draw_pending)
        if self.view is not None:
            _OPEN_WINDOWS.add(self)
        model.samplesArrived.connect(self.on_samples)
        self.on_samples([])

    @property
    def gl_view(self) -> QWidget | None:
        """The GLViewWidget (None in the fallback)."""
        return self.view

    def on_samples(self, samples: list[PoseSample]) -> None:
        """Slot of ``samplesArrived``: draw the newest sample, at most once per display tick
        and no more often than :data:`GL_TIME_BUDGET` allows (a late pose is drawn when due)."""
        if self.view is None:
            return
        if samples:
            self._pending = samples[-1]
        wait = self._last_draw + self.min_interval_s() - time.monotonic()
        if wait <= 0:
            self.draw_pending()
        elif not self._redraw.isActive():
            self._redraw.start(max(1, round(wait * 1000)))

    def min_interval_s(self) -> float:
        """Shortest time between redraws so that all open 3D windows together paint for at
        most GL_TIME_BUDGET of the time, s."""
        if self.view is None:
            return 0.0
        return self.frame_s * max(1, len(_OPEN_WINDOWS)) / GL_TIME_BUDGET

    def event(self, event: QEvent | None) -> bool:
        # A top-level update renders the GL view and composes the window (with software GL
        # most of the cost is there, not in paintGL): time it for the redraw budget.
        if event is None or event.type() != QEvent.Type.UpdateRequest:
            return super().event(event)
        start = time.perf_counter()
        handled = super().event(event)
        spent = time.perf_counter() - start
        self.frame_s = spent if self.frame_s == 0.0 else 0.8 * self.frame_s + 0.2 * spent
        return handled

    def draw_pending(self) -> None:
        self._redraw.stop()
        self._last_draw = time.monotonic()
        sample = self._pending
        self.view.show_pose(sample)
        if self.view.waiting:
            self.status.setText(WAITING_TEXT)
        else:
            self.status.setText(f"frame {sample.index}  ·  x/y/z view along axis, "
                                "d IMU axes, r reset")

    def closeEvent(self, event: object) -> None:
        _OPEN_WINDOWS.discard(self)
        self._redraw.stop()
        with contextlib.suppress(TypeError, RuntimeError):
            self.model.samplesArrived.disconnect(self.on_samples)
        super().closeEvent(event)


def open_3d_window(model: SessionModel, parent: QWidget | None = None) -> QWidget:
    """Open (show) a new independent 3D stick-figure window following ``model``.

    It draws the newest sample's ``joint_positions [21, 3]`` (NED metres, lowest foot on the
    ground) in the z-up display frame ``(x, -y, -z)`` (x north, y west, z up), redrawn on
    ``model.samplesArrived``; keys x/y/z/d/r as in the module doc.
    Each call makes another top-level window. With ``parent`` the window closes with it;
    without, the caller keeps the returned reference. When OpenGL is unavailable the window
    shows a one-line reason instead of the figure.
    """
    window = View3DWindow(model, parent)
    window.show()
    if window.view is not None:
        window.view.setFocus()
    return window
