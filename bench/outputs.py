"""Binary outputs of a 60-minute session: write time of .mat and Parquet beside ``np.save`` of
the same arrays, and the whole ``bpms convert`` beside ``bpms filter`` of the same file, all
measured in this run.

Run: ``.venv/bin/python bench/outputs.py [--minutes 60]``.

The recording is the simulated suit's scripted motion looped to the requested length. The
commands run in this process through ``bpms.cli.main`` after a warm-up on a short file (numba
kernels loaded). Figures only.
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

from bpms.analysis.binary_out import ExportMeta, open_writer
from bpms.analysis.source import CHUNK_FRAMES
from bpms.cli import main
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from bpms.io.frames import FRAME_PERIOD_S
from bpms.io.rawfile import new_header, read_raw, write_raw


def run(argv: list[str]) -> float:
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        rc = main(argv)
    if rc:
        raise SystemExit(f"bpms {' '.join(argv)} failed ({rc})")
    return time.perf_counter() - t0


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=60.0)
    args = parser.parse_args()
    rec = simulate(seed=1)
    loops = max(1, int(np.ceil(args.minutes * 60 / (len(rec) * FRAME_PERIOD_S))))
    n = len(rec) * loops
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        short = folder / "warmup.bpmsraw"
        write_raw(short, 1.7e9 + rec.t, rec.frames, new_header(
            calibration=rec.calibration.values))
        run(["convert", str(short), "-o", str(folder / "w")])
        run(["filter", str(short), "-o", str(folder / "w.csv")])
        raw = folder / "Raw_long_001.bpmsraw"
        write_raw(raw, 1.7e9 + np.arange(n) * FRAME_PERIOD_S, rec.frames * loops,
                  new_header(calibration=rec.calibration.values))
        print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        print(f"recording: {n} frames = {n * FRAME_PERIOD_S / 60:.1f} min")

        # -- writers alone, on results already computed -----------------------------------
        decoded = read_raw(raw).decode()
        proc = BodyPoseProcessor(rec.calibration)
        results = []
        for lo in range(0, n, CHUNK_FRAMES):
            hi = lo + CHUNK_FRAMES
            r = proc.process(decoded.raw[lo:hi], decoded.errors[lo:hi])
            r.segment_quaternions, r.joint_angles, r.joint_positions  # noqa: B018 (computed here)
            results.append(r)
        meta = ExportMeta(1.7e9, n_frames=n)  # .mat written chunk by chunk
        t0 = time.perf_counter()
        arrays = {"t": np.concatenate([r.t for r in results]),
                  "q": np.concatenate([r.segment_quaternions for r in results]).astype(np.float32),
                  "a": np.degrees(np.concatenate([r.joint_angles for r in results]))
                  .astype(np.float32),
                  "p": np.concatenate([r.joint_positions for r in results]).astype(np.float32)}
        for key, value in arrays.items():
            np.save(folder / f"ref_{key}.npy", value)
        t_npy = time.perf_counter() - t0
        size_npy = sum((folder / f"ref_{k}.npy").stat().st_size for k in arrays) / 1e6
        print(f"{'np.save of the same arrays':34s} {t_npy:6.2f} s  {size_npy:7.1f} MB")
        for kind, suffix in (("mat", ".mat"), ("parquet", ".parquet")):
            target = folder / f"writer{suffix}"
            t0 = time.perf_counter()
            writer = open_writer(kind, target, meta)
            for r in results:
                writer.write(r)
            writer.close()
            elapsed = time.perf_counter() - t0
            print(f"{kind + ' writer':34s} {elapsed:6.2f} s  {target.stat().st_size / 1e6:7.1f} MB"
                  f"  ({elapsed / t_npy:.1f}× np.save)")
        del results, decoded

        # -- whole commands -----------------------------------------------------------------
        t_filter = run(["filter", str(raw), "-o", str(folder / "f.csv")])
        print(f"{'bpms filter (reference)':34s} {t_filter:6.2f} s")
        for kind in ("mat", "parquet"):
            elapsed = run(["convert", str(raw), "-f", kind, "-o", str(folder / f"c_{kind}")])
            print(f"{'bpms convert -f ' + kind:34s} {elapsed:6.2f} s  "
                  f"({elapsed / t_filter:.2f}× bpms filter)")
        elapsed = run(["convert", str(raw), "-o", str(folder / "c_both")])
        print(f"{'bpms convert (both, one pass)':34s} {elapsed:6.2f} s  "
              f"({elapsed / t_filter:.2f}× bpms filter)")


if __name__ == "__main__":
    main_bench()
