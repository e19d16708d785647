"""Playback keeps its plots and its angles (issue 44 items 6, 7): a seek or a frame step while
paused redraws the plots' window up to the new position from the file (no empty plot, no log
line per step), and after 200 random seeks the readout is in the standard ranges."""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import pytest

from bpms.filter.door import process_file
from bpms.firmware.sim.session import simulate
from bpms.gui.angle_readout import poorly_defined
from bpms.gui.layouts import LayoutStore
from bpms.gui.main_window import MainWindow
from bpms.gui.modes import ModeConfig, SessionRunner
from bpms.io.options import Options

DT = 0.02  # s a frame (SPEC: 50 Hz)


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    rec = simulate(duration_s=24.0, seed=2)  # the script's arm phases: forearms past 90°
    return rec.save_raw(tmp_path_factory.mktemp("pb") / "Raw_pb_001.bpmsraw")


@pytest.fixture(scope="module")
def batch(recording):
    """The recording filtered as one stream by the batch road (``bpms filter``)."""
    return process_file(recording)


def _window(qtbot, recording: Path, tmp_path: Path) -> MainWindow:
    config = ModeConfig(mode="file", path=str(recording), recording_dir=str(tmp_path))
    runner = SessionRunner(config, Options())
    runner.prepare()
    window = MainWindow(runner, layout_store=LayoutStore(tmp_path / "layouts.json"),
                        restore_last=False)
    qtbot.addWidget(window)
    window.show()
    qtbot.waitExposed(window)
    window.model.set_refresh_hz(100)
    return window


def _wait_shown(qtbot, window: MainWindow, index: int) -> None:
    qtbot.waitUntil(lambda: window.model.latest is not None
                    and window.model.latest.index == index
                    and _history(window) is not None
                    and abs(_history(window).t[-1] - index * DT) < 1e-9, timeout=10000)


def _history(window: MainWindow):
    """The window's plot history as one block (None before the first frame)."""
    return window.display.history.block(window.panels.table_model.calibration)


def test_a_paused_seek_and_steps_redraw_the_plots_window(qtbot, tmp_path, recording, batch):
    window = _window(qtbot, recording, tmp_path)
    try:
        joints = next(p for p in window.views.plot_windows if p.kind == "joints")
        window.panels.table.select_cells([(5, 1)])  # the right forearm's pitch
        cells = window.views.plot_selection()
        panel = window.panels.playback_panel
        assert panel.window_frames == window.display.history.buffer.capacity == 3000
        target = 900  # 18 s in: the window is the 18 s before it, from frame 0
        panel.slider.setValue(target)
        _wait_shown(qtbot, window, target)
        for plot in (joints, cells):
            qtbot.waitUntil(lambda p=plot: len(p.buffer) == target + 1, timeout=5000)
            t = plot.buffer.view()[:, 0]
            np.testing.assert_allclose(t, np.arange(target + 1) * DT)
            x, y = plot.curves[0].getData()
            assert x is not None and len(x) > 100 and np.isfinite(y).sum() > 100
        # the plotted values are the file's: the batch road's numbers (same stream from
        # frame 0, the recorded events at their frames)
        data = cells.buffer.view()
        np.testing.assert_allclose(data[:, 1], np.degrees(batch.euler_output[:target + 1, 5, 1]),
                                   atol=1e-6)
        # a step forward continues (no seek, nothing re-initialised, no log line)
        seeks = sum("re-initialised (seek)" in e for e in window.model.last_status.events)
        window.mode.step_frames(1)
        _wait_shown(qtbot, window, target + 1)
        qtbot.waitUntil(lambda: len(cells.buffer) == target + 2, timeout=5000)
        assert cells.buffer.view()[-1, 1] == pytest.approx(
            np.degrees(batch.euler_output[target + 1, 5, 1]), abs=1e-6)
        window.model.tick()
        assert sum("re-initialised (seek)" in e
                   for e in window.model.last_status.events) == seeks
        # a step back redraws the window up to the frame before (pre-rolled, not empty)
        window.mode.step_frames(-50)
        _wait_shown(qtbot, window, target + 1 - 50)
        qtbot.waitUntil(lambda: len(cells.buffer) == target + 2 - 50, timeout=5000)
        assert not any("re-initialised (seek)" in t for t in window.panels.event_log.texts())
    finally:
        window.close()


def _standard(euler: np.ndarray) -> np.ndarray:
    """(roll, pitch, yaw) rad with pitch in [-90°, 90°], roll and yaw in (-180°, 180°]."""
    roll, pitch, yaw = np.moveaxis(euler, -1, 0)
    flip = np.cos(pitch) < 0
    roll, yaw = roll + np.pi * flip, yaw + np.pi * flip
    pitch = np.where(flip, np.pi - pitch, pitch)
    pitch = np.angle(np.exp(1j * pitch))
    return np.stack([np.angle(np.exp(1j * roll)), pitch, np.angle(np.exp(1j * yaw))], -1)


def test_the_readout_after_200_random_seeks_is_in_the_standard_ranges(qtbot, tmp_path,
                                                                      recording):
    window = _window(qtbot, recording, tmp_path)
    try:
        panel = window.panels.playback_panel
        rng = random.Random(44)
        n = len(window.runner.replay)
        for _ in range(200):
            target = rng.randrange(n)
            # a run of up to 2 s up to the frame (the readout follows it from its start)
            panel.window_frames = rng.randrange(1, 100)
            panel.seek(target)
            _wait_shown(qtbot, window, target)
            shown = window.panels.table_model.euler  # [18, 3] rad, what the table reads
            own = _standard(np.asarray(window.model.latest.euler_output, np.float64))
            away = ~poorly_defined(own[:, 1])
            assert np.abs(np.degrees(shown[away, 1])).max() <= 90.0 + 1e-9
            assert np.abs(np.degrees(shown[:, [0, 2]])).max() <= 200.0 + 1e-9
            clear = away & (np.abs(np.degrees(own[:, [0, 2]])) < 160.0).all(axis=1)
            np.testing.assert_allclose(shown[clear], own[clear], atol=1e-9)
    finally:
        window.close()


@pytest.fixture(scope="module")
def changes_recording(tmp_path_factory) -> Path:
    """A recording made with the factory filter (mahony) whose session changed a gain at
    frame 100 and switched to the observer filter at frame 300 (events as a live session
    writes them, the settings in force at its start first)."""
    import dataclasses

    from bpms.io.options import FilterOptions
    from bpms.io.rawfile import new_header, write_raw
    from bpms.io.session_events import SessionEvent

    rec = simulate(duration_s=10.0, seed=6)
    path = tmp_path_factory.mktemp("pbc") / "Raw_pbc_001.bpmsraw"
    header = new_header(calibration=rec.calibration.values, notes="changes",
                        extra={"session_events": True})
    start = {k: v for k, v in dataclasses.asdict(FilterOptions()).items() if k != "algorithm"}
    events = [SessionEvent("filter", 0, data={"algorithm": "mahony", "source": "in force"}),
              SessionEvent("gains", 0, data={"values": start, "source": "in force"}),
              SessionEvent("gains", 100, data={"values": {"kp_yaw": 0.3}}),
              SessionEvent("filter", 300, data={"algorithm": "observer"})]
    write_raw(path, 1.7e9 + rec.t, rec.frames, header, events)
    return path


def _seek_values(qtbot, window: MainWindow, target: int) -> np.ndarray:
    """Right forearm pitch (deg) of frames 0..target after a paused seek to ``target``."""
    window.panels.table.select_cells([(5, 1)])
    plot = window.views.plot_selection()
    window.model.latest = None  # (the frame shown before: the same index)
    window.panels.playback_panel.seek(target)
    _wait_shown(qtbot, window, target)
    qtbot.waitUntil(lambda: len(plot.buffer) == target + 1
                    and plot.buffer.view()[0, 0] == 0.0, timeout=5000)
    return plot.buffer.view()[:, 1].copy()


def test_playback_replays_the_recorded_filter_and_gains_not_the_apps(qtbot, tmp_path,
                                                                     changes_recording):
    """Issue 44.2: a filter picked earlier in the app (vqf) does not override the recording's
    own filter and gain changes; choosing one in the playback controls does, and says so."""
    options = Options()
    options.filter.algorithm = "adaptive"  # picked in an earlier session of this app run
    config = ModeConfig(mode="file", path=str(changes_recording), recording_dir=str(tmp_path))
    runner = SessionRunner(config, options)
    runner.prepare()
    assert runner.recorded_filter == "mahony" and runner.playback_filter is None
    window = MainWindow(runner, layout_store=LayoutStore(tmp_path / "layouts.json"),
                        restore_last=False)
    qtbot.addWidget(window)
    window.show()
    window.model.set_refresh_hz(100)
    try:
        panel = window.panels.playback_panel
        assert panel.override_label.isHidden()
        assert window.panels.gains_panel.filter_combo.currentText() == "mahony"
        shown = _seek_values(qtbot, window, 400)
        # the recorded filter switch was applied at its frame
        assert runner.session.processor.options.filter.algorithm == "observer"
        recorded = process_file(changes_recording)  # the batch road, as recorded
        np.testing.assert_allclose(shown, np.degrees(recorded.euler_output[:401, 5, 1]),
                                   atol=1e-6)
        # chosen in the playback controls: played again with it, and said on screen
        panel.filter_combo.setCurrentIndex(panel.filter_combo.findData("adaptive"))
        assert not panel.override_label.isHidden()
        assert "adaptive" in panel.override_label.text()
        assert "not applied" in panel.override_label.text()
        assert "adaptive (chosen in playback)" in \
            window.panels.status_panel.labels["options"].text()
        shown = _seek_values(qtbot, window, 400)
        assert runner.session.processor.options.filter.algorithm == "adaptive"
        chosen = process_file(changes_recording, algorithm="adaptive")
        np.testing.assert_allclose(shown, np.degrees(chosen.euler_output[:401, 5, 1]),
                                   atol=1e-6)
        assert np.abs(chosen.euler_output[:401, 5, 1]
                      - recorded.euler_output[:401, 5, 1]).max() > 1e-3  # a real difference
        # back to "as recorded": no word on screen, the recorded numbers again
        panel.filter_combo.setCurrentIndex(0)
        assert panel.override_label.isHidden()
        assert "chosen" not in window.panels.status_panel.labels["options"].text()
        shown = _seek_values(qtbot, window, 400)
        np.testing.assert_allclose(shown, np.degrees(recorded.euler_output[:401, 5, 1]),
                                   atol=1e-6)
    finally:
        window.close()


def test_a_filter_switch_inside_a_run_keeps_the_estimates_per_frame():
    """The playback tick reads every sample's estimates: a run with a switch from mahony (no
    body acceleration) to the observer (one) has them for every frame, NaN before."""
    from bpms.filter.processor import BodyPoseProcessor
    from bpms.io.session_events import SessionEvent

    rec = simulate(duration_s=2.0, seed=7)
    result = BodyPoseProcessor(rec.calibration).process(
        rec.raw, rec.errors, [(60, SessionEvent("filter", data={"algorithm": "observer"}))])
    est = result.estimates
    assert est.shape == (len(rec.raw), 18, 6)
    assert np.isnan(est[:60, :, 3:]).all() and np.isfinite(est[60:, :, 3:]).any()


def test_playback_opens_the_recording_once_through_the_door(tmp_path, recording,
                                                            monkeypatch):
    """Issue 44.1: one pass over the file at opening (it was two: the replay's reader and the
    door's survey), and the door's processor is the session's."""
    from bpms.io import raw_reader

    passes: list[Path] = []
    original = raw_reader.RawFile.pieces

    def counted(self, offset=None, *args, **kwargs):
        if offset is None:  # a pass from the data's start
            passes.append(self.path)
        return original(self, offset, *args, **kwargs)

    monkeypatch.setattr(raw_reader.RawFile, "pieces", counted)
    runner = SessionRunner(ModeConfig(mode="file", path=str(recording),
                                      recording_dir=str(tmp_path)), Options())
    try:
        runner.prepare()
        assert passes == [recording]
        assert runner.session.processor is runner._opened.processor
        assert runner.replay.recording is runner._opened.slots
    finally:
        runner.close()
