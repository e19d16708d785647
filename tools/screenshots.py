"""Save the documentation screenshots into docs/screenshots/ (run under Xvfb, xcb platform).

    tools/screenshots.sh            # = xvfb-run ... .venv/bin/python tools/screenshots.py
    tools/screenshots.sh playback   # only the steps whose name starts so

At the two screen sizes the app is checked at — 1366 × 768 and 1920 × 1080, the window filling
the screen less a 40-px task bar — in the default layout with one plot and one 3D view:

- ``streaming-<size>.png``: the simulated suit live, logging (REC in the status bar);
- ``playback-<size>.png``: a simulated recording played back (the playback-analysis
  layout, the joint angles in front at the bottom, the user's plot a tab behind them);
- ``udp-client-<size>.png``: the UDP client receiving what a UDP server on this machine
  sends;

and ``wizard-magnetometer.png`` / ``wizard-summary.png`` (the calibration wizard on the
simulated suit, its default size), ``startup.png``, ``3d-view.png`` and
``3d-view-imu-axes.png``. A window that cannot be made is reported in one line and the others
are still saved. Saved layouts of the user running it are not used.
"""

from __future__ import annotations

import os
import socket
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "screenshots"
sys.path.insert(0, str(ROOT))
os.environ.setdefault("QT_QPA_PLATFORM", "xcb")
# removed when the script ends (TemporaryDirectory's finaliser), as is the recordings folder
_CONFIG_FOLDER = tempfile.TemporaryDirectory(prefix="bpms-shots-config-")
os.environ["BPMS_CONFIG_DIR"] = _CONFIG_FOLDER.name

from PyQt6.QtWidgets import QApplication, QWidget  # noqa: E402

#: (name, width, height): the screens, less a 40-px task bar (the window's client area).
SIZES = (("1366x768", 1366, 728), ("1920x1080", 1920, 1040))


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


def make_recording(folder: Path) -> Path:
    from bpms.firmware.sim.session import simulate

    return simulate(duration_s=40.0, seed=2).save_raw(folder / "Raw_sim_001.bpmsraw")


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main_window(config, size: tuple[int, int]):
    from PyQt6.QtCore import QRect

    from bpms.gui.main_window import MainWindow
    from bpms.gui.modes import SessionRunner
    from bpms.io.options import Options

    runner = SessionRunner(config, Options())
    runner.prepare()
    # the screen's available area (less the task bar) as the window sees it: maximised at
    # 1366 x 768 (bpms.gui.screen_fit); on the large screen the user maximises it
    window = MainWindow(runner, restore_last=False, available=QRect(0, 0, *size))
    if not window.placement.maximised:
        window.setGeometry(0, 0, *size)
    window.show()
    return window


def one_plot(app: QApplication, window) -> None:
    """The right forearm's roll, pitch and yaw in a plot (they move in the script)."""
    window.panels.table.select_cells([(5, c) for c in (0, 1, 2)])
    window.views.plot_selection()
    pump(app, 0.3)


def streaming(app: QApplication, folder: Path, label: str, size: tuple[int, int]) -> None:
    from bpms.gui.modes import ModeConfig

    window = main_window(ModeConfig(mode="sim", recording_dir=str(folder)), size)
    try:
        window.commands.set_data(True)
        one_plot(app, window)
        window.panels.file_panel.toggle_logging()
        # 14 s into the script: both arms raised sideways
        wait_for(app, lambda: window.model.latest is not None
                 and window.model.latest.index >= 700, 40)
        pump(app, 0.5)
        save_widget(window, f"streaming-{label}.png")
        if label == SIZES[-1][0]:
            views = window.views.view3d_windows
            if views and views[0].gl_view is not None:
                for name in ("3d-view.png", "3d-view-imu-axes.png"):
                    views[0].snapshot(520, 640).save(str(OUT / name))
                    print(f"saved {OUT / name}")
                    views[0].gl_view.toggle_axes()
            else:
                print("3D view not available (no OpenGL?); 3d-view*.png not saved")
    finally:
        window.shutdown()
        window.close()


def playback(app: QApplication, folder: Path, recording: Path, label: str,
             size: tuple[int, int]) -> None:
    from bpms.gui.modes import ModeConfig

    window = main_window(ModeConfig(mode="file", path=str(recording),
                                    recording_dir=str(folder)), size)
    try:
        window.commands.set_data(True)
        wait_for(app, lambda: window.model.latest is not None, 20)
        one_plot(app, window)
        # 27 s in: the second squat (knees, hips and ankles in the joint angles below)
        wait_for(app, lambda: window.model.latest.index >= 1350, 60)
        joints = next((p for p in window.views.plot_windows if p.kind == "joints"), None)
        if joints is not None:
            window.views.dock_of(joints).raise_()  # the joint angles in front of the user's plot
        pump(app, 0.5)
        save_widget(window, f"playback-{label}.png")
    finally:
        window.shutdown()
        window.close()


def udp_client(app: QApplication, folder: Path, recording: Path, label: str,
               size: tuple[int, int]) -> None:
    """A UDP server on this machine (a recording replayed and forwarded) and the client."""
    from bpms.gui.modes import ModeConfig
    from bpms.io.rawfile import read_raw
    from bpms.io.replay import ReplaySource
    from bpms.pipeline.session import LiveSession

    port = free_port()
    sender = LiveSession(ReplaySource(read_raw(recording), speed=1.0), recording_dir=folder)
    window = main_window(ModeConfig(mode="udp", listen=f"127.0.0.1:{port}",
                                    recording_dir=str(folder)), size)
    try:
        sender.start_forwarding([f"127.0.0.1:{port}"])
        sender.start()
        window.commands.set_data(True)
        wait_for(app, lambda: window.model.latest is not None, 20)
        one_plot(app, window)
        wait_for(app, lambda: window.model.latest.index >= 700, 40)
        pump(app, 0.5)
        save_widget(window, f"udp-client-{label}.png")
    finally:
        sender.stop()
        window.shutdown()
        window.close()


def wizard(app: QApplication, folder: Path) -> None:
    """The calibration wizard on the simulated suit: the magnetometer sweep under way, then
    the summary."""
    from bpms.firmware.sim.calibration_poses import (
        CalibrationSuit,
        ScriptedCalibrationSource,
        changed_table,
    )
    from bpms.gui.calibration_wizard import PAGE_MAG, PAGE_SUMMARY, CalibrationWizard
    from bpms.io.options import Options

    source = ScriptedCalibrationSource(CalibrationSuit(changed_table(), seed=2), speed=0,
                                       burst=20)
    wizard = CalibrationWizard(Options(), source=source, output=folder / "Calib.cfg",
                               poll_ms=20)
    try:
        for i, box in enumerate(wizard.setup.imu_boxes):
            box.setChecked(i in (2, 4, 5, 7))
        for name in ("gyro", "accel"):
            wizard.setup.sensor_boxes[name].setChecked(False)
        wizard.setup.sweep_s.setValue(60.0)
        wizard.move(0, 0)
        wizard.show()
        wizard.next()
        if wizard.currentId() != PAGE_MAG:
            print("wizard: the magnetometer page did not open; wizard-*.png not saved")
            return
        mag = wizard.mag_page
        mag.start.click()
        wait_for(app, lambda: mag.proc.progress > 0.4, 30)
        pump(app, 0.3)
        save_widget(wizard, "wizard-magnetometer.png")
        wait_for(app, mag.isComplete, 60)
        wizard.next()
        if wizard.currentId() == PAGE_SUMMARY:
            pump(app, 0.3)
            save_widget(wizard, "wizard-summary.png")
    finally:
        wizard.reject()


def startup(app: QApplication, folder: Path, recording: Path) -> None:
    from bpms.gui.startup import StartupWindow

    window = StartupWindow(recording_dir=str(folder))
    window.show()
    window.select_mode("file")
    window.file_edit.setText(str(recording))
    window.move(20, 20)
    pump(app, 0.5)
    save_widget(window, "startup.png")
    window.close()


def main() -> int:
    app = QApplication(sys.argv[:1])
    OUT.mkdir(parents=True, exist_ok=True)
    recordings = tempfile.TemporaryDirectory(prefix="bpms-shots-")
    folder = Path(recordings.name)
    recording = make_recording(folder)
    steps = [("start-up window", lambda: startup(app, folder, recording))]
    for label, width, height in SIZES:
        size = (width, height)
        steps += [(f"streaming {label}", lambda s=size, n=label: streaming(app, folder, n, s)),
                  (f"playback {label}",
                   lambda s=size, n=label: playback(app, folder, recording, n, s)),
                  (f"UDP client {label}",
                   lambda s=size, n=label: udp_client(app, folder, recording, n, s))]
    steps.append(("wizard", lambda: wizard(app, folder)))
    only = sys.argv[1:]
    for what, step in steps:
        if only and not any(what.startswith(o) for o in only):
            continue
        try:
            step()
        except Exception as exc:  # one window failing must not cost the others
            print(f"{what}: not saved ({type(exc).__name__}: {exc})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
