"""Study-batch speed-up: ``bpms batch`` on the same study with 1 and 2 worker processes (and
more with ``--workers``), measured in this run.

Run: ``.venv/bin/python bench/batch.py [--recordings 8] [--minutes 3] [--workers 1 2]``.

The study is the simulated suit's scripted motion looped to ``--minutes`` per recording, as
``--recordings`` files in 2 subject folders; outputs ``rom,parquet``. The command uses the
platform's start method (fork on Linux, the workers inherit the loaded kernels); the "spawn"
start method of Windows and macOS is timed too. Figures only; the load average is printed
since the machine is shared.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bpms.cli import main
from bpms.firmware.sim.session import simulate
from bpms.io.frames import FRAME_PERIOD_S
from bpms.io.rawfile import new_header, write_raw


def run(argv: list[str]) -> float:
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        rc = main(argv)
    if rc:
        raise SystemExit(f"bpms {' '.join(argv)} failed ({rc})")
    return time.perf_counter() - t0


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--recordings", type=int, default=8)
    parser.add_argument("--minutes", type=float, default=3.0)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    rec = simulate(seed=1)
    loops = max(1, int(np.ceil(args.minutes * 60 / (len(rec) * FRAME_PERIOD_S))))
    n = len(rec) * loops
    with tempfile.TemporaryDirectory() as tmp:
        study = Path(tmp) / "study"
        for k in range(args.recordings):
            folder = study / f"S{k % 2 + 1:02d}"
            folder.mkdir(parents=True, exist_ok=True)
            write_raw(folder / f"Raw_trial_{k:03d}.bpmsraw",
                      1.7e9 + np.arange(n) * FRAME_PERIOD_S, rec.frames * loops,
                      new_header(calibration=rec.calibration.values))
        print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        print(f"study: {args.recordings} recordings × {n * FRAME_PERIOD_S / 60:.1f} min")
        times = {}
        for workers in args.workers:
            out = Path(tmp) / f"out{workers}"
            times[workers] = run(["batch", str(study), "-o", str(out), "--workers",
                                  str(workers), "--outputs", "rom,parquet"])
            shutil.rmtree(out)
            base = times[args.workers[0]]
            print(f"{workers} worker(s): {times[workers]:6.1f} s  speed-up "
                  f"{base / times[workers]:.2f}× vs {args.workers[0]} worker(s)")
        # the Windows/macOS start method: every worker loads the filter kernels itself
        from bpms.analysis.batch import find_recordings, run_batch

        jobs = find_recordings(study)
        for workers in [w for w in args.workers if w > 1]:
            t0 = time.perf_counter()
            run_batch(jobs, Path(tmp) / "spawn", ("rom", "parquet"), workers,
                      start_method="spawn")
            elapsed = time.perf_counter() - t0
            print(f"{workers} worker(s), spawn: {elapsed:6.1f} s  speed-up "
                  f"{times[args.workers[0]] / elapsed:.2f}× vs {args.workers[0]} worker(s)")


if __name__ == "__main__":
    main_bench()
