"""Speed of the filter bank on a 30-minute 18-IMU session, against imufusion, vqf and ahrs.

Run: ``.venv/bin/python bench/filter.py [--minutes 30] [--peer-seconds 60]``.

The session is the simulated suit's scripted motion (``bpms.firmware.sim.session.simulate``)
looped to the requested length (90,000 frames = 1.62 M IMU updates for 30 minutes). Printed:

- the first-call cost of the numba kernels: compiling (empty cache, once per installation)
  and loading from numba's on-disk cache (every later process);
- a check that the batch path matches the scalar reference (tests/reference_mahony.py) to 1e-9;
- IMU updates/s of the suite's batch paths: the kernel alone on calibrated inputs, and the
  whole processor (raw counts → calibration → filter → Reset Zero segment orientations);
- the same for the peers, on the same data converted to their units (specific force in m/s²
  or g, gyro rad/s or °/s, magnetometer as is): ``imufusion.Ahrs`` (a per-sample Python
  call, no batch API), ``vqf.VQF.updateBatch`` (compiled loop), ``ahrs.filters.Mahony``
  batch mode (a pure-Python loop). ``ahrs`` runs on ``--peer-seconds`` of data per IMU only
  (it would take minutes on the whole session); the line says how many updates were timed;
- the live path's per-frame latency (18 IMUs), p50/p99/max, kernel only and processor.step.

Figures only; nothing is asserted on time.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bpms.filter import mahony
from bpms.filter.bank import MahonyBank
from bpms.filter.calibration import STANDARD_GRAVITY
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from bpms.io.frames import encode_frame
from tests.reference_mahony import ReferenceMahony

N_IMUS = 18


def _rate(updates: int, seconds: float) -> str:
    rate = updates / seconds / 1e6
    return f"{rate:6.2f} M IMU-updates/s ({updates:,} updates in {seconds:.2f} s)"


def session(minutes: float) -> tuple[np.ndarray, np.ndarray, BodyPoseProcessor]:
    rec = simulate(seed=0)
    n = round(minutes * 60 * 50)
    reps = -(-n // len(rec))
    raw = np.tile(rec.raw, (reps, 1, 1))[:n]
    errors = np.tile(rec.errors, (reps, 1, 1))[:n]
    return raw, errors, BodyPoseProcessor(rec.calibration)


def check_reference(acc, mag, gyr, gravity, frames: int = 2000) -> float:
    """Max difference of the batch kernel from the scalar reference over all IMUs."""
    out = MahonyBank(gravity).process(acc[:frames], mag[:frames], gyr[:frames], store_terms=True)
    worst = 0.0
    for i in range(N_IMUS):
        ref = ReferenceMahony(gravity[i])
        for k in range(frames):
            ref.update(acc[k, i].tolist(), mag[k, i].tolist(), gyr[k, i].tolist())
        worst = max(worst, np.abs(out.R[k, i] - np.array(ref.R)).max(),
                    np.abs(out.w_i[k, i] - np.array(ref.w_i)).max(),
                    np.abs(out.euler[k, i] - [ref.roll, ref.pitch, ref.yaw]).max())
    return float(worst)


def bench_suite(raw, errors, proc) -> None:
    cal = proc.sensor_calibration
    acc, mag, gyr = cal.calibrate(raw)
    n = len(raw)
    bank = MahonyBank(cal.gravity)
    t0 = time.perf_counter()
    bank.process(acc, mag, gyr, errors=errors)
    print(f"suite batch kernel (calibrated in)   {_rate(n * N_IMUS, time.perf_counter() - t0)}")
    p = BodyPoseProcessor(proc.table)
    t0 = time.perf_counter()
    p.process(raw, errors)
    print(f"suite processor (raw in, C out)      {_rate(n * N_IMUS, time.perf_counter() - t0)}")


def bench_live(raw, errors, proc, frames: int = 5000) -> None:
    cal = proc.sensor_calibration
    acc, mag, gyr = cal.calibrate(raw[:frames])
    bank = MahonyBank(cal.gravity)
    lat = np.empty(frames)
    for k in range(frames):
        t0 = time.perf_counter()
        bank.step(acc[k], mag[k], gyr[k], errors[k])
        lat[k] = time.perf_counter() - t0
    p = BodyPoseProcessor(proc.table)
    lat2 = np.empty(frames)
    for k in range(frames):
        t0 = time.perf_counter()
        p.step(raw[k], errors[k])
        lat2[k] = time.perf_counter() - t0
    wire = [encode_frame(raw[k], errors[k]) for k in range(frames)]
    p = BodyPoseProcessor(proc.table)
    lat3 = np.empty(frames)
    for k in range(frames):
        t0 = time.perf_counter()
        p.step_wire(wire[k])
        lat3[k] = time.perf_counter() - t0
    for name, x in (("live MahonyBank.step (18 IMUs)", lat),
                    ("live BodyPoseProcessor.step      ", lat2),
                    ("live BodyPoseProcessor.step_wire ", lat3)):
        us = np.percentile(x, [50, 99]) * 1e6
        print(f"{name} p50 {us[0]:7.1f} µs  p99 {us[1]:7.1f} µs  max {x.max() * 1e6:7.1f} µs")


def peer_inputs(raw, proc):
    """Specific force m/s² (accelerometer reading: minus the filter's gravity direction),
    gyro rad/s, magnetometer (calibrated units), per IMU ``[N, 18, 3]``."""
    acc, mag, gyr = proc.sensor_calibration.calibrate(raw)
    f = -acc / proc.sensor_calibration.gravity[None, :, None] * STANDARD_GRAVITY
    return np.ascontiguousarray(f), np.ascontiguousarray(mag), np.ascontiguousarray(gyr)


def bench_peers(raw, proc, peer_frames: int) -> None:
    f, mag, gyr = peer_inputs(raw, proc)
    n = len(raw)
    try:
        import vqf

        t0 = time.perf_counter()
        for i in range(N_IMUS):
            vqf.VQF(0.02).updateBatch(np.ascontiguousarray(gyr[:, i]),
                                      np.ascontiguousarray(f[:, i]),
                                      np.ascontiguousarray(mag[:, i]))
        print(f"vqf VQF.updateBatch (9D)             {_rate(n * N_IMUS, time.perf_counter() - t0)}")
    except ImportError:
        print("vqf: not installed")
    try:
        import imufusion

        m = n  # a fast C call per sample: the whole session
        g_deg, f_g = np.degrees(gyr[:m]), f[:m] / STANDARD_GRAVITY
        t0 = time.perf_counter()
        for i in range(N_IMUS):
            a = imufusion.Ahrs()
            settings = imufusion.AhrsSettings()
            settings.convention = imufusion.CONVENTION_NED
            settings.sample_rate = 50
            a.set_settings(settings)
            gi, fi, mi = g_deg[:, i], f_g[:, i], mag[:m, i]
            for k in range(m):
                a.update(gi[k], fi[k], mi[k])
        print(f"imufusion Ahrs.update (Python loop)  {_rate(m * N_IMUS, time.perf_counter() - t0)}")
    except ImportError:
        print("imufusion: not installed")
    try:
        from ahrs.filters import Mahony

        m = min(n, peer_frames)
        t0 = time.perf_counter()
        for i in range(N_IMUS):
            Mahony(gyr=gyr[:m, i], acc=f[:m, i], mag=mag[:m, i], frequency=50.0)
        print(f"ahrs Mahony batch (pure Python)      {_rate(m * N_IMUS, time.perf_counter() - t0)}")
    except ImportError:
        print("ahrs: not installed")


def cold_compile_s() -> float:
    """First-ever call cost: compile both kernels with an empty numba cache (subprocess)."""
    import os
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        code = "from bpms.filter.mahony import warm_up; print(warm_up())"
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, timeout=300, cwd=Path(__file__).resolve().parents[1])
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0, help="session length, min")
    parser.add_argument("--peer-seconds", type=float, default=60.0,
                        help="data per IMU for the slow pure-Python peer (ahrs), s")
    args = parser.parse_args()
    print(f"numba kernels, first call with an empty cache (compile): {cold_compile_s():.2f} s")
    print(f"numba kernels, first call in this process (cache load): {mahony.warm_up():.2f} s")
    raw, errors, proc = session(args.minutes)
    n = len(raw)
    print(f"session: {n:,} frames × 18 IMUs = {n * N_IMUS / 1e6:.2f} M IMU updates "
          f"({n / 50 / 60:.1f} min at 50 Hz)")
    acc, mag, gyr = proc.sensor_calibration.calibrate(raw[:2000])
    worst = check_reference(acc, mag, gyr, proc.sensor_calibration.gravity)
    print(f"batch kernel vs scalar reference, 2000 frames × 18 IMUs: max |diff| {worst:.1e} "
          f"({'OK' if worst < 1e-9 else 'FAIL'}, limit 1e-9)")
    bench_suite(raw, errors, proc)
    bench_peers(raw, proc, round(args.peer_seconds * 50))
    bench_live(raw, errors, proc)


if __name__ == "__main__":
    main()
