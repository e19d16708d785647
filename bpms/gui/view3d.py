"""3D views of the solid avatar (pyqtgraph.opengl), any number of them, each independent;
docked in the main window or standing alone.

Display frame: the body model works in world NED (x north, y east, z down, metres, lowest foot
on z = 0). OpenGL views want z up, so every point is drawn as ``(x, -y, -z)``: display x =
north, display y = west, display z = up. That is a 180° rotation about north, so the frame
stays right-handed and the figure stands on the display's ground grid (z = 0).

The figure is one shaded mesh of capsules (:mod:`bpms.gui.avatar`: trunk, head, arms, hands,
legs, feet; right side blue, left orange, arms lighter than legs) over a floor grid, with its
shadow on the floor. The mesh of a pose is computed once and shared by every view.

Keys: x, y, z look along that display axis (from +x, from +y, from above); d toggles each
IMU's axes (a small triad at its segment's mid-point: red = segment x/forward, green = y/right,
blue = z/down, in segment axes after Reset Zero); r resets the view. The original suite's keys:
arrow keys pan, c = Reset Zero from the view, v = alignment (Reset Zero) off/on, p = re-centre
on the figure, = / - / 0 = narrower / wider / default field of view. t cycles the trail of one
joint (off, right wrist, left wrist, right toe, left toe, head). Shift + arrows orbit. The mouse
rotates (left drag), pans (middle drag, or Ctrl + left drag) and zooms (wheel), as pyqtgraph's
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
from collections import deque

import numpy as np
from PyQt6.QtCore import QSize, Qt, QTimer, pyqtSignal
from PyQt6.QtGui import (
    QGuiApplication,
    QImage,
    QKeyEvent,
    QOffscreenSurface,
    QOpenGLContext,
    QPainter,
    QResizeEvent,
)
from PyQt6.QtWidgets import QApplication, QLabel, QVBoxLayout, QWidget

from bpms.filter.body_model import POINT_INDEX, joint_positions
from bpms.gui import avatar
from bpms.gui.model import SessionModel
from bpms.gui.view3d_geometry import CALIBRATION_POSE, imu_axes_lines, to_display
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
KEYS_TEXT = ("arrows pan · c Reset Zero · v alignment · p re-centre · =/-/0 field of view · "
             "x/y/z axis view · d IMU axes · t trail · r reset")
#: The t key cycles the trail through these joints (None = no trail).
TRAIL_JOINTS: tuple[str | None, ...] = (None, "wrist_r", "wrist_l", "toe_r", "toe_l",
                                        "head_top")
TRAIL_S = 3.0
TRAIL_COLOUR = (0.0, 0.62, 0.45, 1.0)  # bluish green (Okabe & Ito)
DEFAULT_FOV = 60.0
PAN_STEP_M = 0.1

_shared_mesh: dict[str, object] = {}


def shared_meshdata(key: object, points: np.ndarray, waiting: bool) -> tuple[object, object]:
    """pyqtgraph MeshData of the body and its shadow for one pose, built once per pose and
    shared by every view (normals are computed once, inside the shared MeshData)."""
    from pyqtgraph.opengl import MeshData

    if _shared_mesh.get("key") is key and key is not None \
            and _shared_mesh.get("waiting") == waiting:
        return _shared_mesh["body"], _shared_mesh["shadow"]
    verts, normals = avatar.figure_mesh(points)
    shadow = avatar.shadow_vertices(verts)
    colours = avatar.WAITING_COLOURS if waiting else avatar.VERTEX_COLOURS
    body = MeshData(vertexes=verts, faces=avatar.FACES, vertexColors=colours)
    # MeshData would compute the normals from the faces in a Python loop (slower than the
    # whole frame); the capsules' exact normals go into its cache instead.
    body._vertexNormals = normals.astype(np.float32)
    flat = MeshData(vertexes=shadow, faces=avatar.FACES)
    _shared_mesh.update(key=key, waiting=waiting, body=body, shadow=flat)
    return body, flat


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

    class AvatarGL(gl.GLViewWidget):
        resetZeroKey = pyqtSignal()  # c
        changed = pyqtSignal()  # v, t: what the status line says changed

        def __init__(self) -> None:
            super().__init__()
            self.last_sample: PoseSample | None = None
            self._programs: dict[object, object] = {}
            self.show_axes = False
            self.aligned = True  # v: False shows the figure without Reset Zero
            self.waiting = True
            self.trail_joint: str | None = None
            self.trail: deque[np.ndarray] = deque(maxlen=round(TRAIL_S * 50))
            self.paint_s = 0.0  # smoothed paintGL time, s
            self.paints = 0  # frames painted (bench/gui.py)
            self.last_points: np.ndarray | None = None
            grid = gl.GLGridItem()
            grid.setSize(6, 6)
            grid.setSpacing(0.5, 0.5)
            grid.setColor((95, 95, 120, 255))  # bluish: never mistaken for the grey figure
            self.addItem(grid)
            self.shadow = gl.GLMeshItem(smooth=False, computeNormals=False, shader=None,
                                        color=avatar.SHADOW, glOptions="opaque")
            self.body = gl.GLMeshItem(smooth=True, computeNormals=True, shader="shaded",
                                      glOptions="opaque")
            self.axes = gl.GLLinePlotItem(mode="lines", width=2.0, antialias=True)
            self.axes.setVisible(False)
            self.trail_item = gl.GLLinePlotItem(mode="line_strip", width=2.0,
                                                color=TRAIL_COLOUR, antialias=True)
            self.trail_item.setVisible(False)
            for item in (self.shadow, self.body, self.axes, self.trail_item):
                self.addItem(item)
            self.opts["fov"] = DEFAULT_FOV
            self.reset_view()
            self.show_pose(None)

        # -- drawing ---------------------------------------------------------------------
        def show_pose(self, sample: PoseSample | None) -> None:
            C = None if sample is None else sample.C
            if sample is not None and not self.aligned:
                pos = joint_positions(np.asarray(sample.R))
            else:
                pos = None if sample is None else sample.joint_positions
            self.waiting = pos is None or not np.isfinite(pos).any()
            points = to_display(CALIBRATION_POSE if self.waiting else pos)
            self.last_points = points
            self.last_sample = sample
            # the aligned figure of a sample is the same in every view: share its mesh
            key = sample if self.aligned else None
            body, shadow = shared_meshdata(key, points, self.waiting)
            self.body.setMeshData(meshdata=body)
            self.shadow.setMeshData(meshdata=shadow)
            if C is not None and not self.waiting:
                axes, axis_colours = imu_axes_lines(points, np.asarray(C))
                self.axes.setData(pos=axes, color=axis_colours)
                self.axes.setVisible(self.show_axes and len(axes) > 0)
            else:
                self.axes.setVisible(False)
            self._draw_trail()

        def add_to_trail(self, samples: list[PoseSample]) -> None:
            if self.trail_joint is None:
                return
            k = POINT_INDEX[self.trail_joint]
            for sample in samples:
                p = sample.joint_positions[k]
                if np.isfinite(p).all():
                    self.trail.append(to_display(p))

        def _draw_trail(self) -> None:
            if self.trail_joint is None or len(self.trail) < 2 or self.waiting:
                self.trail_item.setVisible(False)
                return
            self.trail_item.setData(pos=np.array(self.trail))
            self.trail_item.setVisible(True)

        def cycle_trail(self) -> str | None:
            k = TRAIL_JOINTS.index(self.trail_joint)
            self.trail_joint = TRAIL_JOINTS[(k + 1) % len(TRAIL_JOINTS)]
            self.trail.clear()
            self._draw_trail()
            return self.trail_joint

        # -- camera and keys -------------------------------------------------------------
        def reset_view(self) -> None:
            elevation, azimuth = HOME_VIEW
            self.opts["fov"] = DEFAULT_FOV
            self.look(elevation, azimuth)

        def look(self, elevation: float, azimuth: float) -> None:
            from pyqtgraph import Vector

            self.setCameraPosition(pos=Vector(*VIEW_CENTRE), distance=VIEW_DISTANCE_M,
                                   elevation=elevation, azimuth=azimuth)

        def recentre(self) -> None:
            """p: the camera looks at the figure's pelvis (mid-height)."""
            from pyqtgraph import Vector

            if self.last_points is not None and np.isfinite(self.last_points[0]).all():
                x, y, z = self.last_points[0]
                self.setCameraPosition(pos=Vector(float(x), float(y), float(z)))

        def set_fov(self, fov: float) -> None:
            self.opts["fov"] = float(min(max(fov, 10.0), 120.0))
            self.update()

        def toggle_axes(self) -> None:
            self.show_axes = not self.show_axes
            self.axes.setVisible(self.show_axes and not self.waiting)

        def keyPressEvent(self, ev: QKeyEvent | None) -> None:
            if ev is None:
                return
            key, text = ev.key(), ev.text().lower()
            shift = bool(ev.modifiers() & Qt.KeyboardModifier.ShiftModifier)
            pans = {Qt.Key.Key_Left: (PAN_STEP_M, 0.0), Qt.Key.Key_Right: (-PAN_STEP_M, 0.0),
                    Qt.Key.Key_Up: (0.0, -PAN_STEP_M), Qt.Key.Key_Down: (0.0, PAN_STEP_M)}
            if key in pans and not shift:
                dx, dz = pans[key]
                self.pan(dx, 0.0, dz, relative="view-upright")
            elif text in AXIS_VIEWS:
                self.look(*AXIS_VIEWS[text])
            elif text == "d":
                self.toggle_axes()
            elif text == "r":
                self.reset_view()
            elif text == "p":
                self.recentre()
            elif text in ("=", "+"):
                self.set_fov(self.opts["fov"] / 1.2)
            elif text == "-":
                self.set_fov(self.opts["fov"] * 1.2)
            elif text == "0":
                self.set_fov(DEFAULT_FOV)
            elif text == "c":
                self.resetZeroKey.emit()
            elif text == "v":
                self.aligned = not self.aligned
                self.show_pose(self.last_sample)
                self.changed.emit()
            elif text == "t":
                self.cycle_trail()
                self.changed.emit()
            else:
                super().keyPressEvent(ev)  # Shift + arrows orbit, as pyqtgraph does
                return
            ev.accept()

        def initializeGL(self) -> None:
            # A second initialisation means Qt gave this widget a new context (it moved to
            # another top-level window: a dock floated or docked again). Its items' shader
            # programs and buffers belong to the old one, so it stops drawing and the owner
            # replaces it (View3DWindow.rebuild_view).
            self.stale = getattr(self, "_initialised", False)
            self._initialised = True
            if not self.stale:
                super().initializeGL()

        def paintGL(self, *args: object, **kwargs: object) -> None:
            # Never draw without a valid context (e.g. a window torn down mid-frame).
            context = self.context()
            if not self.isValid() or context is None or not context.isValid() \
                    or getattr(self, "stale", False):
                return
            start = time.perf_counter()
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
            spent = time.perf_counter() - start
            self.paints += 1
            self.paint_s = spent if self.paint_s == 0.0 else 0.8 * self.paint_s + 0.2 * spent

    return AvatarGL()


class ImageView(QWidget):
    """Shows the newest rendered frame; hands keys, mouse and wheel to the 3D view."""

    def __init__(self, owner: View3DWindow) -> None:
        super().__init__(owner)
        self.owner = owner
        self.image: QImage | None = None
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.setMinimumSize(120, 120)
        self.setAttribute(Qt.WidgetAttribute.WA_OpaquePaintEvent)

    def set_image(self, image: QImage) -> None:
        self.image = image
        self.update()

    def paintEvent(self, event) -> None:
        painter = QPainter(self)
        if self.image is None or self.image.isNull():
            painter.fillRect(self.rect(), Qt.GlobalColor.black)
        else:
            painter.drawImage(self.rect(), self.image)
        painter.end()

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        self.owner.view_resized()

    def _forward(self, name: str, event) -> None:
        view = self.owner.view
        if view is not None:
            getattr(view, name)(event)
            self.owner.render()

    def keyPressEvent(self, event) -> None:
        self._forward("keyPressEvent", event)

    def mousePressEvent(self, event) -> None:
        self.setFocus()
        self._forward("mousePressEvent", event)

    def mouseMoveEvent(self, event) -> None:
        self._forward("mouseMoveEvent", event)

    def mouseReleaseEvent(self, event) -> None:
        self._forward("mouseReleaseEvent", event)

    def wheelEvent(self, event) -> None:
        self._forward("wheelEvent", event)


class View3DWindow(QWidget):
    """A 3D view following a :class:`SessionModel` (redrawn per display tick): a top-level
    window, or the content of a main-window dock. ``resetZeroRequested`` is emitted by the c
    key (without a receiver the view asks the session itself).

    The GL view is never shown: it renders off-screen (its own context, its own framebuffer)
    and the frame is painted as an image. A window holding a visible GL widget is composed
    through OpenGL as a whole, every time anything in it repaints; with software GL that
    costs more than all plots together. Off-screen, a frame costs its own pixels only, and a
    dock can float or re-dock without the GL context changing under it.
    """

    resetZeroRequested = pyqtSignal()

    def __init__(self, model: SessionModel, parent: QWidget | None = None) -> None:
        super().__init__(parent, Qt.WindowType.Window)
        self.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        self.setWindowTitle("BPMS 3D view")
        self.resize(440, 580)
        self.setMinimumSize(160, 160)
        self.model = model
        self.view: QWidget | None = None
        self.image_view: ImageView | None = None
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self.status = QLabel(self)
        self.status.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.status.setMinimumWidth(10)
        problem = opengl_problem()
        if problem is None:
            try:
                self.view = _make_gl_view()
            except Exception as exc:  # a broken driver must not take the app down
                problem = f"the 3D view could not be created ({type(exc).__name__}: {exc})"
                log.warning("3D view: %s", problem)
        if self.view is not None:
            self.image_view = ImageView(self)
            layout.addWidget(self.image_view, 1)
            self.status.setToolTip(KEYS_TEXT)
            self.image_view.setToolTip(KEYS_TEXT)
            layout.addWidget(self.status)
            self.setFocusProxy(self.image_view)
            self.view.resetZeroKey.connect(self.request_reset_zero)
            self.view.changed.connect(self._show_status)
        else:
            self.status.setWordWrap(True)
            self.status.setText(f"3D view unavailable: OpenGL is not available ({problem}).\n"
                                "Tables, plots and recording work as usual.")
            layout.addWidget(self.status, 1)
        self.fallback_message = None if self.view is not None else self.status.text()
        self._pending: PoseSample | None = model.latest
        self._last_draw = 0.0
        self.frame_s = 0.0  # smoothed cost of one redraw (render + read back), s
        self._redraw = QTimer(self)
        self._redraw.setSingleShot(True)
        self._redraw.timeout.connect(self.draw_pending)
        self.draws = 0  # redraws done (bench/gui.py)
        if self.view is not None:
            _OPEN_WINDOWS.add(self)
        model.samplesArrived.connect(self.on_samples)
        self.on_samples([])

    def request_reset_zero(self) -> None:
        if self.receivers(self.resetZeroRequested):
            self.resetZeroRequested.emit()
        elif self.model.session is not None:
            self.model.session.reset_zero()

    @property
    def gl_view(self) -> QWidget | None:
        """The GLViewWidget (None in the fallback); ``grabFramebuffer()`` renders a frame."""
        return self.view

    def view_resized(self) -> None:
        if self.view is None or self.image_view is None:
            return
        size = self.image_view.size()
        if self.view.size() != size:
            self._resize_gl(size)
            self.render()

    def snapshot(self, width: int, height: int) -> QImage:
        """The current pose rendered at ``width`` × ``height`` pixels (screenshots)."""
        assert self.view is not None
        old = self.view.size()
        self._resize_gl(QSize(width, height))
        image = self.view.grabFramebuffer()
        self._resize_gl(old)
        return image

    def _resize_gl(self, size: QSize) -> None:
        old = self.view.size()
        self.view.resize(size)
        # A widget never shown gets no resize event from resize(); the GL widget needs one
        # to make its framebuffer the new size.
        QApplication.sendEvent(self.view, QResizeEvent(size, old))

    def render(self) -> None:
        """Render the GL view off-screen and show the frame."""
        if self.view is None or self.image_view is None or not self.isVisible():
            return
        start = time.perf_counter()
        image = self.view.grabFramebuffer()
        self.image_view.set_image(image)
        spent = time.perf_counter() - start
        self.frame_s = spent if self.frame_s == 0.0 else 0.8 * self.frame_s + 0.2 * spent

    def on_samples(self, samples: list[PoseSample]) -> None:
        """Slot of ``samplesArrived``: draw the newest sample, at most once per display tick
        and no more often than :data:`GL_TIME_BUDGET` allows (a late pose is drawn when due).
        A hidden view (a closed or tabbed-away dock) does not draw."""
        if self.view is None:
            return
        if samples:
            self._pending = samples[-1]
            self.view.add_to_trail(samples)
        if not self.isVisible():
            return
        wait = self._last_draw + self.min_interval_s() - time.monotonic()
        if wait <= 0:
            self.draw_pending()
        elif not self._redraw.isActive():
            self._redraw.start(max(1, round(wait * 1000)))

    def min_interval_s(self) -> float:
        """Shortest time between redraws so that all open 3D views together render for at
        most GL_TIME_BUDGET of the time, s."""
        if self.view is None:
            return 0.0
        return self.frame_s * max(1, len(_OPEN_WINDOWS)) / GL_TIME_BUDGET

    def showEvent(self, event) -> None:
        super().showEvent(event)
        if self.view is not None:
            self.view_resized()
            self.draw_pending()

    def draw_pending(self) -> None:
        self._redraw.stop()
        self._last_draw = time.monotonic()
        self.view.show_pose(self._pending)
        self.render()
        self.draws += 1
        self._show_status()

    def _show_status(self) -> None:
        view, sample = self.view, self._pending
        if view is None:
            return
        if view.waiting:
            text = WAITING_TEXT
        else:
            extras = [] if view.aligned else ["alignment OFF (v)"]
            if view.trail_joint:
                extras.append(f"trail {view.trail_joint}")
            text = "  ·  ".join([f"frame {sample.index}", *extras, "F1 keys"])
        if self.status.text() != text:
            self.status.setText(text)

    def closeEvent(self, event: object) -> None:
        _OPEN_WINDOWS.discard(self)
        self._redraw.stop()
        with contextlib.suppress(TypeError, RuntimeError):
            self.model.samplesArrived.disconnect(self.on_samples)
        if self.view is not None:
            self.view.deleteLater()  # a parentless widget: not deleted with this one
        super().closeEvent(event)


def open_3d_window(model: SessionModel, parent: QWidget | None = None) -> QWidget:
    """Open (show) a new independent 3D window following ``model``.

    It draws the newest sample's ``joint_positions [21, 3]`` (NED metres, lowest foot on the
    ground) as the solid avatar in the z-up display frame ``(x, -y, -z)`` (x north, y west,
    z up), redrawn on ``model.samplesArrived``; keys as in the module doc.
    Each call makes another top-level window. With ``parent`` the window closes with it;
    without, the caller keeps the returned reference. When OpenGL is unavailable the window
    shows a one-line reason instead of the figure.
    """
    window = View3DWindow(model, parent)
    window.show()
    if window.image_view is not None:
        window.image_view.setFocus()
    return window
