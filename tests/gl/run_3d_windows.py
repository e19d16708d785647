"""Under Xvfb (QT_QPA_PLATFORM=xcb): two 3D windows on a replayed simulated recording.

Usage: run_3d_windows.py OUTDIR. Presses each key in each window, saves the framebuffer after
every step as OUTDIR/<window>_<step>.png and writes OUTDIR/results.json with pixel counts per
image; tests/test_gui_3d_gl.py asserts on them. Exit status 3 = OpenGL unavailable.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
from PyQt6.QtGui import QImage
from PyQt6.QtTest import QTest
from PyQt6.QtWidgets import QApplication

from bpms.firmware.sim.session import simulate
from bpms.gui.model import SessionModel
from bpms.gui.view3d import open_3d_window, opengl_problem
from bpms.gui.view3d_geometry import (
    AXIS_COLOURS,
    LEFT_COLOUR,
    RIGHT_COLOUR,
    WAITING_COLOUR,
)
from bpms.io.rawfile import new_header, read_raw, write_raw
from bpms.io.replay import ReplaySource
from bpms.pipeline.session import LiveSession

KEYS = ("x", "y", "z", "r", "d")


def pump(app: QApplication, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        app.processEvents()
        time.sleep(0.005)


def pixels(image: QImage) -> np.ndarray:
    image = image.convertToFormat(QImage.Format.Format_RGB888)
    h, w, stride = image.height(), image.width(), image.bytesPerLine()
    buf = np.frombuffer(image.constBits().asstring(stride * h), np.uint8)
    return buf.reshape(h, stride)[:, : w * 3].reshape(h, w, 3)


def near(rgb: np.ndarray, colour: tuple[float, ...], tol: int = 40) -> int:
    target = np.array(colour[:3]) * 255
    return int((np.abs(rgb.astype(int) - target).max(axis=2) <= tol).sum())


def measure(image: QImage) -> dict:
    rgb = pixels(image)
    return {
        "size": [image.width(), image.height()],
        "non_background": int((rgb.max(axis=2) > 30).sum()),
        "right": near(rgb, RIGHT_COLOUR),
        "left": near(rgb, LEFT_COLOUR),
        "grey": near(rgb, WAITING_COLOUR, tol=12),
        "axis_blue": near(rgb, AXIS_COLOURS[2], tol=30),
    }


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
    windows = [open_3d_window(model), open_3d_window(model)]
    for i, window in enumerate(windows):
        window.move(40 + 560 * i, 40)
    pump(app, 0.5)
    results: dict = {"windows": [], "waiting_text": windows[0].status.text()}
    waiting = windows[0].view.grabFramebuffer()
    waiting.save(str(out / "w0_waiting.png"))
    results["waiting"] = measure(waiting)

    session.start()
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and not (
            session.status().processed == len(recording) and model.latest is not None
            and model.latest.index == len(recording) - 1):
        pump(app, 0.05)
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
    model.stop()
    for window in windows:
        window.close()
    (out / "results.json").write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))
