"""End to end: `bpms record` and `bpms monitor` (real subprocesses) against the simulated suit
over a real pseudo-terminal and over TCP, through a power-cycle and an unplugged device."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from deadlines import scaled
from waiting import wait_until

from bpms.firmware.sim.arbiter import Arbiter, MotionSource
from bpms.firmware.sim.server import PtyServer, TcpServer
from bpms.io.rawfile import read_raw

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def motion():
    return MotionSource.simulated(duration_s=120.0, seed=11)


class Suit:
    """The simulated suit behind a port that can be power-cycled, unplugged and plugged."""

    def __init__(self, kind: str, folder: Path, motion: MotionSource) -> None:
        self.kind = kind
        self.arbiter = Arbiter(motion)
        self.link = folder / "rfcomm-suit"  # pty: a stable name, like a udev link
        self.server = None
        self.tcp_port = 0
        self.plug()

    @property
    def port(self) -> str:
        return str(self.link) if self.kind == "pty" else f"socket://127.0.0.1:{self.tcp_port}"

    def plug(self) -> None:
        self.arbiter.host_disconnected()  # a re-enumerated device: idle
        if self.kind == "pty":
            self.server = PtyServer(self.arbiter).start()
            tmp = self.link.with_suffix(".new")
            os.symlink(self.server.path, tmp)
            os.replace(tmp, self.link)
        else:
            self.server = TcpServer(self.arbiter, port=self.tcp_port).start()
            self.tcp_port = self.server.port

    def unplug(self) -> None:
        if self.kind == "pty":
            self.link.unlink()  # the device node disappears with the device
        self.server.stop()

    def power_cycle(self, off_s: float) -> None:
        """Off for ``off_s`` (nothing either way), then on and idle: a new start is needed."""
        self.arbiter.silence(off_s)
        self.arbiter.host_disconnected()

    def close(self) -> None:
        self.server.stop()


class Cli:
    """A `bpms` subprocess whose output lines are collected as they come."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "bpms", *args], cwd=ROOT,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.lines: list[str] = []
        self._thread = threading.Thread(target=self._collect, daemon=True)
        self._thread.start()

    def _collect(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))

    def wait_line(self, predicate, start: int = 0, timeout: float = 30.0) -> int:
        """Index of the first line from ``start`` on that satisfies ``predicate``."""
        found: list[int] = []

        def check() -> bool:
            for k in range(start, len(self.lines)):
                if predicate(self.lines[k]):
                    found.append(k)
                    return True
            return False

        assert wait_until(check, timeout), f"no such line after {timeout} s:\n" + "\n".join(
            self.lines[-15:])
        return found[0]

    def stop(self) -> tuple[int, str]:
        self.proc.send_signal(signal.SIGINT)
        self.proc.wait(scaled(30))
        self._thread.join(10)
        return self.proc.returncode, self.proc.stderr.read()


def motion_indices(frames: list[bytes], motion: MotionSource, n: int) -> list[int]:
    lookup = {motion.frame(j): j for j in range(n)}
    return [lookup.get(f, -1) for f in frames]


def run_faults(cli: Cli, suit: Suit, streaming, state_is) -> None:
    """Power-cycle the suit, then unplug it and plug it back; the link must come back."""
    k = cli.wait_line(streaming, timeout=40)
    suit.power_cycle(2.0)
    k = cli.wait_line(lambda s: state_is(s, "silent"), k + 1)
    k = cli.wait_line(streaming, k + 1)
    suit.unplug()
    k = cli.wait_line(lambda s: state_is(s, "gone") or state_is(s, "reopening"), k + 1)
    suit.plug()
    k = cli.wait_line(streaming, k + 1)
    cli.wait_line(streaming, k + 1)


@pytest.mark.parametrize("kind", ["pty", "tcp"])
def test_record_survives_a_power_cycle_and_an_unplugged_device(kind, motion, tmp_path):
    suit = Suit(kind, tmp_path, motion)
    try:
        cli = Cli("record", suit.port, "-o", str(tmp_path), "--name", "faults")

        def streaming(line: str) -> bool:
            return line.startswith("t ") and " streaming " in line and \
                float(line.split("Hz")[0].split()[-1]) > 40.0

        def state_is(line: str, state: str) -> bool:
            return line.startswith("t ") and f" {state} " in line

        run_faults(cli, suit, streaming, state_is)
        code, err = cli.stop()
    finally:
        suit.close()
    assert code == 0, err
    assert "Traceback" not in err
    recording = read_raw(tmp_path / "Raw_faults_1.bpmsraw")
    assert recording.problems == []
    n = suit.arbiter.stats.motion_frames
    idx = motion_indices([recording.frame_bytes(k) for k in range(len(recording))], motion, n)
    assert -1 not in idx  # nothing but motion frames: no stale frame recorded
    assert np.all(np.diff(idx) > 0)  # in order, no duplicate
    # Frames missing only where the device really went away: the power-cycle's silence
    # loses none (the suit samples nothing while off); unplugging loses what was in flight.
    missing = n - len(idx)
    assert 0 <= missing <= 20, missing
    assert cli.lines[-1].startswith(f"recorded {len(recording)} frames to ")
    assert suit.arbiter.stats.starts >= 3  # first start, after the power-cycle, after replug


@pytest.mark.parametrize("kind", ["pty", "tcp"])
def test_monitor_survives_a_power_cycle_and_an_unplugged_device(kind, motion, tmp_path):
    suit = Suit(kind, tmp_path, motion)
    try:
        cli = Cli("monitor", suit.port)

        def streaming(line: str) -> bool:
            return line.startswith("t ") and line.endswith(" V") and \
                float(line.split("rate")[1].split("Hz")[0]) > 40.0

        def state_is(line: str, state: str) -> bool:
            return line.startswith("t ") and f"  {state.upper()}" in line

        run_faults(cli, suit, streaming, state_is)
        code, err = cli.stop()
    finally:
        suit.close()
    assert code == 0, err
    assert "Traceback" not in err
    assert cli.lines[0].startswith(f"connected to the suit on {suit.port}; battery 3.35 V")
    frames = [int(line.split("frames")[1].split()[0]) for line in cli.lines[1:]]
    assert frames == sorted(frames) and frames[-1] >= 150, "\n".join(cli.lines)
