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
from PyQt6.QtCore import Qt
from PyQt6.QtGui import QImage
from PyQt6.QtTest import QTest
from PyQt6.QtWidgets import QApplication

from bpms.firmware.sim.session import simulate
from bpms.gui.avatar import LEFT_ARM, LEFT_LEG, RIGHT_ARM, RIGHT_LEG
from bpms.gui.model import SessionModel
from bpms.gui.view3d import open_3d_window, opengl_problem
from bpms.gui.view3d_geometry import AXIS_COLOURS
from bpms.io.rawfile import new_header, read_raw, write_raw
from bpms.io.replay import ReplaySource
from bpms.pipeline.session import LiveSession

KEYS = ("x", "y", "z", "r", "d")
#: The original suite's keys, pressed after KEYS: pan, field of view, re-centre, trail.
EXTRA_KEYS = ("Left", "=", "0", "p", "t")


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


def hue(rgb: np.ndarray, *colours: tuple[float, ...], cos: float = 0.995) -> int:
    """Pixels of one of ``colours`` whatever the shading (the shaded solid scales a colour's
    brightness, not its direction in RGB space); dark pixels are left out."""
    p = rgb.reshape(-1, 3).astype(float)
    bright = p.max(axis=1) > 40
    unit = p / np.maximum(np.linalg.norm(p, axis=1), 1e-9)[:, None]
    hit = np.zeros(len(p), bool)
    for colour in colours:
        c = np.array(colour[:3], float)
        hit |= unit @ (c / np.linalg.norm(c)) > cos
    return int((hit & bright).sum())


def measure(image: QImage) -> dict:
    rgb = pixels(image)
    spread = rgb.max(axis=2).astype(int) - rgb.min(axis=2)
    return {
        "size": [image.width(), image.height()],
        "non_background": int((rgb.max(axis=2) > 30).sum()),
        "right": hue(rgb, RIGHT_ARM, RIGHT_LEG),
        "left": hue(rgb, LEFT_ARM, LEFT_LEG),
        "grey": int(((spread < 8) & (rgb.max(axis=2) > 70)).sum()),
        "axis_blue": hue(rgb, AXIS_COLOURS[2], cos=0.98),
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
        extra = {}
        for step in EXTRA_KEYS:
            key = getattr(Qt.Key, f"Key_{step}") if len(step) > 1 else step
            c = view.opts["center"]
            before = [c.x(), c.y(), c.z(), view.opts["fov"]]
            QTest.keyClick(view, key)
            pump(app, 0.1)
            c = view.opts["center"]
            after = [c.x(), c.y(), c.z(), view.opts["fov"]]
            extra[step] = {"before": before, "after": after,
                           "trail": view.trail_joint}
        results.setdefault("extra", []).append(extra)
        # The other window did not move when this one's keys were pressed.
        results["windows"].append(shots)
    model.stop()
    for window in windows:
        window.close()
    (out / "results.json").write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))
