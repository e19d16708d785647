"""``bpms sim`` and ``bpms monitor`` as real subprocesses."""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import threading
import tty
from pathlib import Path

import pytest
from deadlines import scaled

pytestmark = pytest.mark.timeout(90)

ROOT = Path(__file__).resolve().parents[1]
#: how long the monitor waits for a simulated suit's reply: the default 1 s on a quiet
#: machine, longer on a loaded one (the simulated suit is another Python process to start)
REPLY = ("--timeout", f"{scaled(1.0):.2f}")
STATUS = re.compile(
    r"^t +(?P<t>[\d.]+) s  rate +(?P<rate>[\d.]+) Hz  frames +(?P<frames>\d+)  "
    r"resyncs +(?P<resyncs>\d+)  discarded +(?P<discarded>\d+) B  error bits +(?P<errors>\d+)  "
    r"battery (?P<volts>[\d.]+) V$")


def bpms(*args: str) -> list[str]:
    return [sys.executable, "-m", "bpms", *args]


def start_sim(*args: str) -> tuple[subprocess.Popen, str]:
    """``bpms sim ...`` in the background; returns it and its first output line."""
    proc = subprocess.Popen(bpms("sim", *args), cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    ready, _, _ = select.select([proc.stdout], [], [], scaled(30.0))
    if not ready:
        proc.kill()
        pytest.fail("bpms sim printed nothing within 30 s")
    return proc, proc.stdout.readline().strip()


def stop_sim(proc: subprocess.Popen) -> tuple[int, str]:
    proc.send_signal(signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        pytest.fail("bpms sim did not stop on SIGINT")
    return proc.returncode, err


def status_lines(out: str) -> list[re.Match]:
    return [m for m in map(STATUS.match, out.splitlines()) if m]


def test_monitor_against_bpms_sim_on_a_pty():
    sim, path = start_sim("--pty")
    try:
        assert re.fullmatch(r"/dev/pts/\d+", path), path
        mon = subprocess.run(bpms("monitor", path, "--seconds", "3", *REPLY), cwd=ROOT,
                             capture_output=True, text=True, timeout=30)
    finally:
        code, err = stop_sim(sim)
    assert mon.returncode == 0, mon.stderr
    lines = mon.stdout.splitlines()
    assert lines[0] == f"connected to the suit on {path}; battery 3.35 V"
    status = status_lines(mon.stdout)
    assert len(status) >= 2 and len(lines) == 1 + len(status)
    for m in status:
        assert 45.0 <= float(m["rate"]) <= 55.0
        assert m["resyncs"] == "0" and m["discarded"] == "0" and m["errors"] == "0"
        assert m["volts"] == "3.35"
    frames = [int(m["frames"]) for m in status]
    assert frames == sorted(frames) and frames[-1] >= 95
    assert "Traceback" not in mon.stderr
    assert code == 0 and "stopped;" in err and "Traceback" not in err


def test_monitor_counts_faults_over_tcp_in_fast_mode():
    sim, url = start_sim("--tcp", "0", "--fast", "--drop-rate", "0.05", "--error-rate", "0.001")
    try:
        assert re.fullmatch(r"socket://127\.0\.0\.1:\d+", url), url
        mon = subprocess.run(bpms("monitor", url, "--seconds", "1.5", *REPLY), cwd=ROOT,
                             capture_output=True, text=True, timeout=30)
    finally:
        code, _ = stop_sim(sim)
    assert mon.returncode == 0, mon.stderr
    (m,) = status_lines(mon.stdout)[:1]
    assert int(m["resyncs"]) > 0 and int(m["discarded"]) > 0 and int(m["errors"]) > 0
    assert code == 0


def test_monitor_without_a_suit_never_passes_off_the_simulated_one():
    mon = subprocess.run(bpms("monitor", "--seconds", "1.5", "--timeout", "0.3"), cwd=ROOT,
                         capture_output=True, text=True, timeout=60)
    assert mon.returncode == 2 and mon.stdout == ""
    (line,) = mon.stderr.strip().splitlines()
    assert re.fullmatch(r"bpms monitor: no suit answered on \d+ candidate port\(s\) .*--sim.*",
                        line), line


def test_monitor_sim_says_simulated_on_every_line():
    mon = subprocess.run(bpms("monitor", "--sim", "--seconds", "2.5", *REPLY), cwd=ROOT,
                         capture_output=True, text=True, timeout=60)
    assert mon.returncode == 0, mon.stderr
    lines = mon.stdout.splitlines()
    assert re.fullmatch(r"connected to the SIMULATED suit on /dev/pts/\d+; battery 3\.35 V",
                        lines[0]), lines[0]
    assert len(lines) >= 3 and all(line.endswith("  SIMULATED") for line in lines[1:])
    status = status_lines("\n".join(line.removesuffix("  SIMULATED") for line in lines))
    assert len(status) == len(lines) - 1 and int(status[-1]["frames"]) >= 50


def test_monitor_on_a_port_that_does_not_exist():
    mon = subprocess.run(bpms("monitor", "/dev/nonexistent-bpms", "--seconds", "1"), cwd=ROOT,
                         capture_output=True, text=True, timeout=30)
    assert mon.returncode != 0
    assert mon.stderr.strip() == ("bpms monitor: cannot open /dev/nonexistent-bpms: "
                                  "No such file or directory")
    assert mon.stdout == ""


def test_monitor_on_a_port_that_answers_garbage():
    master, slave = os.openpty()
    tty.setraw(slave)
    stop = threading.Event()

    def answer() -> None:
        while not stop.is_set():
            ready, _, _ = select.select([master], [], [], 0.02)
            if ready:
                os.read(master, 1024)
                os.write(master, b"AT OK\r\n\xff\x00")

    thread = threading.Thread(target=answer, daemon=True)
    thread.start()
    try:
        mon = subprocess.run(bpms("monitor", os.ttyname(slave), "--timeout", "0.5"), cwd=ROOT,
                             capture_output=True, text=True, timeout=30)
    finally:
        stop.set()
        thread.join(1.0)
        os.close(master)
        os.close(slave)
    assert mon.returncode != 0
    lines = mon.stderr.strip().splitlines()
    assert len(lines) == 1 and "did not answer 'BPMS' within 0.5 s" in lines[0], mon.stderr


def test_sim_rejects_bad_options_in_one_line():
    bad = subprocess.run(bpms("sim", "--pty", "--drop-rate", "2"), cwd=ROOT,
                         capture_output=True, text=True, timeout=30)
    assert bad.returncode == 2 and bad.stdout == ""
    assert bad.stderr.strip() == ("bpms sim: error: argument --drop-rate: 2: must be at least "
                                  "0 and at most 1")


def test_monitor_counts_the_error_bits_the_simulated_suit_set():
    """The monitor's error-bit count is the number of sensor failures the simulated suit
    injected (its own count), read through the one frame decoder."""
    import numpy as np

    from bpms.commands.monitor import count_error_bits
    from bpms.firmware.sim.arbiter import CMD_START, Arbiter, Faults, MotionSource
    from bpms.io.frames import FRAME_SIZE

    rng = np.random.default_rng(7)
    raw = rng.integers(-2000, 2000, (40, 18, 9)).astype(np.int16)
    suit = Arbiter(MotionSource(raw), Faults(error_rate=0.05), realtime=False, seed=3)
    suit.receive(bytes([CMD_START]))
    data = b"".join(b"".join(suit.poll()) for _ in range(30))
    frames = [data[k:k + FRAME_SIZE] for k in range(0, len(data), FRAME_SIZE)]
    assert len(frames) == suit.stats.frames_sent > 100
    assert suit.stats.error_flags > 50
    assert count_error_bits(frames) == suit.stats.error_flags
    assert count_error_bits(frames[:1]) == 0  # the stale first frame carries no flag
    assert count_error_bits([]) == 0
