"""3D windows under Xvfb (xcb + Mesa): two windows, every key, framebuffer grabbed to PNGs.

The GL work runs in tests/gl/run_3d_windows.py as a subprocess so this pytest process stays on
the offscreen platform; the PNGs land in this test's tmp_path.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from deadlines import scaled

SCRIPT = Path(__file__).parent / "gl" / "run_3d_windows.py"
XVFB = ["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24"]

pytestmark = [
    pytest.mark.gl,
    pytest.mark.skipif(shutil.which("xvfb-run") is None,
                       reason="xvfb-run is missing (Debian: apt-get install xvfb xauth)"),
]


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("gl3d")
    env = {**os.environ, "QT_QPA_PLATFORM": "xcb"}
    proc = subprocess.run([*XVFB, sys.executable, str(SCRIPT), str(out)], env=env,
                          capture_output=True, text=True, timeout=scaled(120))
    if proc.returncode == 3:
        pytest.skip(f"no OpenGL under Xvfb here: {proc.stdout.strip()}")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    return out, json.loads((out / "results.json").read_text())


def test_before_reset_zero_the_figure_is_grey_with_a_label(run):
    out, results = run
    assert "Reset Zero" in results["waiting_text"]
    waiting = results["waiting"]
    assert waiting["grey"] > 300
    assert waiting["left"] == waiting["right"] == 0
    assert (out / "w0_waiting.png").stat().st_size > 1000


def test_the_figure_is_drawn_after_reset_zero(run):
    out, results = run
    assert results["last_index"] == results["frames"] - 1
    assert results["figure_finite"]
    assert results["status_text"].startswith(f"frame {results['frames'] - 1}")
    for w, shots in enumerate(results["windows"]):
        for step, shot in shots.items():
            # Both sides visible (fewer pixels from above, where limbs are foreshortened).
            assert shot["left"] > 30 and shot["right"] > 30, step
            assert shot["non_background"] > 5000, step
            assert (out / f"w{w}_{step}.png").stat().st_size > 1000


def test_keys_move_the_camera_and_r_resets_it(run):
    out, results = run
    assert results["all_shown"], "the recording was not shown whole before the keys"
    for w, shots in enumerate(results["windows"]):
        assert shots["x"]["camera"] == [0.0, 0.0]
        assert shots["y"]["camera"] == [0.0, 90.0]
        assert shots["z"]["camera"] == [90.0, 0.0]
        assert shots["r"]["camera"] == shots["start"]["camera"]
        images = {s: np.load(out / f"w{w}_{s}.npy") for s in shots}
        for a, b in (("start", "x"), ("x", "y"), ("y", "z")):
            assert (images[a] != images[b]).any(axis=2).mean() > 0.005, (a, b)
        # Same pose, same camera: the reset view is the first view again.
        assert (images["r"] != images["start"]).any(axis=2).mean() < 0.001


def test_d_toggles_the_imu_axes(run):
    out, results = run
    for w, shots in enumerate(results["windows"]):
        assert not shots["r"]["axes_shown"] and shots["d"]["axes_shown"]
        assert shots["r"]["axis_blue"] == 0 and shots["d"]["axis_blue"] > 100
        before, after = np.load(out / f"w{w}_r.npy"), np.load(out / f"w{w}_d.npy")
        assert (before != after).any(axis=2).sum() > 300


def test_two_windows_are_independent_and_identical_for_the_same_input(run):
    _out, results = run
    first, second = results["windows"]
    for step in first:
        assert first[step]["right"] == second[step]["right"], step
    # Window 1 was grabbed after window 0's keys (last: d) were pressed: it saw none of them.
    assert first["d"]["axes_shown"] and not second["start"]["axes_shown"]
    assert second["start"]["camera"] == first["start"]["camera"] != first["z"]["camera"]


DOCKED = Path(__file__).parent / "gl" / "run_docked_views.py"


@pytest.fixture(scope="module")
def docked(tmp_path_factory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("gldocked")
    env = {**os.environ, "QT_QPA_PLATFORM": "xcb"}
    proc = subprocess.run([*XVFB, sys.executable, str(DOCKED), str(out)], env=env,
                          capture_output=True, text=True, timeout=scaled(180))
    if proc.returncode == 3:
        pytest.skip(f"no OpenGL under Xvfb here: {proc.stdout.strip()}")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    return out, json.loads((out / "results.json").read_text())


def test_several_docked_3d_views_render_the_solid_avatar(docked):
    _out, results = docked
    assert results["index"] >= 745
    assert len(results["docked"]) == 3
    for shot in results["docked"]:
        assert shot["valid"] and shot["draws"] > 0
        # both sides of the shaded figure in every view (shared mesh, per-view GL state)
        assert shot["right"] > 100 and shot["left"] > 100, shot
    floating = results["floating"]
    assert floating["floating"] and floating["valid"]
    assert floating["right"] > 200 and floating["left"] > 200, floating


def _inside(extent: dict, margin: int = 1) -> bool:
    """The figure's pixels keep off the image's border (the whole body is in the frame)."""
    (w, h), rows, cols = extent["size"], extent["rows"], extent["cols"]
    return rows is not None and rows[0] >= margin and rows[1] <= h - 1 - margin \
        and cols[0] >= margin and cols[1] <= w - 1 - margin


def _camera(state: dict) -> np.ndarray:
    """The camera position as pyqtgraph places it (centre + distance × direction)."""
    el, az = np.radians(state["elevation"]), np.radians(state["azimuth"])
    direction = [np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]
    return np.array(state["center"]) + state["distance"] * np.array(direction)


def _same(before: dict, after: dict, *names: str) -> bool:
    return all(np.allclose(before[n], after[n]) for n in names)


def _check_press(p: dict) -> None:
    """The documented effect (the help table's action) of one press."""
    b, a, press, cmd = p["before"], p["after"], p["press"], p["command"]
    moved = np.array(a["center"]) - np.array(b["center"])
    if p["inputs"] == "left drag":
        assert (b["azimuth"], b["elevation"]) != (a["azimuth"], a["elevation"])
        assert _same(b, a, "center", "distance")
    elif press in ("middle", "ctrl-left"):
        assert np.linalg.norm(moved) > 0.01 and _same(b, a, "distance", "azimuth")
    elif p["inputs"] == "wheel":
        assert a["distance"] < b["distance"] and a["fov"] == b["fov"]  # wheel forward: nearer
    elif p["inputs"] == "Ctrl + wheel":
        assert a["fov"] != b["fov"] and a["distance"] == b["distance"]
    elif cmd == "pan_step":
        assert abs(np.linalg.norm(moved) - 0.1) < 1e-3  # 0.1 m
        view = _camera(b) - np.array(b["center"])
        assert abs(moved @ view) < 1e-3  # in the view plane
        assert _same(b, a, "distance", "azimuth", "elevation")
        if press in ("Key_Up", "Key_Down"):
            assert (moved[2] > 0) == (press == "Key_Up")
        else:  # left / right: horizontal, towards the camera's left / right
            right = np.cross(-view, [0.0, 0.0, 1.0])
            assert abs(moved[2]) < 1e-6 and (moved @ right > 0) == (press == "Key_Right")
    elif cmd == "orbit_step":
        turn = {"Key_Left+shift": (5, 0), "Key_Right+shift": (-5, 0), "Key_Up+shift": (0, 5),
                "Key_Down+shift": (0, -5)}[press]
        assert (a["azimuth"] - b["azimuth"], a["elevation"] - b["elevation"]) == turn
        assert _same(b, a, "center", "distance")
    elif cmd == "reset_zero":
        assert a["resets"] == b["resets"] + 1
    elif cmd == "toggle_alignment":
        assert b["aligned"] and not a["aligned"] and a["pelvis"] != b["pelvis"]
    elif cmd == "recentre":
        assert np.allclose(a["center"], a["pelvis"], atol=1e-6)
    elif cmd == "field_of_view":
        want = {"Key_Equal": b["fov"] / 1.2, "Key_Plus": b["fov"] / 1.2,
                "Key_Minus": b["fov"] * 1.2, "Key_0": 60.0}[press]
        assert abs(a["fov"] - want) < 1e-6 and a["fov"] != b["fov"]
    elif cmd == "axis_view":
        assert [a["elevation"], a["azimuth"]] == {"Key_X": [0, 0], "Key_Y": [0, 90],
                                                  "Key_Z": [90, 0]}[press]
        assert _inside(p["extent"])
    elif cmd == "toggle_axes":
        assert a["axes"] and p["pixels"]["axis_blue"] > 100
    elif cmd == "cycle_trail":
        assert b["trail"] is None and a["trail"] == "wrist_r"
    elif cmd == "reset_view":
        assert (a["elevation"], a["azimuth"], a["fov"]) == (15.0, 35.0, 60.0) != \
            (b["elevation"], b["azimuth"], b["fov"])
        assert _inside(p["extent"])
    else:
        raise AssertionError(f"no check for {p['inputs']!r} ({cmd})")


def test_every_key_and_mouse_input_of_the_help_table_does_what_it_says(run):
    from bpms.gui.view3d_keys import VIEW3D_BINDINGS

    keys = run[1]["bindings"]
    pressed = {p["binding"] for p in keys["presses"]}
    assert pressed == set(range(len(VIEW3D_BINDINGS)))  # every row of F1's table
    for p in keys["presses"]:
        _check_press(p)


def test_the_whole_body_is_framed_on_opening_and_on_r_whatever_the_view_shape(run):
    for shot in run[1]["bindings"]["framing"]:
        assert _inside(shot), shot
        (w, h), rows, cols = shot["size"], shot["rows"], shot["cols"]
        # framed, not lost in the distance: the figure (with room left for the arms' reach
        # on either side) fills a good part of the tighter dimension
        assert max((rows[1] - rows[0]) / h, (cols[1] - cols[0]) / w) > 0.3, shot
