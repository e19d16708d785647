"""Sensor calibration: raw counts ↔ filter units (docs/units.md), for all 18 IMUs at once.

Filter frame: X forward, Y right, Z down, after the IMU's pre-rotation R* (docs/suit.md).
- accelerometer: "Gravity counts" (|a| ≈ Gravity ≈ 256–270 at rest), pointing *down*
  (the filter's accel is the gravity direction, +Gravity on Z when level);
- magnetometer: scaled so the full per-axis range is ±100;
- gyroscope: rad/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from bpms.io.calib_file import CalibrationTable
from bpms.io.frames import N_CHANNELS, N_IMUS, N_SENSORS
from bpms.io.mag_ellipsoid import MAG_FULL_SCALE, MagEllipsoid
from bpms.io.options import SensorOptions

STANDARD_GRAVITY = 9.81  # m/s² per g, as the dissertation uses
GYRO_RAD_S_PER_COUNT = 0.06957 * math.pi / 180.0  # ITG-3200: 14.375 LSB per °/s
MAG_GAUSS_PER_COUNT = 0.000917431  # HMC5883L gain, appendix C's GainMag

#: Pre-rotations R* (eq. 2.15–2.17), applied as v' = R* v.
PITCH_90 = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
ROLL_90 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
_PRE_ROTATION_KIND = (
    "pitch", "identity", "pitch", "pitch", "pitch", "pitch", "pitch", "pitch", "pitch",
    "pitch", "pitch", "pitch", "pitch", "identity", "pitch", "roll", "roll", "identity",
)
PRE_ROTATIONS = np.stack(
    [{"pitch": PITCH_90, "roll": ROLL_90, "identity": np.eye(3)}[k] for k in _PRE_ROTATION_KIND]
)
assert PRE_ROTATIONS.shape == (N_IMUS, 3, 3)


@dataclass(frozen=True)
class SensorCalibration:
    """Per-axis offsets and scales of all 18 IMUs, plus sign vectors and pre-rotations.

    Arrays are ``[18, 3]`` unless noted. ``gravity`` is ``[18]`` counts per g.
    """

    gravity: np.ndarray
    accel_offset: np.ndarray
    accel_scale: np.ndarray
    mag_offset: np.ndarray
    mag_scale: np.ndarray
    gyro_avg: np.ndarray
    accel_signs: np.ndarray  # [3]
    mag_signs: np.ndarray  # [3]
    gyro_signs: np.ndarray  # [3]
    pre_rotations: np.ndarray = field(default_factory=PRE_ROTATIONS.copy)  # [18, 3, 3]
    #: Optional magnetometer ellipsoid correction (hard + soft iron): when set, the board
    #: magnetometer is ``signs * (mag_matrix @ (raw - mag_center))`` instead of the per-axis
    #: min/max formula. ``[18, 3, 3]`` and ``[18, 3]``; IMUs without an ellipsoid carry the
    #: min/max values as a diagonal matrix. None (the default) keeps the min/max path untouched.
    mag_matrix: np.ndarray | None = None
    mag_center: np.ndarray | None = None

    @classmethod
    def from_table(
        cls, table: CalibrationTable, sensors: SensorOptions | None = None,
        ellipsoids: dict[int, MagEllipsoid] | None = None,
    ) -> SensorCalibration:
        """Offsets ``(min+max)/2``; accel scale ``Gravity/(max-offset)``; mag scale
        ``100/(max-offset)`` (docs/units.md). ``ellipsoids``: optional per-IMU magnetometer
        ellipsoid fits that replace the min/max magnetometer values of those IMUs."""
        sensors = sensors or SensorOptions()
        acc = table.accel_min_max
        mag = table.mag_min_max
        acc_off = acc.mean(axis=-1)
        mag_off = mag.mean(axis=-1)
        gravity = table.gravity.copy()
        cal = cls(
            gravity=gravity,
            accel_offset=acc_off,
            accel_scale=gravity[:, None] / (acc[..., 1] - acc_off),
            mag_offset=mag_off,
            mag_scale=MAG_FULL_SCALE / (mag[..., 1] - mag_off),
            gyro_avg=table.gyro_avg.copy(),
            accel_signs=np.asarray(sensors.accel_signs, dtype=np.float64),
            mag_signs=np.asarray(sensors.mag_signs, dtype=np.float64),
            gyro_signs=np.asarray(sensors.gyro_signs, dtype=np.float64),
        )
        return cal.with_ellipsoids(ellipsoids) if ellipsoids else cal

    # -- magnetometer ellipsoid ------------------------------------------------------------
    def with_ellipsoids(self, ellipsoids: dict[int, MagEllipsoid]) -> SensorCalibration:
        """A copy whose magnetometer uses ``ellipsoids[imu]`` for the IMUs given (the others
        keep their min/max offset and scale, written as a diagonal matrix)."""
        matrix = (self.mag_matrix.copy() if self.mag_matrix is not None
                  else np.stack([np.diag(s) for s in self.mag_scale]))
        center = (self.mag_center.copy() if self.mag_center is not None
                  else self.mag_offset.copy())
        for imu, ell in ellipsoids.items():
            matrix[imu] = ell.matrix
            center[imu] = ell.center
        return replace(self, mag_matrix=matrix, mag_center=center)

    def mag_correction(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The ellipsoid correction (:meth:`_mag_affine`, computed once), or None."""
        return self._mag_affine

    @cached_property
    def _mag_affine(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The ellipsoid correction as an affine map on the *default* (min/max) filter-frame
        magnetometer: ``m_ellipsoid = K @ m_default + c``, ``K [18, 3, 3]``, ``c [18, 3]``
        (calibrated units). None without ellipsoids. :meth:`calibrate` applies it after the
        min/max formula."""
        if self.mag_matrix is None or self.mag_center is None:
            return None
        rot = self.pre_rotations
        signs = np.diag(self.mag_signs)
        # default: P (raw - o), P = rot S diag(scale); new: rot S A (raw - b)
        P_inv = np.einsum("kij,jl->kil", np.stack([np.diag(1.0 / s) for s in self.mag_scale]),
                          signs) @ np.swapaxes(rot, -1, -2)
        new = rot @ signs @ self.mag_matrix
        K = new @ P_inv
        c = np.einsum("kij,kj->ki", new, self.mag_offset - self.mag_center)
        return K, c

    # -- raw counts → filter units -------------------------------------------------------
    @cached_property
    def _counts_to_units(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(offset ``[18, 9]`` counts, gain ``[18, 9]`` units per count with the axis signs,
        the gains and pre-rotations as one map ``[3, 1, 18, 9, 3]``) for :meth:`calibrate`
        (computed once). The map takes an IMU's 9 offset-free counts to one sensor's 3
        filter-frame axes: ``map[s, 0, i, 3s + c, :] = gain[i, 3s + c] · R*[i]ᵀ[c, :]``, zero
        for the other sensors' counts."""
        offset = np.concatenate([self.accel_offset, self.mag_offset,
                                 np.broadcast_to(self.gyro_avg, (N_IMUS, 3))], axis=-1)
        gain = np.concatenate([self.accel_scale * self.accel_signs,
                               self.mag_scale * self.mag_signs,
                               np.broadcast_to(GYRO_RAD_S_PER_COUNT * self.gyro_signs,
                                               (N_IMUS, 3))], axis=-1)
        rot_t = np.swapaxes(self.pre_rotations, -1, -2)
        to_axes = np.zeros((N_SENSORS, 1, N_IMUS, N_CHANNELS, 3))
        for sensor in range(N_SENSORS):
            rows = slice(3 * sensor, 3 * sensor + 3)
            to_axes[sensor, 0, :, rows, :] = gain[:, rows, None] * rot_t
        return offset, gain, to_axes

    def calibrate(self, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Raw ``[N, 18, 9]`` counts → pre-rotated (accel counts-of-g, mag ±100, gyro rad/s),
        each ``[N, 18, 3]`` C-contiguous float64 in the filter frame. This is what the filters
        consume, the one implementation of docs/units.md's formulas: ``v = R* · s ·
        (raw − offset) · scale`` per sensor (``s`` the axis signs; a magnetometer ellipsoid fit,
        when present, in place of the min/max offset and scale)."""
        offset, _, to_axes = self._counts_to_units
        raw = np.asarray(raw)
        n = raw.shape[0]
        # one product gives the three sensors already apart ([sensor, N, 18, axis]): a live
        # frame pays each numpy call's fixed cost, so no transposed copy after it
        counts = (raw - offset).reshape(1, n, N_IMUS, 1, N_CHANNELS)
        out = (counts @ to_axes).reshape(N_SENSORS, n, N_IMUS, 3)
        acc, mag, gyr = out[0], out[1], out[2]
        correction = self.mag_correction()
        if correction is not None:
            K, c = correction
            mag = np.ascontiguousarray((K @ mag[..., None])[..., 0] + c)
        return acc, mag, gyr

    def physical_units(self, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Raw ``[..., 18, 9]`` → (accel m/s², mag gauss, gyro rad/s) in signed board axes
        (before the pre-rotation), for display and logging (docs/units.md): the accelerometer
        and gyroscope as :meth:`calibrate` before its pre-rotation, the accelerometer then in
        m/s² (``× 9.81 / Gravity``), the magnetometer after offset removal with the HMC5883L
        gain (no scaling to ±100, no ellipsoid)."""
        offset, gain, _ = self._counts_to_units
        raw = np.asarray(raw)
        v = (raw - offset) * gain
        acc = v[..., 0:3] * (STANDARD_GRAVITY / self.gravity)[:, None]
        mag = (raw[..., 3:6] - self.mag_offset) * MAG_GAUSS_PER_COUNT * self.mag_signs
        return acc, mag, v[..., 6:9]

    # -- filter units → raw counts (the simulated suit) ----------------------------------
    def uncalibrate(self, acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`calibrate`: pre-rotated filter-frame vectors ``[..., 18, 3]`` →
        raw counts ``[..., 18, 9]`` (float, not yet rounded or saturated)."""
        rot_t = np.swapaxes(self.pre_rotations, -1, -2)
        acc_b, mag_b, gyr_b = (np.einsum("kij,...kj->...ki", rot_t, np.asarray(v, dtype=np.float64))
                               for v in (acc, mag, gyr))
        raw_acc = acc_b * self.accel_signs / self.accel_scale + self.accel_offset
        if self.mag_matrix is None or self.mag_center is None:
            raw_mag = mag_b * self.mag_signs / self.mag_scale + self.mag_offset
        else:
            inv = np.linalg.inv(self.mag_matrix)
            raw_mag = np.einsum("kij,...kj->...ki", inv, mag_b * self.mag_signs) + self.mag_center
        raw_gyr = gyr_b * self.gyro_signs / GYRO_RAD_S_PER_COUNT + self.gyro_avg
        return np.concatenate([raw_acc, raw_mag, raw_gyr], axis=-1)
