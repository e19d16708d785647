"""Sensor model of the simulated suit: true orientations and motion → raw counts.

Filter-frame sensor values (docs/units.md), for IMU i with true DCM ``R_i = C_i E_i``
(``E_i`` its mounting misalignment):

- accel, Gravity counts, the gravity direction: ``Gravity_i R_iᵀ (g - a_lin) / 9.81`` with
  ``g = (0, 0, 9.81)`` m/s² (NED) and ``a_lin`` the IMU's world linear acceleration;
- mag, ±100 units at the full field: ``100 R_iᵀ m`` with ``m = (cos dip, 0, sin dip)`` plus an
  optional magnet near a point (:class:`MagDisturbance`);
- gyro, rad/s: the mean body rate over the sample interval, ``log(R_{k-1}ᵀ R_k) / dt``, which is
  what the filter's ``R_k = R_{k-1}(I + dt skew(ω_k))`` integrates; plus a residual bias.

Each gets white noise, then :meth:`SensorCalibration.uncalibrate` of the *true* calibration
table turns them into raw counts (rounded and saturated to int16).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bpms.filter.calibration import STANDARD_GRAVITY, SensorCalibration
from bpms.filter.rotations import euler_to_dcm
from bpms.io.frames import N_IMUS, N_SENSORS

G_WORLD = np.array([0.0, 0.0, STANDARD_GRAVITY])  # m/s², NED (down)
FOOT_IMUS = {"right": 1, "left": 13}


@dataclass(frozen=True)
class SensorModel:
    """Settings of the simulated sensors."""

    dip_deg: float = 60.0  # magnetic dip (inclination), positive = field points down
    acc_noise_counts: float = 1.5  # accel white noise, rms, Gravity counts
    mag_noise: float = 0.5  # mag white noise, rms, calibrated units (full field = 100)
    gyro_noise_dps: float = 0.3  # gyro white noise, rms, °/s
    gyro_bias_dps: float = 0.0  # residual bias magnitude per IMU (random direction), °/s
    mounting_error_deg: float = 3.0  # rms per axis of the IMU mounting misalignment, °
    heel_strike_g: float = 2.5  # peak |accel| on the foot IMU at a heel strike, g
    heel_strike_frames: int = 3  # length of the impact transient, frames


@dataclass(frozen=True)
class MagDisturbance:
    """A magnet near a fixed world point for a time window (raised-cosine ramps).

    The added field, in calibrated units (Earth's field = 100), is ``strength * direction``
    scaled by ``(1 + (d / radius)²)^-1.5`` with d the IMU's distance to ``position``.
    """

    t0: float
    t1: float
    position: tuple[float, float, float]  # m, NED
    strength: float = 60.0
    radius: float = 0.2  # m
    direction: tuple[float, float, float] = (0.0, 1.0, 0.0)  # world NED (unit)
    ramp_s: float = 0.5


def mounting_errors(rng: np.random.Generator, rms_deg: float) -> np.ndarray:
    """``[18, 3, 3]`` small fixed rotations (roll, pitch, yaw each ~ N(0, rms_deg))."""
    angles = np.deg2rad(rng.normal(0.0, rms_deg, size=(N_IMUS, 3)))
    return euler_to_dcm(angles[:, 0], angles[:, 1], angles[:, 2])


def rotation_log(R: np.ndarray) -> np.ndarray:
    """Rotation vectors ``[..., 3]`` (axis × angle, rad) of rotation matrices ``[..., 3, 3]``."""
    v = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                        R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    s = np.linalg.norm(v, axis=-1)
    c = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    angle = np.arctan2(s, c)
    factor = np.where(s > 1e-12, angle / np.maximum(s, 1e-300), 1.0)
    return v * factor[..., None]


def body_rates(R: np.ndarray, dt: float) -> np.ndarray:
    """``[N, 18, 3]`` rad/s: sample k's mean body rate over [t_{k-1}, t_k]; sample 0 reads 0."""
    out = np.zeros((*R.shape[:-2], 3))
    rel = np.swapaxes(R[:-1], -1, -2) @ R[1:]
    out[1:] = rotation_log(rel) / dt
    return out


def heel_strike_spikes(t: np.ndarray, strikes: list[tuple[float, str]], acc_lin: np.ndarray,
                       model: SensorModel, dt: float) -> np.ndarray:
    """World linear acceleration ``[N, 18, 3]`` of the foot IMUs' heel-strike impacts (an
    upward transient, not integrated into the positions), sized so that the foot accel's
    magnitude peaks at ``model.heel_strike_g``."""
    spikes = np.zeros_like(acc_lin)
    n = model.heel_strike_frames
    shape = np.sin(np.pi * (np.arange(n) + 1) / (n + 1))  # peak 1 in the middle
    for time_s, side in strikes:
        kc = round(time_s / dt)  # the peak sits on the strike's sample
        k0 = kc - n // 2
        imu = FOOT_IMUS[side]
        if not 0 <= kc < len(t):
            continue
        v = G_WORLD - acc_lin[kc, imu]
        target = model.heel_strike_g * STANDARD_GRAVITY
        # |v + m ẑ| = target → m = -v_z + sqrt(v_z² - |v|² + target²)
        m = -v[2] + np.sqrt(max(v[2] ** 2 - v @ v + target**2, 0.0))
        for j in range(n):
            k = k0 + j
            if 0 <= k < len(t):
                spikes[k, imu, 2] -= m * shape[j]  # upward = -z in NED
    return spikes


def magnet_field(t: np.ndarray, imu_pos: np.ndarray, disturbances: list[MagDisturbance]
                 ) -> np.ndarray:
    """Added world field ``[N, 18, 3]`` (calibrated units) of the magnets."""
    field = np.zeros_like(imu_pos)
    for d in disturbances:
        ramp = max(d.ramp_s, 1e-6)
        up = np.clip((t - d.t0) / ramp, 0.0, 1.0)
        down = np.clip((d.t1 - t) / ramp, 0.0, 1.0)
        env = 0.5 * (1 - np.cos(np.pi * np.minimum(up, down)))
        dist = np.linalg.norm(imu_pos - np.asarray(d.position), axis=-1)
        falloff = (1.0 + (dist / d.radius) ** 2) ** -1.5
        direction = np.asarray(d.direction, dtype=np.float64)
        direction = direction / np.linalg.norm(direction)
        field += (d.strength * env[:, None] * falloff)[..., None] * direction
    return field


@dataclass
class SensorValues:
    """Filter-frame sensor values ``[N, 18, 3]``: accel (Gravity counts), mag (±100), gyro
    (rad/s)."""

    acc: np.ndarray
    mag: np.ndarray
    gyr: np.ndarray


def ideal_sensors(R: np.ndarray, acc_lin: np.ndarray, gravity: np.ndarray, dip_deg: float,
                  mag_extra: np.ndarray | None, dt: float) -> SensorValues:
    """Noise-free filter-frame values from true DCMs ``R[N, 18, 3, 3]``, world linear
    accelerations ``acc_lin[N, 18, 3]`` (m/s²) and the Gravity counts ``[18]`` of each IMU."""
    Rt = np.swapaxes(R, -1, -2)
    acc = np.einsum("nkij,nkj->nki", Rt, G_WORLD - acc_lin)
    acc *= (gravity / STANDARD_GRAVITY)[None, :, None]
    dip = np.deg2rad(dip_deg)
    field = np.broadcast_to(100.0 * np.array([np.cos(dip), 0.0, np.sin(dip)]), acc.shape)
    if mag_extra is not None:
        field = field + mag_extra
    mag = np.einsum("nkij,nkj->nki", Rt, field)
    gyr = body_rates(R, dt)
    return SensorValues(acc, mag, gyr)


def add_noise(values: SensorValues, model: SensorModel, rng: np.random.Generator,
              bias_rng: np.random.Generator) -> SensorValues:
    """White noise on all three sensors, plus the per-IMU residual gyro bias."""
    shape = values.acc.shape
    bias_dir = bias_rng.normal(size=(N_IMUS, 3))
    bias_dir /= np.linalg.norm(bias_dir, axis=-1, keepdims=True)
    bias = np.deg2rad(model.gyro_bias_dps) * bias_dir
    # One draw per sample, so a shorter recording is a prefix of a longer one (same seed).
    white = rng.standard_normal((shape[0], N_IMUS, 3, 3))
    return SensorValues(
        acc=values.acc + model.acc_noise_counts * white[..., 0, :],
        mag=values.mag + model.mag_noise * white[..., 1, :],
        gyr=values.gyr + bias + np.deg2rad(model.gyro_noise_dps) * white[..., 2, :],
    )


def to_raw(values: SensorValues, calibration: SensorCalibration) -> np.ndarray:
    """Raw counts ``int16 [N, 18, 9]`` (rounded, saturated) through the true calibration."""
    raw = calibration.uncalibrate(values.acc, values.mag, values.gyr)
    return np.clip(np.rint(raw), -32768, 32767).astype(np.int16)


def inject_errors(raw: np.ndarray, rate: float, rng: np.random.Generator
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Fail each (frame, IMU, sensor) with probability ``rate``: its error bit is set and its
    three values read 0 (half the failures) or garbage (the other half). Returns (raw, flags)."""
    flags = np.zeros((*raw.shape[:-1], N_SENSORS), dtype=bool)
    if rate <= 0:
        return raw, flags
    draw = rng.random((*flags.shape, 2))  # per sample: fail?, zero or garbage?
    flags = draw[..., 0] < rate
    raw = raw.copy()
    view = raw.reshape(*raw.shape[:-1], N_SENSORS, 3)
    idx = np.nonzero(flags)
    garbage = ((draw[idx][:, 1:] * 1e6 * np.arange(1, 4)) % 65536 - 32768).astype(np.int16)
    garbage[draw[idx][:, 1] < 0.5] = 0
    view[idx] = garbage
    return raw, flags
