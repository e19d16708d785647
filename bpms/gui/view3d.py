"""3D views of the solid avatar (pyqtgraph.opengl), any number of them, each independent;
docked in the main window or standing alone.

Display frame: the body model works in world NED (x north, y east, z down, metres, lowest foot
on z = 0). OpenGL views want z up, so every point is drawn as ``(x, -y, -z)``: display x =
north, display y = west, display z = up. That is a 180° rotation about north, so the frame
stays right-handed and the figure stands on the display's ground grid (z = 0).

The figure is one shaded mesh of capsules (:mod:`bpms.gui.avatar`: trunk, head, arms, hands,
legs, feet; right side blue, left orange, arms lighter than legs) over a floor grid, with its
shadow on the floor. The mesh of a pose is computed once and shared by every view.

Keys and mouse: :data:`bpms.gui.view3d_keys.VIEW3D_BINDINGS`, the one table the views
dispatch from and the F1 page is made of. On opening and on ``r`` the camera frames the whole
body (:func:`bpms.gui.view3d_geometry.frame_camera`, for the view's current shape); while the
user has not moved the camera, a resize or the first real pose frames it again.

Data that is not live (link lost, paused, stopped) is veiled with the age of the last frame
(:mod:`bpms.gui.stale`, from ``SessionModel.healthChanged``).

When OpenGL is unavailable (pyqtgraph.opengl or PyOpenGL cannot be imported, no GL context
can be made, or Qt runs on a platform without GL such as ``offscreen``) the window shows a
plain message instead, so 2D tests and remote sessions never crash on it.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import time
import weakref

from PyQt6.QtCore import QSize, Qt, QTimer, pyqtSignal
from PyQt6.QtGui import (
    QGuiApplication,
    QImage,
    QOffscreenSurface,
    QOpenGLContext,
    QPainter,
    QResizeEvent,
)
from PyQt6.QtWidgets import QApplication, QLabel, QVBoxLayout, QWidget

from bpms.gui.health import Health, stale_text
from bpms.gui.model import SessionModel
from bpms.gui.stale import StaleOverlay
from bpms.gui.view3d_keys import VIEW3D_BINDINGS, short_help
from bpms.pipeline.session import PoseSample

log = logging.getLogger(__name__)

#: Share of the GUI thread all 3D windows together may spend painting. With hardware GL a
#: paint takes ~1 ms and this never bites; with software GL (llvmpipe, Xvfb, VMs) a paint takes
#: 10-20 ms and the windows then redraw less often than the display timer, newest pose first.
GL_TIME_BUDGET = 0.4

WAITING_TEXT = "Waiting for Reset Zero: grey figure = calibration pose"
KEYS_TEXT = short_help(VIEW3D_BINDINGS)

_OPEN_WINDOWS: weakref.WeakSet[QWidget] = weakref.WeakSet()


@functools.cache
def opengl_problem() -> str | None:
    """Why 3D views cannot be drawn here (one line), or None when OpenGL works. Cached."""
    platform = QGuiApplication.platformName()
    if platform in {"offscreen", "minimal", "vnc"}:
        # Qt's offscreen platform has no usable GL surface; pyqtgraph GL would crash there.
        return f"the Qt platform '{platform}' has no OpenGL display"
    try:
        import pyqtgraph.opengl  # noqa: F401
    except Exception as exc:  # ImportError, or PyOpenGL failing to find libGL
        return f"pyqtgraph.opengl cannot be loaded ({type(exc).__name__}: {exc})"
    context = QOpenGLContext()
    surface = QOffscreenSurface()
    surface.create()
    problem = None
    if not context.create() or not context.isValid():
        problem = "no OpenGL context could be created (graphics driver?)"
    elif not context.makeCurrent(surface):
        problem = "the OpenGL context cannot be made current"
    else:
        fmt = context.format()
        context.doneCurrent()
        if (fmt.majorVersion(), fmt.minorVersion()) < (2, 0):
            problem = f"OpenGL {fmt.majorVersion()}.{fmt.minorVersion()} is older than 2.0"
    if problem:
        log.warning("3D views disabled: %s", problem)
    return problem


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
                from bpms.gui.view3d_gl import make_gl_view

                self.view = make_gl_view()
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
        self.stale = StaleOverlay(self)
        model.samplesArrived.connect(self.on_samples)
        model.healthChanged.connect(self.show_health)
        self.on_samples([])
        if model.last_health is not None:
            self.show_health(model.last_health)

    def show_health(self, health: Health) -> None:
        """Veil the figure while the data is not live (link lost, paused, stopped)."""
        self.stale.show_text(stale_text(health))

    def view_settings(self) -> dict:
        """What a saved layout keeps of this view: the camera (centre, distance, elevation,
        azimuth, field of view, whether it frames the body), alignment, IMU axes, trail."""
        view = self.view
        if view is None:
            return {}
        c = view.opts["center"]
        return {"center": [c.x(), c.y(), c.z()], "distance": view.opts["distance"],
                "elevation": view.opts["elevation"], "azimuth": view.opts["azimuth"],
                "fov": view.opts["fov"], "framed": view.framed, "aligned": view.aligned,
                "axes": view.show_axes, "trail": view.trail_joint}

    def apply_view_settings(self, settings: dict) -> None:
        """The settings of :meth:`view_settings` (unknown or bad entries are ignored)."""
        view = self.view
        if view is None or not settings:
            return
        from bpms.gui.view3d_gl import TRAIL_JOINTS

        try:
            for key in ("distance", "elevation", "azimuth", "fov"):
                if key in settings:
                    view.opts[key] = float(settings[key])
            if "center" in settings:
                from pyqtgraph import Vector

                view.opts["center"] = Vector(*(float(v) for v in settings["center"]))
        except (TypeError, ValueError):
            log.warning("3D view: saved camera settings ignored (%r)", settings)
        view.framed = bool(settings.get("framed", False))
        if bool(settings.get("aligned", True)) != view.aligned:
            view.toggle_alignment()
        if bool(settings.get("axes", False)) != view.show_axes:
            view.toggle_axes()
        trail = settings.get("trail")
        if trail in TRAIL_JOINTS:
            while view.trail_joint != trail:
                view.cycle_trail()
        if view.framed:
            view.frame()
        view.update()
        self.draw_pending()

    def request_reset_zero(self) -> None:
        if self.receivers(self.resetZeroRequested):
            self.resetZeroRequested.emit()
        elif self.model.session is not None:
            self.model.session.reset_zero("3d-view")

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
        with contextlib.suppress(TypeError, RuntimeError):
            self.model.healthChanged.disconnect(self.show_health)
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
