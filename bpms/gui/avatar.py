"""The solid avatar's geometry (numpy only, no Qt, no GL): each body segment as a shaded
capsule between its two joints, a large one for the head, small ones for hands and feet, and a
flattened copy as the shadow on the floor.

One mesh for the whole body: a fixed triangle list (:data:`FACES`) and, per pose, vertices
``[V, 3]`` and colours ``[V, 4]`` built in one vectorised pass. The 3D views build the mesh
of a pose once and share it (:func:`bpms.gui.view3d_gl.shared_meshdata`).

Points are display metres (x north, y west, z up; :mod:`bpms.gui.view3d_geometry`).
"""

from __future__ import annotations

import numpy as np

from bpms.filter.body_model import SEGMENTS

#: Capsule radius per segment child point, metres.
RADII: dict[str, float] = {
    "spine_mid": 0.11, "neck_base": 0.10, "head_base": 0.045, "head_top": 0.10,
    "shoulder_r": 0.05, "elbow_r": 0.048, "wrist_r": 0.04, "fingers_r": 0.032,
    "shoulder_l": 0.05, "elbow_l": 0.048, "wrist_l": 0.04, "fingers_l": 0.032,
    "hip_r": 0.075, "knee_r": 0.07, "ankle_r": 0.052, "toe_r": 0.042,
    "hip_l": 0.075, "knee_l": 0.07, "ankle_l": 0.052, "toe_l": 0.042,
}

#: Colour-blind-safe body colours (Okabe & Ito): right side blue, left side orange (arms
#: lighter than legs, so arms over legs stay readable in front view), trunk and head grey.
RIGHT_ARM = (0.34, 0.71, 0.91, 1.0)   # sky blue
RIGHT_LEG = (0.0, 0.45, 0.70, 1.0)    # blue
LEFT_ARM = (0.94, 0.76, 0.35, 1.0)    # light orange
LEFT_LEG = (0.84, 0.37, 0.0, 1.0)     # vermilion
TRUNK = (0.75, 0.75, 0.78, 1.0)
WAITING = (0.55, 0.55, 0.55, 1.0)
SHADOW = (0.18, 0.18, 0.2, 1.0)
#: The shadow sits this far above the floor grid, metres.
SHADOW_Z = 0.003

_ARMS = ("shoulder", "elbow", "wrist", "fingers")


def _colour(child: str) -> tuple[float, float, float, float]:
    limb = child.rsplit("_", 1)[0]
    if child.endswith("_r"):
        return RIGHT_ARM if limb in _ARMS else RIGHT_LEG
    if child.endswith("_l"):
        return LEFT_ARM if limb in _ARMS else LEFT_LEG
    return TRUNK


# -- the capsule template -------------------------------------------------------------------
SIDES = 12
#: Rings along the capsule: (radius factor, fraction of the length, offset in radii).
_RINGS = ((0.0, 0.0, -1.0), (0.7, 0.0, -0.7), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0),
          (0.7, 1.0, 0.7), (0.0, 1.0, 1.0))


def _template() -> tuple[np.ndarray, np.ndarray]:
    """Per vertex (cos, sin, radius factor, length fraction, radius offset) and the faces of
    one capsule (the end rings of radius 0 are its poles)."""
    angles = 2 * np.pi * np.arange(SIDES) / SIDES
    rows = [(np.cos(a), np.sin(a), rf, lf, off) for rf, lf, off in _RINGS for a in angles]
    faces = []
    for r in range(len(_RINGS) - 1):
        for k in range(SIDES):
            a, b = r * SIDES + k, r * SIDES + (k + 1) % SIDES
            c, d = a + SIDES, b + SIDES
            # wound so that pyqtgraph's "shaded" shader lights the side facing the camera
            faces += [(a, d, b), (a, c, d)]
    return np.array(rows), np.array(faces, dtype=np.int32)


_TEMPLATE, _CAPSULE_FACES = _template()
N_SEGMENTS = len(SEGMENTS)
VERTS_PER_SEGMENT = len(_TEMPLATE)
#: The whole body's triangles ``[F, 3]`` (vertex indices; constant).
FACES = np.concatenate([_CAPSULE_FACES + k * VERTS_PER_SEGMENT for k in range(N_SEGMENTS)])
SEG_RADII = np.array([RADII.get(child, 0.05) for _, child, _ in SEGMENTS])
SEG_COLOURS = np.array([_colour(child) for _, child, _ in SEGMENTS])
#: Vertex colours ``[V, 4]`` of the figure and of the waiting (grey) figure.
VERTEX_COLOURS = np.repeat(SEG_COLOURS, VERTS_PER_SEGMENT, axis=0)
WAITING_COLOURS = np.tile(np.array(WAITING), (N_SEGMENTS * VERTS_PER_SEGMENT, 1))

from bpms.gui.view3d_geometry import SEG_END, SEG_START  # noqa: E402  (after SEGMENTS use)


def capsule_mesh(a: np.ndarray, b: np.ndarray, radii: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, unit normals), both ``[M * VERTS_PER_SEGMENT, 3]``, of M capsules from
    ``a [M, 3]`` to ``b [M, 3]`` with ``radii [M]`` (metres; a zero-length one is a sphere). The
    normals are exact (radial on the sides, spherical on the caps) and point inwards, the
    side pyqtgraph's "shaded" shader lights when it faces the camera; computing them from
    the faces would cost more than the whole frame."""
    d = b - a
    length = np.linalg.norm(d, axis=1)
    axis = np.where(length[:, None] > 1e-9, d / np.maximum(length, 1e-9)[:, None],
                    np.array([0.0, 0.0, 1.0]))
    # Any unit vector not parallel to the axis, then an orthonormal frame (e1, e2, axis).
    ref = np.where(np.abs(axis[:, 2:3]) < 0.9, np.array([0.0, 0.0, 1.0]),
                   np.array([1.0, 0.0, 0.0]))
    e1 = np.cross(axis, ref)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(axis, e1)
    t = _TEMPLATE
    r = radii[:, None]  # [M, 1]
    radial = t[None, :, 2] * r  # [M, V]
    along = t[None, :, 3] * length[:, None] + t[None, :, 4] * r
    cx, sy = t[None, :, 0] * radial, t[None, :, 1] * radial
    verts = (a[:, None, :] + cx[..., None] * e1[:, None, :] + sy[..., None] * e2[:, None, :]
             + along[..., None] * axis[:, None, :])
    # outward normal: (cos e1 + sin e2) × radius factor + axis × offset, normalised
    nr, na = t[:, 2], t[:, 4]
    normals = (t[None, :, 0, None] * nr[None, :, None] * e1[:, None, :]
               + t[None, :, 1, None] * nr[None, :, None] * e2[:, None, :]
               + na[None, :, None] * axis[:, None, :])
    normals /= np.linalg.norm(normals, axis=2, keepdims=True)
    return verts.reshape(-1, 3), -normals.reshape(-1, 3)


def figure_vertices(points: np.ndarray) -> np.ndarray:
    """The body mesh's vertices ``[V, 3]`` for joint points ``[21, 3]`` (display metres).
    Non-finite points give a degenerate (invisible) capsule at the origin."""
    return figure_mesh(points)[0]


def figure_mesh(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, normals) ``[V, 3]`` of the body for joint points ``[21, 3]``."""
    points = np.where(np.isfinite(points), points, 0.0)
    return capsule_mesh(points[SEG_START], points[SEG_END], SEG_RADII)


def shadow_vertices(verts: np.ndarray) -> np.ndarray:
    """The figure flattened onto the floor (z = :data:`SHADOW_Z`)."""
    flat = verts.copy()
    flat[:, 2] = SHADOW_Z
    return flat

