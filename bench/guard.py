"""Cost of the state guard (bpms/filter/guard.py) on the batch and live paths.

Run: ``.venv/bin/python bench/guard.py [--minutes 10]``.

Reference measured in the same run: the same bank without the guard (``bank.process`` /
``bank.step`` on the same calibrated inputs). Printed: IMU updates/s of a batch with and
without the guard, the live step's p50/p99 per frame (18 IMUs) with and without it, and the
batch cost when an event forces a rewind (a pinned gyroscope in the middle of the batch).
Figures only; nothing is asserted on time.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bpms.filter.guard import StateGuard, guarded_process, guarded_step
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate


def _best(fn, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--minutes", type=float, default=10.0)
    args = parser.parse_args()
    rec = simulate(seed=1)
    reps = max(1, round(args.minutes * 3000 / len(rec.raw)))
    raw = np.concatenate([rec.raw] * reps)[: round(args.minutes * 3000)]
    proc = BodyPoseProcessor()
    acc, mag, gyr = proc.calibrate(raw)
    n = len(raw) * 18

    def plain() -> None:
        proc.bank.reset()
        proc.bank.process(acc, mag, gyr)

    def guarded() -> None:
        proc.bank.reset()
        guarded_process(proc.bank, StateGuard(18), acc, mag, gyr)

    plain(), guarded()  # compile / warm
    t_plain, t_guard = _best(plain), _best(guarded)
    print(f"batch {len(raw)} frames: without guard {n / t_plain / 1e6:6.2f} M IMU updates/s, "
          f"with guard {n / t_guard / 1e6:6.2f} M/s ({100 * (t_guard / t_plain - 1):+.1f} %)")

    bad = gyr.copy()
    mid = len(bad) // 2
    bad[mid:mid + 5] = 40.0  # ≈ full scale: the state leaves SO(3), the batch rewinds

    def event() -> None:
        proc.bank.reset()
        guarded_process(proc.bank, StateGuard(18), acc, mag, bad)

    event()
    t_event = _best(event)
    print(f"batch with an event mid-way: {n / t_event / 1e6:6.2f} M IMU updates/s "
          f"(reference without guard {n / t_plain / 1e6:6.2f} M/s)")

    frames = min(len(raw), 3000)
    guard = StateGuard(18)
    for label, fn in (("bank.step   ", lambda k: proc.bank.step(acc[k], mag[k], gyr[k])),
                      ("guarded_step", lambda k: guarded_step(proc.bank, guard, acc[k], mag[k],
                                                              gyr[k]))):
        guard.forget()
        proc.bank.reset()
        times = np.empty(frames)
        for k in range(frames):
            t0 = time.perf_counter()
            fn(k)
            times[k] = time.perf_counter() - t0
        p50, p99 = np.percentile(times[100:] * 1e6, [50, 99])
        print(f"live {label}: p50 {p50:6.1f} µs  p99 {p99:6.1f} µs per frame (18 IMUs)")


if __name__ == "__main__":
    main()
