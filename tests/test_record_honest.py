"""`bpms record` tells the truth about its file: a full disk or a removed folder is shown on
every later line, the final line gives the frames really on the disk and the frames lost, the
exit code is 1; and frames received before a silence are on the disk within a second."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from test_link_faults_e2e import Cli, Suit
from waiting import wait_until

from bpms.firmware.sim.arbiter import MotionSource
from bpms.io.rawfile import read_raw

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[1]

# Runs `bpms` with the raw file wrapped so that the disk is "full" after BUDGET bytes: the
# write that does not fit raises ENOSPC, exactly as the OS does. No production hook needed.
DISK_FULL_WRAPPER = r'''
import errno, sys
import bpms.io.rawfile as rawfile

BUDGET = int(sys.argv.pop(1))

class FullDisk:
    def __init__(self, f):
        self._f, self.used = f, 0
    def write(self, data):
        if self.used + len(data) > BUDGET:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.used += len(data)
        return self._f.write(data)
    def __getattr__(self, name):
        return getattr(self._f, name)

_init = rawfile.RawWriter.__init__
def init(self, *a, **kw):
    _init(self, *a, **kw)
    self._file = FullDisk(self._file)
    self._file.used = self._data_offset
rawfile.RawWriter.__init__ = init

from bpms.cli import main
sys.exit(main(sys.argv[1:]))
'''


@pytest.fixture(scope="module")
def motion():
    return MotionSource.simulated(duration_s=120.0, seed=13)


@contextlib.contextmanager
def full_disk(tmp_path: Path, how: str):
    """(folder, command prefix): with ``how == "tmpfs"`` a 64 kB tmpfs when it can be mounted
    (unmounted whatever happens); otherwise an ordinary folder and a writer that fails with
    ENOSPC after 64 kB."""
    disk = tmp_path / "small"
    disk.mkdir()
    mounted = (how == "tmpfs" and os.name == "posix" and os.geteuid() == 0
               and shutil.which("mount") is not None
               and subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(disk)],
                                  capture_output=True).returncode == 0)
    try:
        if mounted:
            yield disk, [sys.executable, "-m", "bpms"]
        else:
            wrapper = tmp_path / "disk_full.py"
            wrapper.write_text(DISK_FULL_WRAPPER)
            yield disk, [sys.executable, str(wrapper), str(64 * 1024)]
    finally:
        if mounted:
            subprocess.run(["umount", "-l", str(disk)], capture_output=True)


@pytest.mark.parametrize("how", ["tmpfs", "enospc"])
def test_disk_full_during_record(tmp_path, how):
    with full_disk(tmp_path, how) as (disk, prefix):
        proc = subprocess.Popen([*prefix, "record", "--sim", "-o", str(disk), "--name", "full"],
                                cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
        lines: list[str] = []
        try:
            def error_shown_twice() -> bool:
                lines.append(proc.stdout.readline().rstrip("\n"))
                return sum("WRITE ERROR" in line for line in lines) >= 2

            assert wait_until(error_shown_twice, 60), "\n".join(lines)
        finally:
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=30)
        raw = disk / "Raw_full_1.bpmsraw"
        on_disk = len(read_raw(raw))
    lines += out.splitlines()
    assert proc.returncode == 1 and "Traceback" not in err
    status = [line for line in lines if line.startswith("t ")]
    first = next(k for k, line in enumerate(status) if "WRITE ERROR" in line)
    assert all("WRITE ERROR" in line and "No space left" in line for line in status[first:])
    assert all(line.endswith("SIMULATED") for line in status)
    final = err.strip().splitlines()[-1]
    assert final.startswith("recording FAILED: ") and "No space left on device" in final
    assert f"; {on_disk} frames on disk in " in final
    lost = int(final.split(", ")[-1].split()[0])
    frames = int(status[-1].split("frames")[1].split()[0])
    assert on_disk > 50 and lost > 0 and on_disk + lost >= frames


def test_recording_folder_removed_during_record(tmp_path, motion):
    folder = tmp_path / "recordings"
    suit = Suit("pty", tmp_path, motion)
    try:
        cli = Cli("record", suit.port, "-o", str(folder), "--name", "gone")
        raw = folder / "Raw_gone_1.bpmsraw"
        assert wait_until(lambda: raw.exists() and raw.stat().st_size > 20_000, 40)
        shutil.rmtree(folder)
        k = cli.wait_line(lambda s: "WRITE ERROR" in s)
        cli.wait_line(lambda s: "WRITE ERROR" in s, k + 1)
        code, err = cli.stop()
    finally:
        suit.close()
    assert code == 1 and "Traceback" not in err
    assert not folder.exists()
    final = err.strip().splitlines()[-1]
    assert final.startswith("recording FAILED: ") and "removed" in final
    assert "; 0 frames on disk in " in final  # the file went with its folder
    lost = int(final.split(", ")[-1].split()[0])
    assert lost >= suit.arbiter.stats.motion_frames - 5  # all but frames in flight at the end


def test_kill_9_during_a_silence_loses_nothing_received_before(tmp_path, motion):
    suit = Suit("pty", tmp_path, motion)
    try:
        cli = Cli("record", suit.port, "-o", str(tmp_path), "--name", "k9")
        k = cli.wait_line(lambda s: s.startswith("t ") and int(s.split("frames")[1].split()[0])
                          > 100, timeout=40)
        suit.arbiter.silence(30.0)
        sent = suit.arbiter.stats.motion_frames
        # The "silent" state shows after 1 s without data, on a line printed later still:
        # every frame sent before the silence was received more than 1 s before the kill.
        cli.wait_line(lambda s: " silent " in s, k + 1)
        cli.proc.send_signal(signal.SIGKILL)
        cli.proc.wait(30)
    finally:
        suit.close()
    recording = read_raw(tmp_path / "Raw_k9_1.bpmsraw")
    assert recording.problems == []
    assert len(recording) == sent
    assert recording.frames.tobytes() == b"".join(motion.frame(j) for j in range(sent))
