"""A live recording under CPU competition (issue 45.5): `bpms record` of the simulated suit at
50 Hz over a real pseudo-terminal, while more CPU-bound processes than the machine has cores
compete for them. Every frame the suit sent is in the file, in order, and the link is never
reported lost (no `silent`, `gone` or `reopening`). The suit's own motion numbering is the
truth (the simulated suit never imports the filters)."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from pty_suit import suit_pty

from bpms.firmware.sim.arbiter import Arbiter, MotionSource
from bpms.firmware.sim.server import pty_available
from bpms.io.rawfile import read_raw

pytestmark = [pytest.mark.timeout(120),
              pytest.mark.skipif(not pty_available(), reason="needs pseudo-terminals")]
ROOT = Path(__file__).resolve().parents[1]
RECORD_S = 4
#: each competitor spins this long at most, even if the test dies (s)
SPIN_LIMIT_S = 40
SPIN = ("import time\nend = time.monotonic() + {limit}\n"
        "while time.monotonic() < end:\n    pass\n")


def test_a_recording_holds_every_frame_with_more_busy_processes_than_cores(tmp_path):
    competitors = (os.cpu_count() or 1) + 2  # more runnable processes than cores
    spinners = [subprocess.Popen([sys.executable, "-c", SPIN.format(limit=SPIN_LIMIT_S)])
                for _ in range(competitors)]
    motion = MotionSource.simulated(duration_s=60.0, seed=455)
    arbiter = Arbiter(motion)  # real time: 50 frames a second
    try:
        with suit_pty(arbiter) as (_server, path):
            rec = subprocess.Popen([sys.executable, "-m", "bpms", "record", path, "-o",
                                    str(tmp_path), "--name", "busy", "--seconds",
                                    str(RECORD_S)], cwd=ROOT, stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True)
            lines: list[str] = []
            reader = threading.Thread(target=lambda: lines.extend(
                line.rstrip("\n") for line in rec.stdout), daemon=True)
            reader.start()
            _, err = rec.communicate(timeout=90)
            reader.join(10)
            sent = arbiter.stats.motion_frames
    finally:
        for p in spinners:
            p.kill()
        for p in spinners:
            p.wait(10)
    assert rec.returncode == 0 and "Traceback" not in err, err
    status = [x for x in lines if x.startswith("t ")]
    assert status, lines
    assert not [x for x in status if " streaming " not in x and " connecting " not in x], \
        status  # never silent, gone or reopening
    recording = read_raw(tmp_path / "Raw_busy_1.bpmsraw")
    lookup = {motion.frame(j): j for j in range(sent)}
    idx = [lookup.get(recording.frame_bytes(k), -1) for k in range(len(recording))]
    assert idx == list(range(len(idx)))  # every motion sample from the first, in order
    assert len(idx) >= RECORD_S * 50 - 10
    assert np.diff(recording.times).max() < 0.5  # no hole
