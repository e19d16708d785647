"""Sensor model of the simulated suit: true orientations and motion → raw counts.

This is the test suite's *independent forward model*: it is written from the specification's
tables (board mounting and pre-rotations, axis polarities, the calibration table's meaning,
the sensors' data-sheet sensitivities and ranges) and imports nothing from the filter package,
whose inverse (raw counts → filter units) it checks.

Physical values, in each IMU's *filter frame* (X forward, Y right, Z down of its segment in the
calibration pose), for IMU i with true DCM ``R_i = C_i E_i`` (``E_i`` its mounting
misalignment):

- accel, in g, the gravity direction (what the suit's accelerometer convention reads:
  +1 g on the axis that points down at rest): ``R_iᵀ (g - a_lin) / 9.81`` with
  ``g = (0, 0, 9.81)`` m/s² (NED) and ``a_lin`` the IMU's world linear acceleration;
- mag, in units of the Earth's field × 100: ``100 R_iᵀ m``, ``m = (cos dip, 0, sin dip)``,
  plus an optional magnet near a point (:class:`MagDisturbance`);
- gyro, rad/s: the mean body rate over the sample interval, ``log(R_{k-1}ᵀ R_k) / dt``, plus a
  residual bias.

Raw counts (:func:`to_raw`): each vector goes into board axes through the IMU's mounting
(:data:`MOUNTING`, which filter direction each board axis points to), gets the chip's axis
polarity (:data:`POLARITY`), then the calibration table's meaning is applied forwards: the
accelerometer reads ``(min+max)/2 ± (max-min)/2`` at ±1 g, the magnetometer the same at ± the
full field, the gyroscope ``avg + 14.375 counts per °/s`` (ITG-3200 data sheet). The
accelerometer saturates at its configured range (:attr:`SensorModel.accel_range_g`, ±16 g as the
firmware sets the ADXL345; suits with older firmware ran at ±2 g. Full resolution keeps 256
counts per g, so the chip's output ends at ±range × 256 counts); everything saturates at int16.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bpms.firmware.sim.geometry import logm, zyx
from bpms.io.frames import N_IMUS, N_SENSORS

G = 9.81  # m/s² per g (the dissertation's value)
G_WORLD = np.array([0.0, 0.0, G])  # m/s², NED (down)
FOOT_IMUS = {"right": 1, "left": 13}
GYRO_COUNTS_PER_DPS = 14.375  # ITG-3200 sensitivity (data sheet)
ACCEL_COUNTS_PER_G_FULL_RES = 256.0  # ADXL345 full-resolution mode, at every range
ACCEL_RANGES_G = (2.0, 4.0, 8.0, 16.0)  # ADXL345 range settings

# -- board mounting ------------------------------------------------------------------------
#: Filter-frame unit vectors by name (X forward, Y right, Z down).
DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "forward": (1.0, 0.0, 0.0), "back": (-1.0, 0.0, 0.0),
    "right": (0.0, 1.0, 0.0), "left": (0.0, -1.0, 0.0),
    "down": (0.0, 0.0, 1.0), "up": (0.0, 0.0, -1.0),
}
#: Where the board's x, y, z axes point in the calibration pose, per pre-rotation kind of the
#: specification's IMU table. "pitch 90°": the stick runs along the limb with its x axis up,
#: z forward; "roll 90°" (the shoulders): y down, z to the left; "identity" (feet, head):
#: board axes are the body axes.
MOUNTING_KINDS: dict[str, tuple[str, str, str]] = {
    "pitch 90°": ("up", "right", "forward"),
    "roll 90°": ("forward", "down", "left"),
    "identity": ("forward", "right", "down"),
}
#: The specification's IMU table: pre-rotation kind of IMU id 0..17.
MOUNTING: tuple[str, ...] = (
    "pitch 90°",  # 0 right thigh
    "identity",  # 1 right foot
    "pitch 90°",  # 2 right shank
    "pitch 90°",  # 3 right hand
    "pitch 90°",  # 4 right arm
    "pitch 90°",  # 5 right forearm
    "pitch 90°",  # 6 hip (pelvis)
    "pitch 90°",  # 7 neck
    "pitch 90°",  # 8 mid spine
    "pitch 90°",  # 9 left hand
    "pitch 90°",  # 10 left arm
    "pitch 90°",  # 11 left forearm
    "pitch 90°",  # 12 left thigh
    "identity",  # 13 left foot
    "pitch 90°",  # 14 left shank
    "roll 90°",  # 15 right shoulder
    "roll 90°",  # 16 left shoulder
    "identity",  # 17 head
)


#: ``[18, 3, 3]``: per IMU, rows the filter-frame directions of board x, y, z
#: (``v_board = BOARD_AXES[imu] @ v_filter``).
BOARD_AXES = np.array([[DIRECTIONS[name] for name in MOUNTING_KINDS[kind]] for kind in MOUNTING])

#: Chip polarity per board axis (accel, mag, gyro), what the host's sign vectors undo: the
#: accelerometer reads +1 g on a board axis pointing down; the magnetometer's y and z and all
#: three gyro axes read the opposite of the right-handed board-axis value.
POLARITY: dict[str, tuple[float, float, float]] = {
    "accel": (1.0, 1.0, 1.0),
    "mag": (1.0, -1.0, -1.0),
    "gyro": (-1.0, -1.0, -1.0),
}


@dataclass(frozen=True)
class SensorModel:
    """Settings of the simulated sensors."""

    dip_deg: float = 60.0  # magnetic dip (inclination), positive = field points down
    acc_noise_counts: float = 1.5  # accel white noise, rms, raw counts
    mag_noise: float = 0.5  # mag white noise, rms, calibrated units (full field = 100)
    gyro_noise_dps: float = 0.3  # gyro white noise, rms, °/s
    gyro_bias_dps: float = 0.0  # residual bias magnitude per IMU (random direction), °/s
    #: A further gyro bias of this size on every axis (°/s, board axes), its sign drawn per
    #: IMU and axis from the seed: 0.2 gives each IMU a different (±0.2, ±0.2, ±0.2) °/s.
    gyro_bias_axis_dps: float = 0.0
    mounting_error_deg: float = 3.0  # rms per axis of the IMU mounting misalignment, °
    heel_strike_g: float = 2.5  # peak |accel| on the foot IMU at a heel strike, g
    heel_strike_frames: int = 3  # length of the impact transient, frames
    #: The accelerometer's configured range, ±g (ADXL345: 2, 4, 8 or 16). The firmware sets
    #: ±16 g (older firmware: ±2 g); counts beyond ±range × 256 saturate (at ±2 g a heel strike
    #: above 2 g is clipped).
    accel_range_g: float = 16.0

    def __post_init__(self) -> None:
        if self.accel_range_g not in ACCEL_RANGES_G:
            raise ValueError(f"accel_range_g must be one of {ACCEL_RANGES_G}, "
                             f"not {self.accel_range_g}")

    def accel_limits(self) -> tuple[int, int]:
        """The accelerometer's lowest and highest output, raw counts (full resolution)."""
        top = int(self.accel_range_g * ACCEL_COUNTS_PER_G_FULL_RES)
        return -top, top - 1


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
    return zyx(angles[:, 0], angles[:, 1], angles[:, 2])


def body_rates(R: np.ndarray, dt: float) -> np.ndarray:
    """``[N, 18, 3]`` rad/s: sample k's mean body rate over [t_{k-1}, t_k]; sample 0 reads 0."""
    out = np.zeros((*R.shape[:-2], 3))
    rel = np.swapaxes(R[:-1], -1, -2) @ R[1:]
    out[1:] = logm(rel) / dt
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
        target = model.heel_strike_g * G
        # |v + m ẑ| = target → m = -v_z + sqrt(v_z² - |v|² + target²)
        m = -v[2] + np.sqrt(max(v[2] ** 2 - v @ v + target**2, 0.0))
        lo, hi = max(k0, 0), min(k0 + n, len(t))  # the samples inside the recording
        spikes[lo:hi, imu, 2] -= m * shape[lo - k0:hi - k0]  # upward = -z in NED
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
    """Physical filter-frame values ``[N, 18, 3]``: accel in g (the gravity direction at
    rest), mag in units of the Earth's field × 100, gyro rad/s."""

    acc: np.ndarray
    mag: np.ndarray
    gyr: np.ndarray


def ideal_sensors(R: np.ndarray, acc_lin: np.ndarray, dip_deg: float,
                  mag_extra: np.ndarray | None, dt: float) -> SensorValues:
    """Noise-free filter-frame values from true DCMs ``R[N, 18, 3, 3]`` and world linear
    accelerations ``acc_lin[N, 18, 3]`` (m/s²)."""
    Rt = np.swapaxes(R, -1, -2)
    acc = np.einsum("nkij,nkj->nki", Rt, G_WORLD - acc_lin) / G
    dip = np.deg2rad(dip_deg)
    field = np.broadcast_to(100.0 * np.array([np.cos(dip), 0.0, np.sin(dip)]), acc.shape)
    if mag_extra is not None:
        field = field + mag_extra
    mag = np.einsum("nkij,nkj->nki", Rt, field)
    gyr = body_rates(R, dt)
    return SensorValues(acc, mag, gyr)


@dataclass
class Noise:
    """White noise (and the gyro bias) drawn for a recording, in the sensors' own units:
    accel raw counts, mag calibrated units, gyro rad/s; each ``[N, 18, 3]``."""

    acc_counts: np.ndarray
    mag: np.ndarray
    gyr: np.ndarray


def draw_noise(n: int, model: SensorModel, rng: np.random.Generator,
               bias_rng: np.random.Generator) -> Noise:
    """White noise on all three sensors, plus the per-IMU residual gyro bias."""
    bias_dir = bias_rng.normal(size=(N_IMUS, 3))
    bias_dir /= np.linalg.norm(bias_dir, axis=-1, keepdims=True)
    bias = np.deg2rad(model.gyro_bias_dps) * bias_dir
    if model.gyro_bias_axis_dps:  # drawn after the direction: other draws stay the same
        signs = np.where(bias_rng.random((N_IMUS, 3)) < 0.5, -1.0, 1.0)
        bias = bias + np.deg2rad(model.gyro_bias_axis_dps) * signs
    # One draw per sample, so a shorter recording is a prefix of a longer one (same seed).
    white = rng.standard_normal((n, N_IMUS, 3, 3))
    return Noise(acc_counts=model.acc_noise_counts * white[..., 0, :],
                 mag=model.mag_noise * white[..., 1, :],
                 gyr=bias + np.deg2rad(model.gyro_noise_dps) * white[..., 2, :])


def _board(v: np.ndarray) -> np.ndarray:
    """Filter-frame vectors ``[..., 18, 3]`` → board axes ``[..., 18, 3]``."""
    return np.einsum("kij,...kj->...ki", BOARD_AXES, np.asarray(v, dtype=np.float64))


def to_raw(values: SensorValues, table, model: SensorModel | None = None,
           noise: Noise | None = None, polarity: dict[str, tuple[float, float, float]]
           | None = None, mag_ellipsoids: dict | None = None) -> np.ndarray:
    """Raw counts ``int16 [N, 18, 9]`` (rounded, saturated) of physical filter-frame values.

    table: the suit's *true* calibration table (anything with ``values [18, 16]``): its
    min/max are the readings at ∓1 g / ∓ the full field, its averages the gyro's zero-rate counts.
    polarity: the chip's axis polarities (default :data:`POLARITY`).
    mag_ellipsoids: optional true soft-iron distortions per IMU, objects with ``center [3]``
    counts and ``matrix [3, 3]`` (board-axis calibrated units per count): that IMU's
    magnetometer then reads ``center + matrix⁻¹ (polarity × m_board)``.
    """
    model = model or SensorModel()
    pol = polarity or POLARITY
    v = np.asarray(table.values, dtype=np.float64)
    acc_lo, acc_hi = v[:, 1:7:2], v[:, 2:7:2]  # [18, 3] readings at -1 g and +1 g
    mag_lo, mag_hi = v[:, 7:13:2], v[:, 8:13:2]
    gyro_zero = v[:, 13:16]
    acc_b = _board(values.acc) * np.asarray(pol["accel"])  # g, board axes, chip polarity
    mag_b = _board(values.mag) * np.asarray(pol["mag"])
    gyr_b = _board(values.gyr) * np.asarray(pol["gyro"])
    raw_acc = (acc_lo + acc_hi) / 2 + acc_b * (acc_hi - acc_lo) / 2
    if noise is not None:
        mag_b = mag_b + noise.mag  # isotropic: no need to rotate the noise
        gyr_b = gyr_b + noise.gyr
        raw_acc = raw_acc + noise.acc_counts
    raw_mag = (mag_lo + mag_hi) / 2 + (mag_b / 100.0) * (mag_hi - mag_lo) / 2
    for imu, ell in (mag_ellipsoids or {}).items():
        raw_mag[..., imu, :] = np.asarray(ell.center) + np.linalg.solve(
            np.asarray(ell.matrix), mag_b[..., imu, :, None])[..., 0]
    raw_gyr = gyro_zero + np.rad2deg(gyr_b) * GYRO_COUNTS_PER_DPS
    lo, hi = model.accel_limits()
    raw_acc = np.clip(np.rint(raw_acc), lo, hi)
    raw = np.concatenate([raw_acc, np.rint(raw_mag), np.rint(raw_gyr)], axis=-1)
    return np.clip(raw, -32768, 32767).astype(np.int16)


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
