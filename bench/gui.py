"""Benchmark: the desktop app's GUI thread while streaming at 50 Hz.

The main window with its table, 8 plot windows of 6 curves each and 3 3D windows (when
bpms.gui.view3d is available), fed by the simulated suit (real time, 50 frames/s, over a pty)
or by a recording replayed at 1×. Prints:

- tick time: GUI-thread time spent in each display-timer tick (draining the mailbox, the
  table, every plot's ring buffer and curves, the 3D figures), p50 / p99 / max, ms;
- event-loop lag: how late a 10 ms probe timer fires (includes painting), p50 / p99 / max, ms;
- process CPU use (all threads: pipeline + GUI), % of one core, and frames received/dropped.

Run under Xvfb:  QT_QPA_PLATFORM=xcb xvfb-run -a -s "-screen 0 1920x1080x24" \\
                 .venv/bin/python bench/gui.py [--seconds 30] [--source sim|replay]
Aim (issue 5): tick p99 ≤ 33 ms on the 2-core machine.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("QT_QPA_PLATFORM", "xcb")

from PyQt6.QtCore import QTimer
from PyQt6.QtWidgets import QApplication

from bpms.gui.main_window import MainWindow
from bpms.gui.modes import ModeConfig, SessionRunner
from bpms.io.options import Options


def make_recording(folder: Path) -> Path:
    from bpms.firmware.sim.session import simulate
    from bpms.io.rawfile import new_header, write_raw

    rec = simulate(seed=1)
    path = folder / "bench_gui.bpmsraw"
    write_raw(path, 1.7e9 + rec.t, rec.frames, new_header())
    return path


def percentiles(values: list[float]) -> str:
    a = np.array(values) * 1e3
    if len(a) == 0:
        return "no samples"
    return (f"p50 {np.percentile(a, 50):6.2f}  p99 {np.percentile(a, 99):6.2f}  "
            f"max {a.max():6.2f} ms  (n = {len(a)})")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=30.0, help="measured time, s")
    ap.add_argument("--warmup", type=float, default=3.0, help="not measured, s")
    ap.add_argument("--source", choices=("sim", "replay"), default="sim")
    ap.add_argument("--plots", type=int, default=8)
    ap.add_argument("--curves", type=int, default=6)
    ap.add_argument("--views3d", type=int, default=3)
    args = ap.parse_args()

    app = QApplication(sys.argv[:1])
    tmp = Path(tempfile.mkdtemp(prefix="bpms-bench-gui-"))
    if args.source == "sim":
        config = ModeConfig(mode="sim", recording_dir=str(tmp))
    else:
        config = ModeConfig(mode="file", path=str(make_recording(tmp)), recording_dir=str(tmp))
    runner = SessionRunner(config, Options())
    runner.prepare()
    window = MainWindow(runner)
    window.show()

    # Time every display tick (all views connected to the model run inside it).
    ticks: list[float] = []
    measuring = [False]
    model = window.model
    model._timer.timeout.disconnect()

    def timed_tick() -> None:
        start = time.perf_counter()
        model.tick()
        if measuring[0]:
            ticks.append(time.perf_counter() - start)

    model._timer.timeout.connect(timed_tick)

    lags: list[float] = []
    probe = QTimer()
    probe.setInterval(10)
    last = [time.perf_counter()]

    def probe_tick() -> None:
        now = time.perf_counter()
        if measuring[0]:
            lags.append(max(0.0, now - last[0] - 0.010))
        last[0] = now

    probe.timeout.connect(probe_tick)
    probe.start()

    window.set_data(True)
    rng = np.random.default_rng(0)
    numeric = [(i, c) for i in range(18) for c in range(21)]
    for k in range(args.plots):
        picks = rng.choice(len(numeric), args.curves, replace=False)
        window.table.select_cells([numeric[j] for j in sorted(picks)])
        plot = window.plot_selection()
        if plot is not None:
            plot.move(40 * k, 30 * k)
    n3d = 0
    if window.view3d_button.isEnabled():
        for _ in range(args.views3d):
            if window.open_3d_view() is not None:
                n3d += 1
    print(f"source {args.source}; table + {len(window.plot_windows)} plot windows × "
          f"{args.curves} curves + {n3d} 3D windows; platform {app.platformName()}; "
          f"refresh {model.options.display.refresh_hz:g} Hz", flush=True)

    cpu0 = wall0 = 0.0

    def start_measuring() -> None:
        nonlocal cpu0, wall0
        measuring[0] = True
        cpu0, wall0 = time.process_time(), time.perf_counter()

    QTimer.singleShot(int(args.warmup * 1000), start_measuring)
    QTimer.singleShot(int((args.warmup + args.seconds) * 1000), app.quit)
    app.exec()
    cpu = (time.process_time() - cpu0) / (time.perf_counter() - wall0)
    status = model.last_status
    window.shutdown()
    print(f"tick time       {percentiles(ticks)}")
    print(f"event-loop lag  {percentiles(lags)}")
    print(f"process CPU     {cpu * 100:.0f} % of one core")
    if status is not None:
        print(f"frames          {status.frames} received, rate {status.rate_hz:.1f} Hz, "
              f"dropped deliveries {status.dropped}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
