"""Benchmark: the main window (table + 8 plots + 3 docked 3D views of the solid avatar) against
bare toolkit widgets showing the same data, in the same run, under Xvfb with software GL.

Two phases, each in its own process fed by the same pipeline (a simulated recording replayed
at 1×, 50 frames/s, through a real LiveSession):

- ``app``:  bpms.gui.main_window.MainWindow, "live monitoring" layout, 8 cell plots of 6 curves
  each and 3 docked 3D views;
- ``bare``: the same data in bare widgets: a QTableView over a minimal model, 8 pyqtgraph
  PlotWidgets with 6 PlotCurveItems each (numpy history, setData every tick), 3 GLViewWidgets
  with a grid and one GLMeshItem of the same avatar mesh (each view building its own).

Printed side by side: process CPU (pipeline + GUI, % of one core), plot update rate (Hz, per
plot: mean and slowest), 3D redraw rate (Hz per view), display-tick time p50/p99, samples lost
(fan-out drops and gaps in the plotted time axis). Targets (issue 18.6): plots ≥ 20 Hz, 3D ≥
15 Hz, no sample lost, app CPU ≤ 1.15 × bare CPU.

The CPU ratio only means something when the bare reference keeps its own rates: software GL
on a small machine may not redraw 3 views at 15 Hz, and a reference that skips redraws costs
less. So both phases run twice, with the 3D views and without them (table and plots only);
the verdict uses the configurations whose reference kept its rates and says when one did not.

    QT_QPA_PLATFORM=xcb xvfb-run -a -s "-screen 0 1920x1080x24" \\
        .venv/bin/python bench/gui.py [--seconds 30] [--refresh 30]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
N_PLOTS, N_CURVES, N_VIEWS = 8, 6, 3  # (--plots / --views3d change them, for diagnosis)
SIZE = (1920, 1040)


def make_recording(folder: Path, seconds: float) -> Path:
    from bpms.firmware.sim.session import simulate

    return simulate(duration_s=seconds, seed=1).save_raw(folder / "bench_gui.bpmsraw")


def plot_cells() -> list[list[tuple[int, int]]]:
    """8 × 6 numeric table cells, the same in both phases."""
    from bpms.gui.columns import COLUMNS, TEXT_GROUPS

    rng = np.random.default_rng(0)
    numeric = [(i, c) for i in range(18) for c in range(len(COLUMNS))
               if COLUMNS[c].group not in TEXT_GROUPS]
    return [[numeric[j] for j in sorted(rng.choice(len(numeric), N_CURVES, replace=False))]
            for _ in range(N_PLOTS)]


class PaintCounter:
    """Counts the paint events each watched widget receives (what reached the screen)."""

    def __init__(self, widgets: list) -> None:
        from PyQt6.QtCore import QEvent, QObject

        counts = self.counts = [0] * len(widgets)

        class Filter(QObject):
            def eventFilter(self, obj, event):
                if event.type() == QEvent.Type.Paint:
                    counts[widgets.index(obj)] += 1
                return False

        self._filter = Filter()
        for widget in widgets:
            widget.installEventFilter(self._filter)


def percentiles(values: list[float]) -> tuple[float, float]:
    a = np.array(values) * 1e3
    return (float(np.percentile(a, 50)), float(np.percentile(a, 99))) if len(a) else (0, 0)


def gaps(t: np.ndarray) -> int:
    """Missing 20 ms steps in a plotted time axis."""
    if len(t) < 2:
        return 0
    steps = np.round(np.diff(t) / 0.02).astype(int)
    return int((steps[steps > 1] - 1).sum())


# -- the two phases ----------------------------------------------------------------------------
def run_app(app, recording: Path, folder: Path, refresh: float) -> dict:
    from PyQt6.QtCore import Qt

    from bpms.gui.layouts import LIVE, LayoutStore
    from bpms.gui.main_window import MainWindow
    from bpms.gui.modes import ModeConfig, SessionRunner
    from bpms.io.options import Options

    options = Options()
    options.display.refresh_hz = refresh
    runner = SessionRunner(ModeConfig(mode="file", path=str(recording),
                                      recording_dir=str(folder)), options)
    runner.prepare()
    window = MainWindow(runner, layout_store=LayoutStore(folder / "layouts.json"),
                        restore_last=False)
    # the bench's own size: not maximised (a screen below 1600 x 900 opens it maximised)
    window.setWindowState(Qt.WindowState.WindowNoState)
    window.resize(*SIZE)
    window.layouts.apply_default_layout(LIVE, views3d=N_VIEWS)
    for cells in plot_cells():
        window.panels.table.select_cells(cells)
        window.views.plot_selection()
    window.layouts.tile_plots()  # all 8 in view (new plots beyond the room side by side are tabbed)
    window.show()
    model = window.model

    painted = PaintCounter([p.graphics.viewport() for p in window.views.plot_windows])

    def counters() -> dict:
        return {"plots": [p.redraws for p in window.views.plot_windows],
                "plot_paints": list(painted.counts),
                "views": [v.draws for v in window.views.view3d_windows],
                "paints": [v.view.paints if v.view is not None else 0
                           for v in window.views.view3d_windows]}

    def check() -> dict:
        return {"gaps": max((gaps(p.buffer.view()[:, 0]) for p in window.views.plot_windows),
                            default=0),
                "visible_plots": sum(p.isVisible() for p in window.views.plot_windows),
                "gl": [v.view is not None for v in window.views.view3d_windows]}

    return measure(app, model, runner, window, counters, check)


def run_bare(app, recording: Path, folder: Path, refresh: float) -> dict:
    import pyqtgraph as pg
    import pyqtgraph.opengl as gl
    from PyQt6.QtCore import QAbstractTableModel, QModelIndex, Qt, QTimer
    from PyQt6.QtWidgets import QGridLayout, QMainWindow, QTableView, QWidget

    from bpms.filter.calibration import SensorCalibration
    from bpms.gui import avatar
    from bpms.gui.columns import COLUMNS, TEXT_GROUPS, calibrated, column_values
    from bpms.gui.view3d_geometry import to_display
    from bpms.io.calib_file import load_factory_calibration
    from bpms.io.rawfile import read_raw
    from bpms.io.replay import ReplaySource
    from bpms.pipeline.session import LiveSession

    calibration = SensorCalibration.from_table(load_factory_calibration())
    session = LiveSession(ReplaySource(read_raw(recording), speed=1.0, autoplay=True),
                          recording_dir=folder)
    sub = session.subscribe(maxlen=3000)

    class Model(QAbstractTableModel):
        def __init__(self) -> None:
            super().__init__()
            self.values = np.full((18, len(COLUMNS)), np.nan)

        def rowCount(self, parent=QModelIndex()):  # noqa: B008
            return 18

        def columnCount(self, parent=QModelIndex()):  # noqa: B008
            return len(COLUMNS)

        def data(self, index, role=Qt.ItemDataRole.DisplayRole):
            if role == Qt.ItemDataRole.DisplayRole:
                return f"{self.values[index.row(), index.column()]:.3f}"
            return None

    window = QMainWindow()
    central = QWidget()
    grid = QGridLayout(central)
    window.setCentralWidget(central)
    model = Model()
    table = QTableView()
    table.setModel(model)
    grid.addWidget(table, 0, 0, 1, 2)
    views = []
    for k in range(N_VIEWS):
        view = gl.GLViewWidget()
        view.addItem(gl.GLGridItem())
        mesh = gl.GLMeshItem(smooth=True, computeNormals=True, shader="shaded")
        view.addItem(mesh)
        view.setCameraPosition(distance=3.0)
        grid.addWidget(view, 0, 2 + k)
        views.append((view, mesh))
    cells = plot_cells()
    history = 60 * 50
    plots = []
    plot_widgets: list = []
    for k, plot_cells_k in enumerate(cells):
        widget = pg.PlotWidget()
        plot_widgets.append(widget)
        curves = [widget.plot(pen=pg.mkPen(pg.intColor(j), width=1)) for j in range(N_CURVES)]
        grid.addWidget(widget, 1 + k // 4, k % 4 + (1 if k % 4 >= 2 else 0))
        plots.append((plot_cells_k, curves, np.full((0, 1 + N_CURVES), np.nan)))
    window.resize(*SIZE)
    window.show()
    counts = {"plots": [0] * N_PLOTS, "views": [0] * N_VIEWS}
    painted = PaintCounter([widget.viewport() for widget in plot_widgets])
    ticks: list[float] = []

    def tick() -> None:
        start = time.perf_counter()
        samples = sub.drain()
        if not samples:
            return
        raw = np.array([s.raw for s in samples])
        cal = calibrated(calibration, raw)
        euler = np.array([s.euler for s in samples])
        t = np.array([s.index for s in samples]) * 0.02
        last = samples[-1]
        for c, column in enumerate(COLUMNS):
            if column.group not in TEXT_GROUPS:  # the flags' text columns have no number
                model.values[:, c] = column_values(column, raw[-1:], cal[-1:], euler[-1:],
                                                   True)[0]
        model.dataChanged.emit(model.index(0, 0), model.index(17, len(COLUMNS) - 1))
        for k, (pcells, curves, buf) in enumerate(plots):
            rows = np.empty((len(t), 1 + N_CURVES))
            rows[:, 0] = t
            for j, (imu, col) in enumerate(pcells):
                rows[:, 1 + j] = column_values(COLUMNS[col], raw, cal, euler, True)[:, imu]
            buf = np.concatenate([buf, rows])[-history:]
            plots[k] = (pcells, curves, buf)
            for j, curve in enumerate(curves):
                curve.setData(buf[:, 0], buf[:, 1 + j])
            counts["plots"][k] += 1
        points = to_display(last.joint_positions)
        for k, (_view, mesh) in enumerate(views):
            mesh.setMeshData(vertexes=avatar.figure_vertices(points), faces=avatar.FACES,
                             vertexColors=avatar.VERTEX_COLOURS)
            counts["views"][k] += 1
        ticks.append(time.perf_counter() - start)

    timer = QTimer()
    timer.timeout.connect(tick)
    timer.start(max(1, round(1000 / refresh)))
    session.start()

    class Runner:
        replay = None

    def check() -> dict:
        return {"gaps": max((gaps(buf[:, 0]) for _, _, buf in plots), default=0),
                "visible_plots": N_PLOTS,
                "gl": [True] * N_VIEWS}

    result = measure(app, None, Runner(), window,
                     lambda: {"plots": list(counts["plots"]), "views": list(counts["views"]),
                              "plot_paints": list(painted.counts),
                              "paints": [0] * N_VIEWS}, check, ticks=ticks,
                     dropped=lambda: sub.dropped)
    session.stop()
    return result


def measure(app, model, runner, window, counters, check, ticks=None, dropped=None) -> dict:
    from PyQt6.QtCore import QTimer

    args = ARGS
    if model is not None:
        ticks = window.display.tick_times_s
        window.commands.set_data(True)
    state: dict = {}

    def start() -> None:
        state["c0"] = counters()
        state["cpu0"], state["wall0"] = time.process_time(), time.perf_counter()
        state["ticks0"] = len(ticks)
        state["drop0"] = dropped() if dropped else (model.last_status.dropped
                                                    if model.last_status else 0)

    def stop() -> None:
        wall = time.perf_counter() - state["wall0"]
        state["cpu"] = (time.process_time() - state["cpu0"]) / wall
        c1 = counters()
        state["plot_hz"] = [(b - a) / wall for a, b in zip(state["c0"]["plots"], c1["plots"],
                                                           strict=True)]
        state["view_hz"] = [(b - a) / wall for a, b in zip(state["c0"]["views"], c1["views"],
                                                           strict=True)]
        state["paint_hz"] = [(b - a) / wall for a, b in zip(state["c0"]["paints"],
                                                            c1["paints"], strict=True)]
        state["plot_paint_hz"] = [(b - a) / wall for a, b in zip(
            state["c0"]["plot_paints"], c1["plot_paints"], strict=True)]
        state["ticks"] = percentiles(ticks[state["ticks0"]:])
        now_dropped = dropped() if dropped else model.session.status().dropped
        state["dropped"] = now_dropped - state["drop0"]
        state.update(check())
        app.quit()

    QTimer.singleShot(int(args.warmup * 1000), start)
    QTimer.singleShot(int((args.warmup + args.seconds) * 1000), stop)
    app.exec()
    if model is not None:
        window.shutdown()
    return {k: v for k, v in state.items() if k not in ("c0",)}


def phase(name: str) -> int:
    os.environ.setdefault("QT_QPA_PLATFORM", "xcb")
    from PyQt6.QtWidgets import QApplication

    app = QApplication(sys.argv[:1])
    folder = Path(tempfile.mkdtemp(prefix="bpms-bench-gui-"))
    os.environ["BPMS_CONFIG_DIR"] = str(folder / "config")
    recording = make_recording(folder, ARGS.warmup + ARGS.seconds + 10.0)
    runner = run_app if name == "app" else run_bare
    result = runner(app, recording, folder, ARGS.refresh)
    result["platform"] = app.platformName()
    print("RESULT " + json.dumps(result), flush=True)
    return 0


def per_update(result: dict) -> float:
    """Process CPU per display update (all plots and views redrawn once), ms: the cost of
    the same work when the two sides manage different update rates."""
    hz = float(np.mean(result["plot_hz"])) if result["plot_hz"] else 0.0
    return 1e3 * result["cpu"] / hz if hz else float("nan")


def main() -> int:
    env = {**os.environ, "QT_QPA_PLATFORM": os.environ.get("QT_QPA_PLATFORM", "xcb"),
           "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT),
                                                       os.environ.get("PYTHONPATH")]))}
    verdicts = []
    for views in dict.fromkeys((N_VIEWS, 0)):
        results = {}
        for name in ("bare", "app"):
            cmd = [sys.executable, __file__, "--phase", name, "--seconds", str(ARGS.seconds),
                   "--warmup", str(ARGS.warmup), "--refresh", str(ARGS.refresh),
                   "--plots", str(N_PLOTS), "--views3d", str(views)]
            done = subprocess.run(cmd, env=env, capture_output=True, text=True,
                                  timeout=ARGS.seconds + ARGS.warmup + 180)
            lines = [ln for ln in done.stdout.splitlines() if ln.startswith("RESULT ")]
            if done.returncode != 0 or not lines:
                print(f"{name} phase failed (status {done.returncode}):\n{done.stderr[-2000:]}")
                return 1
            results[name] = json.loads(lines[-1][7:])
        verdicts.append(report(results["app"], results["bare"], views))
    fair = [ratio for ratio, reference_kept_up in verdicts if reference_kept_up]
    print("\nCPU ratio main window / bare where the reference kept its rates: "
          + (", ".join(f"{r:.2f}" for r in fair) if fair else "none (no fair comparison)"))
    return 0


def _rates_met(result: dict, views: int) -> bool:
    return (min(result["plot_hz"], default=0) >= 20
            and (views == 0 or min(result["view_hz"], default=0) >= 15))


def report(app: dict, bare: dict, views: int) -> tuple[float, bool]:
    """Print one configuration's table; (CPU ratio, whether the bare reference kept its
    rates)."""
    print(f"\nGUI benchmark: table + {N_PLOTS} plots × {N_CURVES} curves + {views} 3D views, "
          f"{ARGS.seconds:g} s at 50 frames/s, display timer {ARGS.refresh:g} Hz, "
          f"platform {app['platform']}, window {SIZE[0]}×{SIZE[1]}")
    print(f"{'':22}{'main window':>22}{'bare widgets':>22}")

    def hz(result: dict, key: str) -> str:
        values = result[key]
        return f"{np.mean(values):.1f}/{min(values):.1f}" if values else "–"

    rows = [
        ("process CPU, % core", f"{100 * app['cpu']:.0f}", f"{100 * bare['cpu']:.0f}"),
        ("plots Hz mean/min", hz(app, "plot_hz"), hz(bare, "plot_hz")),
        ("plot paints Hz mean/min", hz(app, "plot_paint_hz"), hz(bare, "plot_paint_hz")),
        ("3D Hz mean/min", hz(app, "view_hz"), hz(bare, "view_hz")),
        ("3D GL paints Hz", f"{np.mean(app['paint_hz']):.1f}" if app["paint_hz"] else "–",
         "–"),
        ("CPU ms per update", f"{per_update(app):.0f}", f"{per_update(bare):.0f}"),
        ("tick ms p50/p99", "{:.1f}/{:.1f}".format(*app["ticks"]),
         "{:.1f}/{:.1f}".format(*bare["ticks"])),
        ("samples lost", f"{app['dropped']} dropped, {app['gaps']} gaps",
         f"{bare['dropped']} dropped, {bare['gaps']} gaps"),
    ]
    for label, a, b in rows:
        print(f"{label:22}{a:>22}{b:>22}")
    ratio = app["cpu"] / bare["cpu"] if bare["cpu"] else float("inf")
    kept_up = _rates_met(bare, views)
    ok = _rates_met(app, views) and app["dropped"] == 0 and app["gaps"] == 0 and ratio <= 1.15
    print(f"CPU per update, main window / bare: {per_update(app) / per_update(bare):.2f}")
    print(f"CPU ratio main window / bare: {ratio:.2f} (target ≤ 1.15); plots ≥ 20 Hz"
          f"{', 3D ≥ 15 Hz' if views else ''}, no sample lost: "
          f"{'all met' if ok else 'NOT all met'}"
          + ("" if kept_up else "; the bare reference missed its own rates: this ratio "
                                "compares against less work"))
    return ratio, kept_up


def _args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=30.0, help="measured time, s")
    ap.add_argument("--warmup", type=float, default=5.0, help="not measured, s")
    ap.add_argument("--refresh", type=float, default=30.0, help="display timer, Hz")
    ap.add_argument("--plots", type=int, default=8)
    ap.add_argument("--views3d", type=int, default=3)
    ap.add_argument("--phase", choices=("app", "bare"), help=argparse.SUPPRESS)
    return ap.parse_args()


ARGS = _args() if __name__ == "__main__" else None
if ARGS is not None:
    N_PLOTS, N_VIEWS = ARGS.plots, ARGS.views3d

if __name__ == "__main__":
    sys.exit(phase(ARGS.phase) if ARGS.phase else main())
