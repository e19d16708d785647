"""Starting the desktop app: the display check, the QApplication, the start-up window.

:func:`display_problem` is Qt-free so ``bpms gui`` can refuse cleanly (one line, exit 2)
before Qt is imported when there is no display.
"""

from __future__ import annotations

import logging
import os
import signal
import sys
from collections.abc import Mapping

log = logging.getLogger(__name__)

HEADLESS_HINT = ("use the headless commands instead: bpms monitor, bpms record, bpms filter, "
                 "bpms replay")


def display_problem(env: Mapping[str, str] | None = None) -> str | None:
    """Why no window can be shown (one line), or None when a display is available.

    A display is DISPLAY or WAYLAND_DISPLAY, or an explicit QT_QPA_PLATFORM (e.g. offscreen).
    """
    env = os.environ if env is None else env
    if sys.platform in ("win32", "darwin"):
        return None
    if env.get("QT_QPA_PLATFORM") or env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"):
        return None
    return f"no display (DISPLAY and WAYLAND_DISPLAY are unset); {HEADLESS_HINT}"


def run(*, options_path: str | None = None, calibration_path: str | None = None,
        simulated: bool = False, recording_dir: str | None = None, seed: int = 0,
        sim_options: dict | None = None, subject: str | None = None) -> int:
    """Run the app until its last window closes. Returns the exit status. ``sim_options``:
    the simulated subject's, ``subject`` the subject's profile of the live sessions
    (:class:`bpms.gui.modes.ModeConfig`)."""
    from PyQt6.QtCore import QTimer
    from PyQt6.QtWidgets import QApplication

    from bpms.gui.startup import StartupWindow
    from bpms.io.calib_file import load_calibration
    from bpms.io.options import load_options

    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("BPMS Suite")
    # none given: the start-up window takes the user's defaults (else factory)
    options = load_options(options_path) if options_path else None
    calibration = load_calibration(calibration_path) if calibration_path else None
    startup = StartupWindow(options, calibration, recording_dir)
    startup.seed_spin.setValue(seed)
    startup.sim_options = dict(sim_options or {})
    startup.subject = subject or ""
    if options is not None and options.problems:
        startup.load_options_file(options_path)  # shows the warning dialog
    if calibration is not None and calibration.problems:
        startup.load_calibration_file(calibration_path)

    def quitting() -> None:
        if startup.main_window is not None:
            startup.main_window.shutdown()

    app.aboutToQuit.connect(quitting)
    # Ctrl+C in the terminal closes the app cleanly (the timer lets Python see the signal).
    signal.signal(signal.SIGINT, lambda *_: app.quit())
    tick = QTimer()
    tick.timeout.connect(lambda: None)
    tick.start(200)
    if simulated:
        startup.select_mode("sim")
        startup.go()
    else:
        startup.show()
    # Once the event loop runs, Ctrl+C quits cleanly: say so (tests wait for this line).
    QTimer.singleShot(0, lambda: log.info("the app is running (Ctrl+C quits)"))
    return int(app.exec())
