"""Speed of the analysis commands on a 30-minute recording (90,000 frames).

Run: ``.venv/bin/python bench/analysis.py [--minutes 30]``.

The recording is the simulated suit's scripted motion (``simulate(seed=1)``, 74 s) looped to
the requested length and written as a native raw file with its calibration. Each command runs
in this process through ``bpms.cli.main`` (numba kernels already loaded by a warm-up on a short
file), and the wall time of each is printed with the size of what it wrote. Also printed: the
load average, since the figures scale with what else the machine runs. Figures only.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
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


def _sizes(folder: Path) -> dict[Path, int]:
    return {p: p.stat().st_size for p in folder.rglob("*") if p.is_file()}


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0)
    args = parser.parse_args()
    rec = simulate(seed=1)
    loops = max(1, int(np.ceil(args.minutes * 60 / (len(rec) * FRAME_PERIOD_S))))
    n = len(rec) * loops
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        short = folder / "warmup.bpmsraw"
        write_raw(short, 1.7e9 + rec.t, rec.frames, new_header(
            calibration=rec.calibration.values))
        run(["export", "matlab", str(short), "-o", str(folder / "w.csv")])
        raw = folder / "Raw_long_001.bpmsraw"
        write_raw(raw, 1.7e9 + np.arange(n) * FRAME_PERIOD_S, rec.frames * loops,
                  new_header(calibration=rec.calibration.values))
        print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        print(f"recording: {n} frames = {n * FRAME_PERIOD_S / 60:.1f} min, "
              f"{raw.stat().st_size / 1e6:.1f} MB")
        jobs = [
            ("extract raw --imu all", ["extract", "raw", str(raw), "--imu", "all",
                                       "-o", str(folder / "x.csv")]),
            ("extract raw --imu 0 --calibrated", ["extract", "raw", str(raw), "--imu", "0",
                                                  "--calibrated", "-o", str(folder / "c.csv")]),
            ("export opensim", ["export", "opensim", str(raw), "-o", str(folder / "o")]),
            ("export bvh", ["export", "bvh", str(raw), "-o", str(folder / "b.bvh")]),
            ("export matlab", ["export", "matlab", str(raw), "-o", str(folder / "m.csv")]),
            ("rom (tables + 7 PNG)", ["rom", str(raw), "-o", str(folder / "rom")]),
            ("track (CSV + PNG)", ["track", str(raw), "-o", str(folder / "t.csv")]),
        ]
        for label, argv in jobs:
            before = _sizes(folder)
            elapsed = run(argv)
            after = _sizes(folder)
            size = sum(v for k, v in after.items() if before.get(k) != v) / 1e6
            print(f"{label:36s} {elapsed:6.2f} s  ({size:.1f} MB written)")
        filtered = folder / "Filtered_long_001.csv"
        run(["filter", str(raw), "-o", str(filtered)])
        elapsed = run(["extract", "filtered", str(filtered), "--imu", "all",
                       "-o", str(folder / "f.csv")])
        print(f"{'extract filtered --imu all':36s} {elapsed:6.2f} s")


if __name__ == "__main__":
    main_bench()
