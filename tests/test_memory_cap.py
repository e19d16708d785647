"""Constant memory (issue 18.1): a 30-minute recording goes through every whole-recording
command in a child process whose address space is capped at what the same command needs for a
1-minute recording plus 350 MB. Keeping every frame's results (21–26 MB per recorded minute
before streaming) would need about twice that margin for 30 minutes. Not timed."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

resource = pytest.importorskip("resource")  # not on Windows
if not sys.platform.startswith("linux"):  # RLIMIT_AS is not enforced elsewhere (macOS)
    pytest.skip("address-space limits are enforced on Linux only", allow_module_level=True)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from memory import COMMANDS, make_long_recording  # noqa: E402

MARGIN_MB = 350

_CHILD = """
import resource, sys
limit = int(sys.argv[1])
if limit:
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
from bpms.cli import main
rc = main(sys.argv[2:])
peak = next(int(ln.split()[1]) for ln in open("/proc/self/status") if ln.startswith("VmPeak"))
print(peak * 1024, file=sys.stderr)
sys.exit(rc)
"""


def _run(argv: list[str], limit: int) -> tuple[int, int, str]:
    # compiled kernels for both lengths: a 1-minute recording would otherwise run on the numpy
    # twins without numba, whose address space is not the long run's reference
    env = {**os.environ, "BPMS_TWIN_FRAMES": "0"}
    proc = subprocess.run([sys.executable, "-c", _CHILD, str(limit), *argv],
                          capture_output=True, text=True, timeout=900, env=env)
    lines = proc.stderr.strip().splitlines()
    peak = int(lines[-1]) if lines and lines[-1].isdigit() else 0
    return proc.returncode, peak, proc.stderr


@pytest.mark.slow
def test_30_minutes_through_every_command_under_a_memory_cap(tmp_path):
    short = make_long_recording(tmp_path / "Raw_short_001.bpmsraw", 1.0)
    long = make_long_recording(tmp_path / "Raw_long_001.bpmsraw", 30.0)
    results = {}
    for name, template in COMMANDS.items():
        caps = []
        for raw in (short, long):
            out = tmp_path / raw.stem
            out.mkdir(exist_ok=True)
            filtered = out / "Filtered_input.csv"
            if name == "extract filtered" and not filtered.exists():
                rc, _, err = _run(["filter", str(raw), "-o", str(filtered)], 0)
                assert rc == 0, err[-500:]
            argv = [a.format(raw=raw, out=out, filtered=filtered) for a in template]
            limit = caps[0] + MARGIN_MB * 2**20 if caps else 0
            rc, peak, err = _run(argv, limit)
            assert rc == 0, f"bpms {name} on {raw.name} (cap {limit / 2**20:.0f} MB): " \
                            f"{err[-500:]}"
            caps.append(peak)
        results[name] = caps
    for name, (short_peak, long_peak) in results.items():
        assert long_peak <= short_peak + MARGIN_MB * 2**20, name
    assert os.path.getsize(long) > 30 * 60 * 50 * 340
