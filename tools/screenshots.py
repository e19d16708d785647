"""Save the documentation screenshots into docs/screenshots/ (run under Xvfb, xcb platform).

    tools/screenshots.sh            # = xvfb-run ... .venv/bin/python tools/screenshots.py

Plays a simulated recording (file mode) and grabs: the start-up window (startup.png); the main
window in the "live monitoring" layout (main-window.png); the avatar in a 3D view
(3d-view.png, 3d-view-imu-axes.png); the main window in the "playback analysis" layout with
plots (main-window-with-plots.png). A window that cannot be made is reported in one line and
the others are still saved. Saved layouts of the user running it are not used.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "screenshots"
sys.path.insert(0, str(ROOT))
os.environ.setdefault("QT_QPA_PLATFORM", "xcb")
os.environ["BPMS_CONFIG_DIR"] = tempfile.mkdtemp(prefix="bpms-shots-config-")

from PyQt6.QtCore import Qt  # noqa: E402
from PyQt6.QtWidgets import QApplication, QWidget  # noqa: E402


def pump(app: QApplication, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        app.processEvents()
        time.sleep(0.01)


def wait_for(app: QApplication, predicate, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        pump(app, 0.05)
    return False


def save_widget(widget: QWidget, name: str) -> None:
    widget.grab().save(str(OUT / name))
    print(f"saved {OUT / name}")


def save_3d(window: QWidget, name: str) -> None:
    view = getattr(window, "gl_view", None)
    image = view.grabFramebuffer() if view is not None else window.grab()
    image.save(str(OUT / name))
    print(f"saved {OUT / name}")


def make_recording(folder: Path) -> Path:
    from bpms.firmware.sim.session import simulate
    from bpms.io.rawfile import new_header, write_raw

    rec = simulate(duration_s=40.0, seed=2)
    path = folder / "Raw_sim_001.bpmsraw"
    write_raw(path, 1.7e9 + rec.t, rec.frames, new_header(notes="simulated"))
    return path


def standalone_3d(app: QApplication, recording: Path, folder: Path) -> None:
    """The 3D window on its own session (used when the main window cannot be made)."""
    from bpms.gui.model import SessionModel
    from bpms.gui.view3d import open_3d_window
    from bpms.io.rawfile import read_raw
    from bpms.io.replay import ReplaySource
    from bpms.pipeline.session import LiveSession

    session = LiveSession(ReplaySource(read_raw(recording), speed=1.0), recording_dir=folder)
    model = SessionModel()
    model.attach(session)
    session.start()
    window = open_3d_window(model)
    wait_for(app, lambda: model.latest is not None and model.latest.index >= 745, 40)
    save_3d(window, "3d-view.png")
    window.view.toggle_axes()
    pump(app, 0.2)
    save_3d(window, "3d-view-imu-axes.png")
    model.stop()
    window.close()


def main() -> int:
    app = QApplication(sys.argv[:1])
    OUT.mkdir(parents=True, exist_ok=True)
    folder = Path(tempfile.mkdtemp(prefix="bpms-shots-"))
    recording = make_recording(folder)
    try:
        from bpms.gui.startup import StartupWindow
    except Exception as exc:
        print(f"start-up window not available ({exc}); 3D view only")
        standalone_3d(app, recording, folder)
        return 0

    startup = StartupWindow(recording_dir=str(folder))
    startup.show()
    startup.select_mode("file")
    startup.file_edit.setText(str(recording))
    startup.move(20, 20)
    pump(app, 0.5)
    save_widget(startup, "startup.png")
    opened: list = []
    startup.mainWindowOpened.connect(opened.append)
    startup.go_button.click()
    if not wait_for(app, lambda: bool(opened), 30):
        print("GO did not open the main window; 3D view only")
        standalone_3d(app, recording, folder)
        return 0
    window = opened[0]
    startup.hide()
    from bpms.gui.layouts import LIVE, PLAYBACK

    window.move(0, 0)
    window.resize(1560, 940)
    window.apply_default_layout(LIVE)
    window.set_data(True)  # play
    wait_for(app, lambda: window.model.latest is not None, 20)
    # 14.9 s into the simulated script: both arms raised sideways.
    wait_for(app, lambda: window.model.latest.index >= 745, 40)
    window.set_data(False)
    window.table.select_cells([(6, c) for c in (0, 1, 2)])
    pump(app, 0.8)
    save_widget(window, "main-window.png")
    views = window.view3d_windows
    if views and views[0].gl_view is not None:
        view = views[0].gl_view
        for name in ("3d-view.png", "3d-view-imu-axes.png"):
            views[0].snapshot(520, 640).save(str(OUT / name))
            print(f"saved {OUT / name}")
            view.toggle_axes()
    else:
        print("3D view not available (no OpenGL?); 3d-view*.png not saved")
    window.apply_default_layout(PLAYBACK)
    window.table.select_cells([(6, c) for c in (0, 1, 2)])  # hip roll, pitch, yaw
    window.plot_selection()
    window.table.select_cells([(4, 0), (5, 0), (10, 0), (11, 0)])  # arms and forearms, roll
    window.plot_selection()
    pump(app, 0.3)
    bottom = [d for d in window.dynamic_docks
              if window.dockWidgetArea(d) == Qt.DockWidgetArea.BottomDockWidgetArea]
    window.resizeDocks(bottom, [430] * len(bottom), Qt.Orientation.Vertical)
    bottom[0].raise_()  # the joint angles in front of the event log
    window.set_data(True)
    wait_for(app, lambda: window.model.latest.index > 1200, 40)
    window.set_data(False)
    pump(app, 0.8)
    save_widget(window, "main-window-with-plots.png")
    window.shutdown()
    window.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
