"""The 3D view's OpenGL widget (pyqtgraph.opengl), built only when OpenGL works: the solid
avatar over a floor grid with its shadow, the IMU axes and a joint trail, and the camera
commands of :data:`bpms.gui.view3d_keys.VIEW3D_BINDINGS` (each a method taking the key).

On ``r``, the x/y/z views and when it opens the camera frames the whole body, arms' reach
included (:func:`bpms.gui.view3d_geometry.frame_camera`, for the view's current shape);
while the user has not moved the camera (``framed``), a resize or the first real pose frames
it again.
Display frame and colours: :mod:`bpms.gui.view3d`.
"""

from __future__ import annotations

import time
from collections import deque

import numpy as np
from PyQt6.QtCore import Qt, pyqtSignal
from PyQt6.QtGui import QKeyEvent, QVector3D
from PyQt6.QtWidgets import QWidget

from bpms.filter.body_model import POINT_INDEX
from bpms.gui import avatar
from bpms.gui.view3d_geometry import (
    calibration_pose,
    camera_axes,
    frame_camera,
    imu_axes_lines,
    pose_points,
    reach_points,
    to_display,
)
from bpms.gui.view3d_keys import VIEW3D_BINDINGS, command_for
from bpms.pipeline.session import PoseSample

#: (elevation, azimuth) in degrees for the default view and the x/y/z keys.
HOME_VIEW = (15.0, 35.0)
AXIS_VIEWS = {Qt.Key.Key_X: (0.0, 0.0), Qt.Key.Key_Y: (0.0, 90.0), Qt.Key.Key_Z: (90.0, 0.0)}

#: The t key cycles the trail through these joints (None = no trail).
TRAIL_JOINTS: tuple[str | None, ...] = (None, "wrist_r", "wrist_l", "toe_r", "toe_l",
                                        "head_top")
TRAIL_S = 3.0
TRAIL_COLOUR = (0.0, 0.62, 0.45, 1.0)  # bluish green (Okabe & Ito)
DEFAULT_FOV = 60.0
#: Arrow keys move the view by this much, metres; Shift + arrows orbit by this much, degrees.
PAN_STEP_M = 0.1
ORBIT_STEP_DEG = 5.0

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


def make_gl_view() -> QWidget:
    """The GLViewWidget subclass, defined lazily so importing this module never needs GL."""
    import pyqtgraph.opengl as gl
    from pyqtgraph import Vector
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
            self.lengths = None  # the segment lengths of the last sample (docs/subject.md)
            self._programs: dict[object, object] = {}
            self.show_axes = False
            self.aligned = True  # v: False shows the figure without Reset Zero
            self.waiting = True
            self.trail_joint: str | None = None
            self.trail: deque[np.ndarray] = deque(maxlen=round(TRAIL_S * 50))
            self.paint_s = 0.0  # smoothed paintGL time, s
            self.paints = 0  # frames painted (bench/gui.py)
            self.last_points: np.ndarray | None = None
            self.framed = True  # the camera shows the whole figure (until the user moves it)
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
            pos = pose_points(sample, self.aligned)  # the sample's own segment lengths
            self.lengths = getattr(sample, "body", None) or self.lengths
            was_waiting = self.waiting
            self.waiting = pos is None or not np.isfinite(pos).any()
            points = to_display(calibration_pose(self.lengths) if self.waiting else pos)
            self.last_points = points
            self.last_sample = sample
            if was_waiting and not self.waiting and self.framed:
                self.frame()  # the first real pose: frame it (arms may be out, say)
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

        def cycle_trail(self, _key: object = None) -> str | None:
            k = TRAIL_JOINTS.index(self.trail_joint)
            self.trail_joint = TRAIL_JOINTS[(k + 1) % len(TRAIL_JOINTS)]
            self.trail.clear()
            self._draw_trail()
            self.changed.emit()
            return self.trail_joint

        # -- camera and keys (the commands of VIEW3D_BINDINGS; each takes the key) ------
        def frame(self) -> None:
            """Centre and distance that show the whole figure at the current angles, field of
            view and shape of the view."""
            points = reach_points(self.last_points if self.last_points is not None
                                  else to_display(calibration_pose(self.lengths)))
            aspect = self.width() / max(1, self.height())
            centre, distance = frame_camera(points, self.opts["elevation"],
                                            self.opts["azimuth"], self.opts["fov"], aspect)
            self.setCameraPosition(pos=Vector(*centre), distance=distance)
            self.framed = True

        def reset_view(self, _key: object = None) -> None:
            elevation, azimuth = HOME_VIEW
            self.opts["fov"] = DEFAULT_FOV
            self.look(elevation, azimuth)

        def look(self, elevation: float, azimuth: float) -> None:
            self.setCameraPosition(elevation=elevation, azimuth=azimuth)
            self.frame()

        def axis_view(self, key: object) -> None:
            self.look(*AXIS_VIEWS[key])

        def pan_step(self, key: object) -> None:
            """Arrow keys: the camera and its centre move by PAN_STEP_M in the view plane."""
            _, right, up = camera_axes(self.opts["elevation"], self.opts["azimuth"])
            step = {Qt.Key.Key_Left: -right, Qt.Key.Key_Right: right, Qt.Key.Key_Up: up,
                    Qt.Key.Key_Down: -up}[key] * PAN_STEP_M
            self.opts["center"] += QVector3D(*(float(v) for v in step))
            self.moved()

        def orbit_step(self, key: object) -> None:
            """Shift + arrows: ORBIT_STEP_DEG about the vertical, or up / down."""
            azimuth, elevation = {Qt.Key.Key_Left: (ORBIT_STEP_DEG, 0.0),
                                  Qt.Key.Key_Right: (-ORBIT_STEP_DEG, 0.0),
                                  Qt.Key.Key_Up: (0.0, ORBIT_STEP_DEG),
                                  Qt.Key.Key_Down: (0.0, -ORBIT_STEP_DEG)}[key]
            self.orbit(azimuth, elevation)
            self.moved()

        def moved(self) -> None:
            """The user moved the camera: a resize no longer re-frames the figure."""
            self.framed = False
            self.update()

        def recentre(self, _key: object = None) -> None:
            """p: the camera looks at the figure's pelvis (mid-height)."""
            if self.last_points is not None and np.isfinite(self.last_points[0]).all():
                x, y, z = self.last_points[0]
                self.setCameraPosition(pos=Vector(float(x), float(y), float(z)))
                self.moved()

        def field_of_view(self, key: object) -> None:
            if key == Qt.Key.Key_0:
                self.set_fov(DEFAULT_FOV)
            else:
                wider = key == Qt.Key.Key_Minus
                self.set_fov(self.opts["fov"] * 1.2 if wider else self.opts["fov"] / 1.2)

        def set_fov(self, fov: float) -> None:
            self.opts["fov"] = float(min(max(fov, 10.0), 120.0))
            self.moved()

        def toggle_axes(self, _key: object = None) -> None:
            self.show_axes = not self.show_axes
            self.axes.setVisible(self.show_axes and not self.waiting)

        def toggle_alignment(self, _key: object = None) -> None:
            self.aligned = not self.aligned
            self.show_pose(self.last_sample)
            self.changed.emit()

        def reset_zero(self, _key: object = None) -> None:
            self.resetZeroKey.emit()

        def keyPressEvent(self, ev: QKeyEvent | None) -> None:
            if ev is None:
                return
            shift = bool(ev.modifiers() & Qt.KeyboardModifier.ShiftModifier)
            command = command_for(VIEW3D_BINDINGS, ev.key(), shift)
            if command is None:
                ev.ignore()  # F1 and the window's shortcuts go on to the main window
                return
            getattr(self, command)(ev.key())
            ev.accept()

        def mouseMoveEvent(self, ev) -> None:
            if ev is not None and ev.buttons() != Qt.MouseButton.NoButton:
                self.framed = False
            super().mouseMoveEvent(ev)

        def wheelEvent(self, ev) -> None:
            self.framed = False
            super().wheelEvent(ev)

        def resizeEvent(self, ev) -> None:
            super().resizeEvent(ev)
            if getattr(self, "framed", False):
                self.frame()

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
