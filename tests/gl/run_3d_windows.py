"""Under Xvfb (QT_QPA_PLATFORM=xcb): two 3D windows on a replayed simulated recording.

Usage: run_3d_windows.py OUTDIR. Presses keys in each window, saves the framebuffer after
every step as OUTDIR/<window>_<step>.png and writes OUTDIR/results.json with pixel counts per
image; then every input of the help table on the first window, and its framing in views of
other shapes (view3d_presses.py); tests/test_gui_3d_gl.py asserts on them. Exit status 3 =
OpenGL unavailable.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
from PyQt6.QtTest import QTest
from PyQt6.QtWidgets import QApplication

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(1, str(Path(__file__).parents[1]))  # tests/: the one deadline scale
from deadlines import scaled
from gl_pixels import extent, measure, pixels, pump
from view3d_presses import press_all

from bpms.firmware.sim.session import simulate
from bpms.gui.model import SessionModel
from bpms.gui.view3d import open_3d_window, opengl_problem
from bpms.io.rawfile import new_header, read_raw, write_raw
from bpms.io.replay import ReplaySource
from bpms.pipeline.session import LiveSession

KEYS = ("x", "y", "z", "r", "d")


def main(out: Path) -> int:
    app = QApplication(sys.argv[:1])
    problem = opengl_problem()
    if problem is not None:
        print(f"OpenGL unavailable: {problem}")
        return 3
    out.mkdir(parents=True, exist_ok=True)
    rec = simulate(duration_s=5.0, seed=3)
    path = out / "Raw_sim_1.bpmsraw"
    path.unlink(missing_ok=True)
    write_raw(path, 1.7e9 + rec.t, rec.frames, new_header(notes="simulated"))
    recording = read_raw(path)
    session = LiveSession(ReplaySource(recording, speed=None), recording_dir=out)
    model = SessionModel()
    model.attach(session)
    # Opened wide and short: the waiting (calibration) figure is framed whole at once.
    wide = open_3d_window(model)
    wide.resize(760, 300)
    pump(app, 0.3)
    wide.view_resized()
    opened_wide = {"when": "opened wide", **extent(wide.view.grabFramebuffer())}
    wide.close()
    windows = [open_3d_window(model), open_3d_window(model)]
    for i, window in enumerate(windows):
        window.move(40 + 560 * i, 40)
    pump(app, 0.5)
    results: dict = {"windows": [], "waiting_text": windows[0].status.text()}
    waiting = windows[0].view.grabFramebuffer()
    waiting.save(str(out / "w0_waiting.png"))
    results["waiting"] = measure(waiting)

    session.start()
    deadline = time.monotonic() + scaled(30)

    def all_shown() -> bool:
        return (session.status().processed == len(recording) and model.latest is not None
                and model.latest.index == len(recording) - 1)

    while time.monotonic() < deadline and not all_shown():
        pump(app, 0.05)
    # the keys' shots compare images of one pose: the recording must have been shown whole
    results["all_shown"] = all_shown()
    pump(app, 0.3)
    results["last_index"] = model.latest.index if model.latest is not None else None
    results["frames"] = len(recording)
    results["figure_finite"] = bool(np.isfinite(model.latest.joint_positions).all())
    results["status_text"] = windows[0].status.text()

    for w, window in enumerate(windows):
        view = window.view
        window.activateWindow()
        view.setFocus()
        pump(app, 0.1)
        shots = {}
        for step in ("start", *KEYS):
            if step != "start":
                QTest.keyClick(view, step)
            pump(app, 0.1)
            image = view.grabFramebuffer()
            image.save(str(out / f"w{w}_{step}.png"))
            shots[step] = measure(image)
            shots[step]["camera"] = [view.opts["elevation"], view.opts["azimuth"]]
            shots[step]["axes_shown"] = view.show_axes
            np.save(out / f"w{w}_{step}.npy", pixels(image))
        # The other window did not move when this one's keys were pressed.
        results["windows"].append(shots)
    results["bindings"] = press_all(app, windows[0], out)
    results["bindings"]["framing"].insert(0, opened_wide)
    model.stop()
    for window in windows:
        window.close()
    (out / "results.json").write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))
