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
                          capture_output=True, text=True, timeout=120)
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


def test_the_original_keys_pan_zoom_recentre_and_trail(run):
    _out, results = run
    for extra in results["extra"]:
        left = extra["Left"]
        assert left["after"][:3] != left["before"][:3]  # arrows pan: the centre moves
        assert left["after"][3] == left["before"][3]
        assert extra["="]["after"][3] < extra["="]["before"][3]  # narrower field of view
        assert extra["0"]["after"][3] == 60.0  # default field of view
        assert extra["p"]["after"][:3] != extra["p"]["before"][:3]  # on the pelvis
        assert extra["t"]["trail"] == "wrist_r"


DOCKED = Path(__file__).parent / "gl" / "run_docked_views.py"


@pytest.fixture(scope="module")
def docked(tmp_path_factory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("gldocked")
    env = {**os.environ, "QT_QPA_PLATFORM": "xcb"}
    proc = subprocess.run([*XVFB, sys.executable, str(DOCKED), str(out)], env=env,
                          capture_output=True, text=True, timeout=180)
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
