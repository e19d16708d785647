"""VPython views: importing bpms never imports vpython; the browser view is driven by a
websocket client standing in for the browser (vpython's own HTTP page + websocket protocol)."""

from __future__ import annotations

import json
import os
import re
import socket
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest

from bpms.filter.body_model import SEGMENTS
from bpms.gui.model import SessionModel
from bpms.gui.vpython_views import open_browser_view, vpython_problem
from bpms.pipeline.session import PoseSample


def test_importing_bpms_gui_does_not_import_vpython():
    code = ("import sys, bpms.gui.vpython_views, bpms.gui.view3d, bpms.gui.model; "
            "print('vpython' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60, env={**os.environ, "QT_QPA_PLATFORM": "offscreen"})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"


def test_command_line_without_arguments_is_one_clear_line():
    out = subprocess.run([sys.executable, "-m", "bpms.gui.vpython_views"], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 2
    assert "Traceback" not in out.stderr


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _page(port: int, timeout: float = 30.0) -> str:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            with urllib.request.urlopen(f"http://localhost:{port}/", timeout=2) as response:
                return response.read().decode()
        except OSError:
            time.sleep(0.1)
    raise AssertionError("vpython's page was never served")


class FakeBrowser:
    """What glowcomm.html does: fetch the page, open the websocket, poll with 'trigger'."""

    def __init__(self, http_port: int) -> None:
        import websocket

        page = _page(http_port)
        ws_port = re.search(r"var sock = '(\d+)'", page).group(1)
        # vpython starts its websocket server in a thread after the HTTP one: retry briefly.
        end = time.monotonic() + 20
        while True:
            try:
                self.ws = websocket.create_connection(f"ws://localhost:{ws_port}/", timeout=5)
                break
            except ConnectionRefusedError:
                if time.monotonic() > end:
                    raise
                time.sleep(0.1)
        self.cmds: list[dict] = []
        self.attrs: list[str] = []

    def poll(self) -> None:
        self.ws.send("trigger")
        message = json.loads(self.ws.recv() or "{}")
        self.cmds += message.get("cmds", [])
        self.attrs += message.get("attrs", [])

    def poll_until(self, predicate, timeout: float = 20.0) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.poll()
            if predicate():
                return True
            time.sleep(0.05)
        return False

    def count(self, kind: str) -> int:
        return sum(c.get("cmd") == kind for c in self.cmds)


def _sample(C: np.ndarray) -> PoseSample:
    from bpms.filter.body_model import joint_positions

    nan = np.full((18, 3), np.nan)
    return PoseSample(index=0, host_time=0.0, frame=b"", raw=np.zeros((18, 9), np.int16),
                      errors=np.zeros((18, 3), bool), euler=nan, R=C, C=C,
                      joint_angles=np.full(28, np.nan), joint_positions=joint_positions(C),
                      latency_s=0.0)


@pytest.mark.skipif(vpython_problem() is not None, reason=str(vpython_problem()))
def test_browser_view_draws_the_figure_and_follows_the_model(qtbot, monkeypatch):
    pytest.importorskip("websocket", reason="websocket-client is needed as the fake browser")
    port = _free_port()
    monkeypatch.setenv("VPYTHON_NO_LAUNCH_BROWSER", "1")
    monkeypatch.setenv("VPYTHON_HTTP_PORT", str(port))
    model = SessionModel()
    view = open_browser_view(model)
    try:
        browser = FakeBrowser(port)
        assert browser.poll_until(lambda: browser.count("sphere") == 21)
        assert browser.count("cylinder") == len(SEGMENTS)
        assert browser.count("arrow") == 18 * 3
        cylinders = [c for c in browser.cmds if c.get("cmd") == "cylinder"]
        arm = next(k for k, (_, b, _) in enumerate(SEGMENTS) if b == "elbow_r")
        # Calibration pose: the right arm hangs down 0.34 m (display z up).
        np.testing.assert_allclose(cylinders[arm]["axis"], [0, 0, -0.34], atol=1e-9)

        C = np.broadcast_to(np.eye(3), (18, 3, 3)).copy()
        C[4] = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]  # right arm: segment down → north
        model.samplesArrived.emit([_sample(C)])
        assert view.sent == 1
        idx = cylinders[arm]["idx"]
        expected = f"a{idx}f0.34,0,0"
        assert browser.poll_until(lambda: expected in browser.attrs), browser.attrs[-20:]
        view.close(timeout=10)  # the GUI closes the view while the "tab" is still open
        assert view.process.returncode == 0  # ended by itself, not killed
        browser.ws.close()
    finally:
        view.close(timeout=10)


@pytest.mark.skipif(vpython_problem() is not None, reason=str(vpython_problem()))
def test_script_plays_a_recording_with_a_single_imu_box(tmp_path):
    pytest.importorskip("websocket", reason="websocket-client is needed as the fake browser")
    from bpms.firmware.sim.session import simulate
    from bpms.io.rawfile import new_header, write_raw

    rec = simulate(duration_s=3.0, seed=1)
    path = tmp_path / "Raw_sim_1.bpmsraw"
    write_raw(path, 1.7e9 + rec.t, rec.frames, new_header(notes="simulated"))
    port = _free_port()
    env = {**os.environ, "VPYTHON_NO_LAUNCH_BROWSER": "1", "VPYTHON_HTTP_PORT": str(port)}
    proc = subprocess.Popen([sys.executable, "-m", "bpms.gui.vpython_views", str(path),
                             "--imu", "4", "--mode", "box", "--rate", "50"], env=env)
    try:
        browser = FakeBrowser(port)
        assert browser.poll_until(lambda: browser.count("box") == 1)
        box = next(c for c in browser.cmds if c.get("cmd") == "box")
        # The box turns with the right arm: its axis ('f') and up ('b') are updated. vpython
        # sends an object's newest attributes once per poll, so the count is bounded by the
        # polls during the playback: at 50 frames/s the 3 s give ~40 even on a loaded machine
        # (at 200 frames/s, 0.75 s gave ~10 unloaded and fewer than 6 under load).
        assert browser.poll_until(
            lambda: sum(a.startswith(f"a{box['idx']}f") for a in browser.attrs) > 5)
        assert browser.count("canvas") >= 2  # the body scene and the IMU's own canvas
        assert browser.count("cylinder") == len(SEGMENTS)
        browser.ws.close()  # closing the "tab" ends the script, as in vpython
        assert proc.wait(timeout=15) is not None
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)


@pytest.mark.skipif(vpython_problem() is not None, reason=str(vpython_problem()))
def test_a_browser_that_never_connects_costs_dropped_poses_not_a_blocked_gui(monkeypatch):
    from bpms.gui.vpython_views import BrowserView

    monkeypatch.setenv("VPYTHON_NO_LAUNCH_BROWSER", "1")
    monkeypatch.setenv("VPYTHON_HTTP_PORT", str(_free_port()))
    view = BrowserView()  # vpython waits for a page that never comes: stdin is not read
    try:
        C = np.broadcast_to(np.eye(3), (18, 3, 3))
        results = [view.send(C) for _ in range(200)]  # 200 × 1296 B > a 64 KiB pipe
        assert view.sent + view.dropped == 200
        assert view.dropped > 0 and not all(results)
    finally:
        view.close(timeout=1)
    assert view.process.returncode is not None
