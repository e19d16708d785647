"""Make tests/data/broad_excerpt.npz: a 30 s excerpt of one BROAD trial at the suit's 50 Hz.

BROAD (Laidig, Caruso, Cereatti, Seel, "BROAD — A Benchmark for Robust Inertial Orientation
Estimation", Data 6(7):72, 2021, https://doi.org/10.3390/data6070072), CC BY 4.0; see
tests/data/README.md. Run from the repository root:
``python tools/make_broad_excerpt.py PATH/TO/02_undisturbed_slow_rotation_B.hdf5``.

Resampling to 50 Hz: the gyro is the mean rate over each 20 ms interval (the difference of its
running integral, so no rotation is lost between samples), the accelerometer and magnetometer
are linearly interpolated, the optical truth quaternion is the nearest sample's (NaN kept).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

START_S, LENGTH_S, RATE = 30.0, 30.0, 50.0
OUT = Path(__file__).resolve().parents[1] / "tests" / "data" / "broad_excerpt.npz"


def main(argv: list[str]) -> int:
    import h5py

    src = Path(argv[0])
    with h5py.File(src, "r") as f:
        fs = float(f.attrs["sampling_rate"])
        gyr, acc, mag = (np.asarray(f[k], np.float64) for k in ("imu_gyr", "imu_acc", "imu_mag"))
        quat = np.asarray(f["opt_quat"], np.float64)
        movement = np.asarray(f["movement"], bool)
    t_src = np.arange(len(gyr)) / fs
    t = START_S + np.arange(round(LENGTH_S * RATE) + 1) / RATE
    integral = np.concatenate([np.zeros((1, 3)), np.cumsum(gyr[:-1], axis=0) / fs])
    angle = np.stack([np.interp(t, t_src, integral[:, k]) for k in range(3)], 1)
    rate = np.diff(angle, axis=0) * RATE  # mean rate over (t[k-1], t[k]]
    t = t[1:]

    def lin(x: np.ndarray) -> np.ndarray:
        return np.stack([np.interp(t, t_src, x[:, k]) for k in range(3)], 1)

    near = np.clip(np.rint(t * fs).astype(int), 0, len(t_src) - 1)
    np.savez_compressed(
        OUT, t=(t - t[0]).astype(np.float32), gyr=rate.astype(np.float32),
        acc=lin(acc).astype(np.float32), mag=lin(mag).astype(np.float32),
        opt_quat=quat[near].astype(np.float32), movement=movement[near],
        source=np.array(f"{src.name}, {START_S:.0f}-{START_S + LENGTH_S:.0f} s, 50 Hz"))
    print(f"{OUT}: {OUT.stat().st_size / 1024:.0f} KiB, {len(t)} samples")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
