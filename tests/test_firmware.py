"""Firmware (bpms/firmware): the C++ host tests, the AVR build and its size budget, and a
simulated suit run (arbiter + 6 clusters on fake hardware) decoded with the suite's own codec,
so that firmware and host software cannot disagree about the frame."""

from __future__ import annotations

import fcntl
import json
import re
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from bpms.io.frames import FRAME_SIZE, N_CHANNELS, N_IMUS, N_SENSORS, decode_frames
from bpms.io.parser import FrameParser

FIRMWARE = Path(__file__).resolve().parents[1] / "bpms" / "firmware"
HOST_DIR = FIRMWARE / "build" / "host"
AVR_DIR = FIRMWARE / "build" / "avr"
ARDUINO_CORE = Path("/usr/share/arduino/hardware/arduino/avr/cores/arduino")

# Budget (docs/firmware.md): the dissertation's "Arduino Mini w/ ATmega328" setting reserves
# 4 KiB for the bootloader, leaving 28672 bytes of flash; >= 512 of 2048 bytes of RAM must stay
# free for the stack.
FLASH_LIMIT = 28672
RAM_TOTAL = 2048
STACK_MIN = 512

# What sim::scripted_value (sketches/host/fake_hardware.cpp) puts in the chips' registers, in
# chip axes, and the documented chip -> board axis order: board axis i reads chip axis
# CHIP_AXIS[sensor][i] (accel and gyro swap x and y; the magnetometer is already in order).
SPAN = (1000, 4000, 60000)
CHIP_AXIS = ((1, 0, 2), (0, 1, 2), (1, 0, 2))


def _missing(*tools: str) -> list[str]:
    return [t for t in tools if shutil.which(t) is None]


def _make(*targets: str, timeout: float) -> subprocess.CompletedProcess[str]:
    """Run make in bpms/firmware; a lock file keeps parallel test processes from building
    into the same directory at once."""
    (FIRMWARE / "build").mkdir(exist_ok=True)
    with open(FIRMWARE / "build" / ".make.lock", "w") as lock:
        deadline = time.monotonic() + 2 * timeout
        while True:
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    pytest.fail("another process held the firmware build lock for too long")
                time.sleep(0.2)
        return subprocess.run(
            ["make", "--no-print-directory", "-C", str(FIRMWARE), "-j2", *targets],
            capture_output=True,
            text=True,
            timeout=timeout,
            check=False,
        )


@pytest.fixture(scope="session")
def host_build() -> Path:
    missing = _missing("make", "g++")
    if missing:
        pytest.skip(f"{', '.join(missing)} not installed: cannot build the firmware host tests")
    result = _make("host", timeout=180)
    assert result.returncode == 0, result.stdout + result.stderr
    return HOST_DIR


@pytest.fixture(scope="session")
def avr_build() -> str:
    missing = _missing("make", "avr-gcc", "avr-g++", "avr-gcc-ar", "avr-objcopy", "avr-size")
    if missing:
        pytest.skip(
            f"{', '.join(missing)} not installed (tools/dev.sh installs gcc-avr, avr-libc, "
            "arduino-core-avr)"
        )
    if not ARDUINO_CORE.is_dir():
        pytest.skip(f"Arduino core not found at {ARDUINO_CORE} (Debian package arduino-core-avr)")
    result = _make("avr", timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    return result.stdout


def scripted(imu: int, sensor: int, axis: int, sample: int) -> int:
    mix = (sample * 7919 + imu * 104729 + sensor * 1299709 + axis * 15485863) % 2**32
    return mix % SPAN[sensor] - SPAN[sensor] // 2


def expected_frames(
    n_frames: int, faults: set[tuple[int, int, int]], silent: dict[int, set[int]]
) -> tuple[np.ndarray, np.ndarray]:
    """Frames the suit must send: frame j carries, for each cluster, the sample stored at its
    previous answered poll (sample 0 is taken at power-on); a silent poll gives zeros and all
    error bits; a faulty (imu, sensor, sample) gives zeros and that sensor's error bit."""
    raw = np.zeros((n_frames, N_IMUS, N_CHANNELS), dtype=np.int16)
    errors = np.zeros((n_frames, N_IMUS, N_SENSORS), dtype=bool)
    for j in range(n_frames):
        for cluster in range(6):
            dead = silent.get(cluster, set())
            imus = range(3 * cluster, 3 * cluster + 3)
            if j in dead:
                errors[j, imus.start : imus.stop] = True
                continue
            sample = j - sum(1 for p in dead if p < j)
            for imu in imus:
                for s in range(N_SENSORS):
                    if (imu, s, sample) in faults:
                        errors[j, imu, s] = True
                        continue
                    for axis in range(3):
                        raw[j, imu, 3 * s + axis] = scripted(imu, s, CHIP_AXIS[s][axis], sample)
    return raw, errors


def run_suit(host_dir: Path, tmp_path: Path, n_frames: int, faults: bool) -> tuple[bytes, dict]:
    out = tmp_path / "stream.bin"
    scenario = tmp_path / "scenario.json"
    cmd = [str(host_dir / "arbiter_run"), "--frames", str(n_frames), "--out", str(out)]
    if faults:
        cmd += ["--faults", "--scenario", str(scenario)]
    result = subprocess.run(cmd, capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 0, result.stderr
    assert "misrouted 0 host_bytes_lost 0" in result.stdout
    info = json.loads(scenario.read_text()) if faults else {}
    return out.read_bytes(), info


def parse_stream(stream: bytes) -> tuple[bytes, list[bytes], FrameParser]:
    """Split the radio's bytes into the command replies and the frames (fed in odd chunks)."""
    replies = b"BPMS" + b"V3.27\n"
    assert stream.startswith(replies)
    parser = FrameParser()
    frames: list[bytes] = []
    body = stream[len(replies) :]
    for i in range(0, len(body), 97):
        frames += parser.feed(body[i : i + 97])
    frames += parser.flush()
    return replies, frames, parser


def test_host_unit_tests_pass(host_build: Path) -> None:
    result = _make("host-test", timeout=120)
    summaries = re.findall(r"^(\d+) passed, (\d+) failed$", result.stdout, re.MULTILINE)
    assert summaries, result.stdout + result.stderr
    match = summaries[-1]
    assert int(match[1]) == 0, result.stdout
    assert int(match[0]) >= 20
    assert result.returncode == 0


def test_simulated_suit_stream_decodes_to_the_scripted_values(
    host_build: Path, tmp_path: Path
) -> None:
    n = 25
    stream, _ = run_suit(host_build, tmp_path, n, faults=False)
    assert len(stream) == 10 + n * FRAME_SIZE
    _, frames, parser = parse_stream(stream)
    assert len(frames) == n
    assert parser.stats.discarded_bytes == 0
    decoded = decode_frames(b"".join(frames))
    raw, errors = expected_frames(n, set(), {})
    np.testing.assert_array_equal(decoded.raw, raw)
    assert not decoded.errors.any()
    assert np.array_equal(decoded.errors, errors)


def test_simulated_suit_faults_give_the_scripted_error_bits(
    host_build: Path, tmp_path: Path
) -> None:
    n = 25
    stream, info = run_suit(host_build, tmp_path, n, faults=True)
    faults = {(f["imu"], f["sensor"], f["sample"]) for f in info["sensor_faults"]}
    silent = {d["cluster"]: set(d["polls"]) for d in info["silent_polls"]}
    assert faults and silent
    _, frames, parser = parse_stream(stream)
    assert len(frames) == n
    assert parser.stats.discarded_bytes == 0
    decoded = decode_frames(b"".join(frames))
    raw, errors = expected_frames(n, faults, silent)
    np.testing.assert_array_equal(decoded.errors, errors)
    np.testing.assert_array_equal(decoded.raw, raw)
    # A silent cluster's frame: zeros and all nine error bits; it answers stale afterwards.
    assert decoded.errors[8, 15:18].all() and not decoded.raw[8, 15:18].any()
    assert decoded.raw[10, 15, 0] == scripted(15, 0, 1, 8)


def test_arbiter_run_rejects_bad_arguments(host_build: Path) -> None:
    result = subprocess.run(
        [str(host_build / "arbiter_run"), "--frames", "0"],
        capture_output=True,
        text=True,
        timeout=10,
        check=False,
    )
    assert result.returncode == 2
    assert "usage" in result.stderr


def _section_sizes(elf: Path) -> dict[str, int]:
    out = subprocess.run(
        ["avr-size", "-A", str(elf)], capture_output=True, text=True, timeout=30, check=True
    ).stdout
    sizes: dict[str, int] = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0].startswith(".") and parts[1].isdigit():
            sizes[parts[0]] = int(parts[1])
    return sizes


@pytest.mark.parametrize("sketch", ["cluster", "arbiter"])
def test_avr_build_fits_the_atmega328p(avr_build: str, sketch: str) -> None:
    hex_file = AVR_DIR / f"{sketch}.hex"
    lines = hex_file.read_text().splitlines()
    assert lines and all(line.startswith(":") for line in lines)
    assert lines[-1] == ":00000001FF"  # Intel HEX end-of-file record
    sizes = _section_sizes(AVR_DIR / f"{sketch}.elf")
    flash = sizes[".text"] + sizes.get(".data", 0)
    ram = sizes.get(".data", 0) + sizes.get(".bss", 0) + sizes.get(".noinit", 0)
    assert 1000 < flash < FLASH_LIMIT, f"{sketch}: flash {flash} bytes"
    assert RAM_TOTAL - ram >= STACK_MIN, f"{sketch}: static RAM {ram} bytes"
    summary = next(line for line in avr_build.splitlines() if line.startswith(sketch))
    assert f"flash {flash:5d} of {FLASH_LIMIT}" in summary
    assert summary.endswith("OK")
