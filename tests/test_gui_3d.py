"""3D view pieces that need no OpenGL: the fallback window, frames and line geometry."""

from __future__ import annotations

import numpy as np
from PyQt6.QtCore import Qt
from PyQt6.QtWidgets import QWidget

from bpms.filter.body_model import POINT_INDEX, SEGMENTS
from bpms.gui.model import SessionModel
from bpms.gui.view3d import open_3d_window, opengl_problem
from bpms.gui.view3d_geometry import (
    CALIBRATION_POSE,
    LEFT_COLOUR,
    RIGHT_COLOUR,
    figure_lines,
    imu_axes_lines,
    to_display,
)


def test_offscreen_windows_show_a_message_instead_of_crashing(qtbot):
    model = SessionModel()
    windows = [open_3d_window(model), open_3d_window(model)]
    for window in windows:
        qtbot.addWidget(window)
        assert window.isWindow() and window.isVisible()
        assert window.gl_view is None
        assert "OpenGL is not available" in window.fallback_message
        assert "offscreen" in window.fallback_message
        qtbot.keyClick(window, Qt.Key.Key_D)  # keys and samples are harmless in the fallback
        model.samplesArrived.emit([])
    assert windows[0] is not windows[1]
    assert opengl_problem() is not None


def test_with_a_parent_the_window_is_still_top_level(qtbot):
    parent = QWidget()
    qtbot.addWidget(parent)
    window = open_3d_window(SessionModel(), parent)
    assert window.isWindow() and window.parent() is parent


def test_display_frame_is_z_up_and_the_figure_stands_on_the_grid():
    ned = np.array([[1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(to_display(ned), [[1.0, -2.0, -3.0]])
    shown = to_display(CALIBRATION_POSE)
    assert shown[:, 2].min() == 0.0  # lowest foot on the ground
    head = shown[POINT_INDEX["head_top"]]
    assert 1.6 < head[2] < 1.9  # about the 1.73 m default height, above the ground
    # NED east (right) is display -y: the right shoulder has negative display y.
    assert shown[POINT_INDEX["shoulder_r"], 1] < 0 < shown[POINT_INDEX["shoulder_l"], 1]


def test_lines_leave_out_segments_with_unknown_ends_and_colour_the_sides():
    points = to_display(CALIBRATION_POSE)
    pos, colours = figure_lines(points)
    assert pos.shape == (2 * len(SEGMENTS), 3) and colours.shape == (2 * len(SEGMENTS), 4)
    knee = next(k for k, (_, b, _) in enumerate(SEGMENTS) if b == "knee_r")
    np.testing.assert_array_equal(colours[2 * knee], RIGHT_COLOUR)
    elbow = next(k for k, (_, b, _) in enumerate(SEGMENTS) if b == "elbow_l")
    np.testing.assert_array_equal(colours[2 * elbow], LEFT_COLOUR)
    points[POINT_INDEX["wrist_r"]] = np.nan  # forearm and hand segments go
    pos, colours = figure_lines(points)
    assert len(pos) == 2 * (len(SEGMENTS) - 2) and np.isfinite(pos).all()


def test_imu_axes_follow_the_segment_orientation():
    points = to_display(CALIBRATION_POSE)
    C = np.broadcast_to(np.eye(3), (18, 3, 3)).copy()
    pos, colours = imu_axes_lines(points, C)
    assert pos.shape == (18 * 6, 3)
    starts, ends = pos[0::2], pos[1::2]
    directions = (ends - starts).reshape(18, 3, 3)
    # Identity: segment x (red) = north = display +x, z (blue) = down = display -z.
    assert np.allclose(directions[:, 0], [0.12, 0, 0])
    assert np.allclose(directions[:, 2], [0, 0, -0.12])
    np.testing.assert_array_equal(colours[0], [1, 0, 0, 1])
    C[3] = np.nan  # an uninitialised IMU draws no triad
    assert len(imu_axes_lines(points, C)[0]) == 17 * 6


def test_avatar_capsules_enclose_their_segments_with_exact_normals():
    from bpms.gui.avatar import FACES, SEG_RADII, VERTS_PER_SEGMENT, capsule_mesh, figure_mesh
    from bpms.gui.view3d_geometry import CALIBRATION_POSE, SEG_END, SEG_START, to_display

    a = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]])
    b = np.array([[0.0, 0.0, 0.5], [1.0, 2.3, 3.0]])
    radii = np.array([0.1, 0.05])
    verts, normals = capsule_mesh(a, b, radii)
    for k in range(2):
        v = verts[k * VERTS_PER_SEGMENT:(k + 1) * VERTS_PER_SEGMENT]
        n = normals[k * VERTS_PER_SEGMENT:(k + 1) * VERTS_PER_SEGMENT]
        d = (b[k] - a[k]) / np.linalg.norm(b[k] - a[k])
        s = np.clip((v - a[k]) @ d, 0.0, np.linalg.norm(b[k] - a[k]))
        closest = a[k] + s[:, None] * d
        dist = np.linalg.norm(v - closest, axis=1)
        # every vertex within the radius of the segment, the side rings exactly on it
        assert dist.max() <= radii[k] + 1e-9 and np.isclose(np.median(dist), radii[k])
        assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
        # normals point inwards (towards the segment), as the shader wants
        assert (np.einsum("ij,ij->i", n, v - closest) <= 1e-9).all()
    points = to_display(CALIBRATION_POSE)
    verts, normals = figure_mesh(points)
    assert verts.shape == normals.shape == (len(SEG_START) * VERTS_PER_SEGMENT, 3)
    assert FACES.max() < len(verts) and np.isfinite(verts).all()
    # the figure stands on the floor: nothing far below z = 0, the head near 1.73 m
    assert verts[:, 2].min() > -0.1 and 1.6 < verts[:, 2].max() < 2.0
    assert len(SEG_RADII) == len(SEG_END)
