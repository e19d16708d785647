"""Under Xvfb (QT_QPA_PLATFORM=xcb): the main window with three docked 3D views, one of them
then floated, on a replayed simulated recording.

Usage: run_docked_views.py OUTDIR. Writes OUTDIR/results.json (per view: isValid(), pixel
counts of the avatar's right and left sides) and the framebuffers as PNGs;
tests/test_gui_3d_gl.py asserts on them. Exit status 3 = OpenGL unavailable.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path

if "BPMS_CONFIG_DIR" not in os.environ:  # run by hand: a config folder removed at exit
    _CONFIG_FOLDER = tempfile.TemporaryDirectory(prefix="bpms-gl-config-")
    os.environ["BPMS_CONFIG_DIR"] = _CONFIG_FOLDER.name

from PyQt6.QtCore import Qt
from PyQt6.QtWidgets import QApplication

from bpms.firmware.sim.session import simulate
from bpms.gui.main_window import MainWindow
from bpms.gui.modes import ModeConfig, SessionRunner
from bpms.gui.view3d import opengl_problem
from bpms.io.options import Options

sys.path.insert(0, str(Path(__file__).parent))
from gl_pixels import measure, pump


def main(out: Path) -> int:
    app = QApplication(sys.argv[:1])
    problem = opengl_problem()
    if problem is not None:
        print(f"OpenGL unavailable: {problem}")
        return 3
    out.mkdir(parents=True, exist_ok=True)
    path = simulate(duration_s=18.0, seed=2).save_raw(out / "Raw_docked_1.bpmsraw")
    runner = SessionRunner(ModeConfig(mode="file", path=str(path), recording_dir=str(out)),
                           Options())
    runner.prepare()
    window = MainWindow(runner, restore_last=False)
    # this size, not maximised (a screen below 1600 x 900 opens the window maximised)
    window.setWindowState(Qt.WindowState.WindowNoState)
    window.resize(1500, 900)
    window.show()
    while len(window.views.view3d_windows) < 3:
        window.views.open_3d_view()
    pump(app, 0.3)
    # the playback's 4× speed (what a user picks in the Speed box): the views draw the same
    # frames in a quarter of the time
    window.panels.playback_panel.speed_combo.setCurrentText("4×")
    assert runner.replay.speed == 4.0
    window.commands.set_data(True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and (window.model.latest is None
                                           or window.model.latest.index < 745):
        pump(app, 0.05)
    window.commands.set_data(False)
    pump(app, 0.5)
    results: dict = {"docked": [], "index": window.model.latest.index}
    for k, view in enumerate(window.views.view3d_windows):
        image = view.gl_view.grabFramebuffer()
        image.save(str(out / f"docked_{k}.png"))
        results["docked"].append({"valid": view.gl_view.isValid(), "draws": view.draws,
                                  **measure(image)})
    dock = window.views.dock_of(window.views.view3d_windows[1])
    dock.setFloating(True)
    pump(app, 0.5)
    window.mode.step_frames(1)  # a new frame while floating: drawn in the new top-level window
    pump(app, 1.0)
    view = window.views.view3d_windows[1]
    image = view.gl_view.grabFramebuffer()
    image.save(str(out / "floating.png"))
    results["floating"] = {"valid": view.gl_view.isValid(), "floating": dock.isFloating(),
                           **measure(image)}
    window.close()
    (out / "results.json").write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))
