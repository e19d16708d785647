"""The regimes of a filter step planted in the simulated suit's calibrated data, shared by the
tests of each filter kernel against its scalar reference (issue 46.3): accelerations below
0.5 g and above 1.5 g (free fall, heel strikes, a 3 g landing), a missing magnetometer (a zero
field), saturated gyroscopes (±32767 counts) and failed sensors."""

from __future__ import annotations

import numpy as np

from bpms.filter.calibration import GYRO_RAD_S_PER_COUNT, SensorCalibration
from bpms.firmware.sim.session import simulate

#: Frames of the simulated recording (50 Hz).
N = 700
#: |a| / g factors applied from frame 200 to 260, one per IMU: clamps (< 0.5, > 1.5), both
#: slopes, exact edges, free fall (0) and a hard landing (3 g).
ACC_FACTORS = [0.0, 0.2, 0.45, 0.5, 0.55, 0.8, 0.95, 1.05, 1.2, 1.45, 1.5, 1.55, 1.7, 2.0,
               2.5, 3.0, 1.0, 0.3]


def calibrated_suit() -> tuple[np.ndarray, np.ndarray, np.ndarray, SensorCalibration]:
    """(acc, mag, gyr) ``[N, 18, 3]`` (calibrated, pre-rotated; writable copies) and the
    calibration of a simulated recording of N frames (seed 11)."""
    rec = simulate(duration_s=N * 0.02, seed=11)
    cal = SensorCalibration.from_table(rec.calibration)
    acc, mag, gyr = (v.copy() for v in cal.calibrate(rec.raw))
    return acc, mag, gyr, cal


def plant_regimes(acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray) -> np.ndarray:
    """Plant the regimes in ``acc``, ``mag``, ``gyr`` ``[N, 18, 3]`` (in place) and return
    ``errors[N, 18, 3]`` bool (acc, mag, gyr) of the failed sensors, whose values are
    overwritten with what a failed read may carry."""
    acc[200:260] *= np.array(ACC_FACTORS)[None, :, None]
    # short spikes, as heel strikes: 2.2 g on every IMU for 3 frames, then 0.22 g
    acc[300:303] *= 2.2
    acc[330:333] *= 0.1
    mag[380:440, 0:6] = 0.0  # a missing magnetometer: a zero field
    gyro_full = 32767 * GYRO_RAD_S_PER_COUNT
    gyr[460:466, 7] = gyro_full  # saturated gyroscopes (both signs)
    gyr[470:473, 12] = [-gyro_full, gyro_full, -gyro_full]
    errors = np.zeros((N, 18, 3), bool)
    errors[0:15, 3, 1] = True  # no good magnetometer yet: IMU 3 waits to initialise
    errors[520:540, 4, 0] = True  # failed accelerometer
    errors[550:556, 5, 2] = True  # failed gyroscope
    errors[560:600, 6, 1] = True  # failed magnetometer
    errors[610:612, 8] = True  # everything failed
    acc[errors[..., 0]] = 30000.0  # what a failed read may carry
    mag[errors[..., 1]] = -5000.0
    gyr[errors[..., 2]] = 99.0
    return errors
