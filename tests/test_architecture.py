"""docs/architecture.md tells the way of one suit byte through the code; this test runs a live
session on the simulated suit, traces every Python call of the threads involved, and finds the
documented functions in the documented order (one frame's calls form a subsequence of the
thread's calls; a name marked *compiled* is a numba dispatcher, checked to exist instead).

The lists are read from the page itself, so the page and the code cannot drift apart."""

from __future__ import annotations

import importlib
import re
import socket
import sys
import threading
from pathlib import Path

import numpy as np
from waiting import wait_until

from bpms.firmware.sim.arbiter import Arbiter, MotionSource
from bpms.firmware.sim.server import TcpServer
from bpms.io.options import Options, SerialOptions
from bpms.pipeline.session import LiveSession
from bpms.pipeline.sources import SuitFrameSource

PAGE = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"
STEP = re.compile(r"^\d+\. `([\w.]+)`( \*compiled\*)?")


def documented_paths() -> dict[str, list[tuple[str, bool]]]:
    """Each list of the page's path section (by the paragraph before it): [(name, compiled)]."""
    paths: dict[str, list[tuple[str, bool]]] = {}
    title = None
    for line in PAGE.read_text(encoding="utf-8").split("## One suit byte", 1)[1].splitlines():
        step = STEP.match(line)
        if step:
            paths.setdefault(title, []).append((step.group(1), bool(step.group(2))))
        elif line.strip():
            title = line.strip()
    return paths


class CallLog:
    """Every call of a bpms Python function, per thread, as ``module.qualname``."""

    def __init__(self) -> None:
        self.calls: dict[str, list[str]] = {}
        self.lock = threading.Lock()

    def __call__(self, frame, event, arg):
        if event == "call":
            name = frame.f_globals.get("__name__", "")
            if name.startswith("bpms."):
                thread = threading.current_thread().name
                with self.lock:
                    self.calls.setdefault(thread, []).append(
                        f"{name}.{frame.f_code.co_qualname}")
        return None


def _resolves(name: str) -> bool:
    parts = name.split(".")
    for k in range(len(parts) - 1, 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        for attr in parts[k:]:
            obj = getattr(obj, attr, None)
        return obj is not None
    return False


def _in_order(wanted: list[str], calls: list[str]) -> list[str]:
    """The names of ``wanted`` not found, in order, in ``calls`` (empty: all found)."""
    it = iter(calls)
    missing = []
    for name in wanted:
        if not any(call == name for call in it):
            missing.append(name)
            it = iter(calls)  # report every missing name, not only the first
    return missing


def test_one_frame_takes_the_documented_way(qtbot, tmp_path):
    from bpms.gui.data_table import ImuTableModel

    paths = documented_paths()
    assert len(paths) == 6 and all(paths.values()), paths
    for steps in paths.values():
        for name, _ in steps:
            assert _resolves(name), f"docs/architecture.md names {name}, which does not exist"
    options = Options()
    listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listener.bind(("127.0.0.1", 0))
    listener.settimeout(10.0)
    options.udp.forward_to = [f"127.0.0.1:{listener.getsockname()[1]}"]
    log = CallLog()
    arbiter = Arbiter(MotionSource.simulated(seed=2), realtime=True)
    with TcpServer(arbiter) as server:
        session = LiveSession(SuitFrameSource(server.url, SerialOptions()), options,
                              recording_dir=tmp_path)
        sub = session.subscribe(maxlen=1000)
        session.source.connect()
        threading.settrace(log)  # before the threads start (the raw logger's too)
        try:
            session.start_logging(raw=True, filtered=True, name="trace")
            session.start_forwarding()
            session.start()
            assert wait_until(lambda: session.status().recording.filtered_rows >= 10, 30)
        finally:
            threading.settrace(None)
            session.stop()
    datagram = listener.recv(65536)
    listener.close()
    assert datagram[:4] == b"BPMS"
    samples = sub.drain()
    assert samples
    # a display shows a sample whose numbers nobody read yet (the filtered writer may have read
    # those of the session's last frames): the next frame, filtered by the same processor
    from bpms.pipeline.sample import PoseSample

    last = samples[-1]
    result, raw, errors = session.processor.step_wire(last.frame)
    shown = PoseSample(last.index + 1, last.host_time, last.frame, raw[0], errors[0],
                       result=result)
    model = ImuTableModel(session.processor.sensor_calibration)
    sys.settrace(log)
    try:
        model.update(shown)
        text = model.data(model.index(2, 0))
    finally:
        sys.settrace(None)
    assert text not in (None, "")
    threads = {"Acquisition": "bpms-acquisition", "Raw logger": "bpms-raw-logger",
               "Processing": "bpms-processing",
               "Display": threading.current_thread().name}
    for title, steps in paths.items():
        key = next(k for k in threads if title.startswith(k))
        calls = [c for thread, cs in log.calls.items()
                 if thread == threads[key] for c in cs]
        wanted = [name for name, compiled in steps if not compiled]
        assert not _in_order(wanted, calls), (title, _in_order(wanted, calls))
        for name, compiled in steps:
            if compiled:  # a numba dispatcher: no Python frame, but it must be one
                module, _, attr = name.rpartition(".")
                assert type(getattr(importlib.import_module(module), attr)).__name__ \
                    == "CPUDispatcher", name
    assert np.isfinite(samples[-1].joint_angles).all()
