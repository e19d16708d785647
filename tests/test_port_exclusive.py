"""The suit's port belongs to one program (issue 45.3). 682dd18 opened it without exclusive
access: `bpms monitor PORT` during `bpms record PORT` was not refused, and the recorder lost
the link and 1.5-2 s of frames. Now the second program gets one line, exit 2, and the
recording loses nothing (every motion sample in order: the simulated suit's own numbering is
the truth)."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from pty_suit import suit_pty
from waiting import wait_until

from bpms.firmware.sim.arbiter import Arbiter, MotionSource
from bpms.firmware.sim.server import pty_available
from bpms.io.link import DeviceGoneError, PortInUseError, SuitLink
from bpms.io.rawfile import read_raw

pytestmark = [pytest.mark.timeout(120),
              pytest.mark.skipif(not pty_available(), reason="needs pseudo-terminals")]
ROOT = Path(__file__).resolve().parents[1]


def test_a_second_open_of_the_port_is_refused_and_the_first_keeps_reading():
    motion = MotionSource.simulated(duration_s=10.0, seed=45)
    with suit_pty(Arbiter(motion)) as (_, path), SuitLink(path) as first:
        with pytest.raises(PortInUseError, match=r"^.+ is in use by another program$"):
            SuitLink(path)
        first.start()
        frames = []
        assert wait_until(lambda: frames.extend(first.read_frames()) or len(frames) >= 20, 10)
    assert frames[:20] == [motion.frame(j) for j in range(20)]
    # the test's path is gone with its suit: a late opener can never reach another test's
    with suit_pty(Arbiter(motion)) as (_, other), pytest.raises(DeviceGoneError):
        SuitLink(path)
    assert other != path


def test_monitor_during_a_recording_is_refused_and_the_recording_loses_nothing(tmp_path):
    motion = MotionSource.simulated(duration_s=120.0, seed=45)
    arbiter = Arbiter(motion)
    with suit_pty(arbiter) as (_, path):
        rec = subprocess.Popen([sys.executable, "-m", "bpms", "record", path, "-o",
                                str(tmp_path), "--name", "held"], cwd=ROOT,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        lines: list[str] = []
        reader = threading.Thread(target=lambda: lines.extend(
            line.rstrip("\n") for line in rec.stdout), daemon=True)
        reader.start()
        try:
            assert wait_until(lambda: arbiter.stats.motion_frames >= 100, 60), lines
            mon = subprocess.run([sys.executable, "-m", "bpms", "monitor", path, "--seconds",
                                  "2"], cwd=ROOT, capture_output=True, text=True, timeout=60)
            shown = arbiter.stats.motion_frames
            assert wait_until(lambda: arbiter.stats.motion_frames >= shown + 100, 30)
        finally:
            rec.send_signal(signal.SIGINT)
            _, err = rec.communicate(timeout=60)
            reader.join(10)
        n = arbiter.stats.motion_frames
    assert mon.returncode == 2, (mon.stdout, mon.stderr)
    said = mon.stderr.strip().splitlines()
    assert len(said) == 1 and said[0].endswith(f"{path} is in use by another program"), said
    assert mon.stdout == ""
    assert rec.returncode == 0 and "Traceback" not in err, err
    assert not [x for x in lines if " silent" in x or "reopening" in x or " gone" in x]
    recording = read_raw(tmp_path / "Raw_held_1.bpmsraw")
    lookup = {motion.frame(j): j for j in range(n)}
    idx = [lookup.get(recording.frame_bytes(k), -1) for k in range(len(recording))]
    assert idx == list(range(len(idx)))  # every motion sample from the first, in order
    assert len(idx) >= n - 5  # (the last few may still be in flight at the stop)
    assert np.all(np.diff(recording.times) < 0.5)  # no hole in the recording
