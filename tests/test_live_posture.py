"""Declared-posture calibration live (docs/pose-calibration.md): ``bpms record --sim
--calibration-posture suit``, the field command ``p`` typed while the simulated subject stands
still in the pressure-suit posture (the script's first 3 s). The live filtered file shows the
posture's joint angles (the simulator's own), and ``bpms filter`` of the raw recording gives the
same numbers as the live session, to 1e-9 rad."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from waiting import wait_until

from bpms.cli import main
from bpms.firmware.sim.session import simulate
from bpms.io.filtered_file.reader import read_filtered
from bpms.io.rawfile import read_raw

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def field(tmp_path_factory):
    out = tmp_path_factory.mktemp("posture")
    proc = subprocess.Popen(
        [sys.executable, "-m", "bpms", "record", "--sim", "--filtered", "--calibration-posture",
         "suit", "--posture", "suit", "-o", str(out), "--name", "p", "--seconds", "30"],
        cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, bufsize=1)
    lines: list[str] = []
    frames = [0]

    def read() -> None:
        for line in proc.stdout:
            lines.append(line.rstrip())
            m = re.match(r"t\s+\S+ s .* frames\s+(\d+)", line)
            if m:
                frames[0] = int(m.group(1))

    threading.Thread(target=read, daemon=True).start()
    # the still window holds from 0 to 3 s; the automatic Reset Zero is at 1 s
    assert wait_until(lambda: frames[0] >= 60, 40), lines[-5:]
    proc.stdin.write("p\n")
    proc.stdin.flush()
    assert wait_until(lambda: any("declared posture" in ln for ln in lines), 20), lines[-5:]
    assert wait_until(lambda: frames[0] >= 140, 40), lines[-5:]
    proc.send_signal(signal.SIGINT)
    proc.wait(60)
    assert proc.returncode == 0, proc.stderr.read()
    return out / "Raw_p_1.bpmsraw", out / "Filtered_p_1.csv"


def test_the_posture_calibration_is_recorded(field):
    raw, _ = field
    zeros = [(slot, e.data) for slot, e in read_raw(raw).events if e.kind == "reset_zero"]
    sources = [d["source"] for _, d in zeros]
    assert sources[-2:] == ["posture", "posture"], sources
    (capture_at, capture), (adopt_at, adopt) = zeros[-2:]
    assert adopt["adopt"] is True and adopt["posture"]["knee_r.flexion"] == 15.0
    assert adopt_at == capture_at + 1 and capture["motion_deg"] < 5.0


def test_live_shows_the_posture_and_bpms_filter_repeats_it(field, tmp_path):
    raw, filtered = field
    live = read_filtered(filtered)
    out = tmp_path / "again.csv"
    assert main(["filter", str(raw), "--joints", "-o", str(out)]) == 0
    again = read_filtered(out)
    np.testing.assert_allclose(again.joint_angles, live.joint_angles, rtol=0, atol=1e-9)
    adopt_at = [slot for slot, e in read_raw(raw).events if e.kind == "reset_zero"][-1]
    still = slice(adopt_at + 1, adopt_at + 20)  # still in the posture (before 3 s)
    truth = simulate(seed=0, duration_s=2.0, posture="suit").truth.joint_angles[50]
    err = np.degrees(np.abs(live.joint_angles[still] - truth)).max(axis=0)
    assert err.max() < 2.0, err  # reset-zero would be off by 15-20° here
