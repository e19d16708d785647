"""The raw recording has priority on disk space (issue 26.5): below the reserve the filtered
file stops first and the status line says so; the raw file goes on until the disk is full.
`bpms record --sim --filtered` as a real process, with the reserve option set higher than
any disk, and (where this user may mount one) on a real 1 MiB tmpfs."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from deadlines import scaled

from bpms.io.filtered_file.reader import read_filtered
from bpms.io.rawfile import read_raw

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[1]
RECORD = 8 + 340  # bytes of one raw record (docs/raw-format.md)


def record(folder: Path, options: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bpms", "record", "--sim", "--filtered",
                           "-o", str(folder), "--name", "disk", "--options", str(options),
                           *extra], cwd=ROOT, capture_output=True, text=True, timeout=scaled(100))


def record_until_write_error(folder: Path, options: Path) -> tuple[int, str, str]:
    """``bpms record`` until its status line reports the write error (the disk is full),
    then Ctrl-C: (exit code, stdout, stderr)."""
    proc = subprocess.Popen([sys.executable, "-m", "bpms", "record", "--sim", "--filtered",
                             "-o", str(folder), "--name", "disk", "--options", str(options),
                             "--seconds", "90"], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    out = []
    try:
        for line in proc.stdout:
            out.append(line)
            if "WRITE ERROR" in line:
                break
    finally:
        proc.send_signal(signal.SIGINT)
        rest, err = proc.communicate(timeout=scaled(30))
    return proc.returncode, "".join(out) + rest, err


def test_a_reserve_larger_than_the_disk_stops_the_filtered_file_and_keeps_the_raw(tmp_path):
    options = tmp_path / "options.toml"
    options.write_text("[logging]\ndisk_reserve_s = 1e8\n")  # 1.7 PB: more than any disk
    run = record(tmp_path, options, "--seconds", "3")
    assert run.returncode == 0, run.stderr
    assert "Traceback" not in run.stderr
    lines = run.stdout.splitlines()
    assert any(line.startswith("event: ") and "filtered recording stopped: free disk space"
               in line and "kept for the raw recording" in line for line in lines), run.stdout
    status = [line for line in lines if line.startswith("t ")]
    assert status and all("FILTERED FILE STOPPED: free disk space" in line
                          for line in status), run.stdout
    raw = read_raw(tmp_path / "Raw_disk_1.bpmsraw")
    filtered = read_filtered(tmp_path / "Filtered_disk_1.csv")
    assert len(raw) >= 100  # the raw recording went on for its 3 s
    assert len(filtered.t) < 50  # the filtered file stopped within its first second


def _mount_tmpfs(where: Path, size: str) -> bool:
    if not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    where.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                          capture_output=True)
    return done.returncode == 0


def test_on_a_full_1_mib_disk_the_raw_file_gets_the_reserve(tmp_path):
    disk = tmp_path / "disk"
    if not _mount_tmpfs(disk, "1m"):
        pytest.skip("cannot mount a tmpfs here (needs root); the reserve test above runs")
    try:
        options = tmp_path / "options.toml"
        options.write_text("[logging]\ndisk_reserve_s = 12\n")  # 209 kB of the 1 MiB
        code, out, err = record_until_write_error(disk, options)
        usage = shutil.disk_usage(disk)
        raw = read_raw(disk / "Raw_disk_1.bpmsraw")
        filtered = read_filtered(disk / "Filtered_disk_1.csv")
        raw_bytes = (disk / "Raw_disk_1.bpmsraw").stat().st_size
        filtered_bytes = (disk / "Filtered_disk_1.csv").stat().st_size
    finally:
        with contextlib.suppress(OSError):
            subprocess.run(["umount", str(disk)], check=False)
    assert "Traceback" not in err
    assert code == 1 and "recording FAILED" in err, err  # the disk got full
    assert "FILTERED FILE STOPPED" in out
    assert usage.free < 16 * 1024  # truly full: less than four pages left
    # after the filtered file stopped, the raw file alone took at least most of the reserve
    assert len(raw) - len(filtered.t) >= 0.8 * 12 * 50
    assert raw_bytes + filtered_bytes > 0.9 * usage.total
