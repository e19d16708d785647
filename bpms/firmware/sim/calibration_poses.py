"""Raw frames for scripted sensor-calibration poses (the calibration tool's simulated suit).

The operator's moves, per IMU filter frame (docs/units.md), turned into raw counts through a
*true* calibration table (and optional true soft-iron ellipsoids) that may differ from the
factory one:

- :meth:`CalibrationSuit.accel_pose` — one IMU held still with a chosen raw board axis pointing
  up or down (the axis reads its extreme), the others lying still;
- :meth:`CalibrationSuit.still` / :meth:`CalibrationSuit.moving` — the gyro step, kept still or
  rotated;
- :meth:`CalibrationSuit.sweep` — every IMU rotated through every orientation (smooth random
  rotation, for the magnetometer min/max sweep).

:func:`changed_table` makes a deliberately changed truth (offsets and scales moved) for some
IMUs. :class:`ScriptedCalibrationSource` streams these frames as a pipeline frame source whose
scene the caller switches (what the operator is doing now), for ``bpms calibrate --sim`` and the
GUI wizard tests.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import numpy as np

from bpms.firmware.sim.geometry import expm, random_rotations
from bpms.firmware.sim.motion import DT
from bpms.firmware.sim.sensors import (
    BOARD_AXES,
    POLARITY,
    SensorModel,
    draw_noise,
    ideal_sensors,
    to_raw,
)
from bpms.firmware.sim.table import TrueTable, table_2_2
from bpms.io.events import FrameEvent, SourceStatus
from bpms.io.frames import N_IMUS, encode_frames

#: IMUs whose truth :func:`changed_table` moves by default.
CHANGED_IMUS = (2, 7, 11)


def changed_table(imus: tuple[int, ...] = CHANGED_IMUS, seed: int = 1,
                  base: TrueTable | None = None) -> TrueTable:
    """A true table with deliberately changed offsets and scales for ``imus``: accelerometer
    offsets moved by up to ±15 counts, ranges scaled by 0.93–1.07, magnetometer offsets moved
    by up to ±60 counts and ranges scaled by 0.85–1.15, gyro averages moved by up to ±40
    counts. Ranges are kept inside the magnetometer's ±512 so nothing saturates."""
    rng = np.random.default_rng(seed)
    table = (base or table_2_2()).copy()
    for imu in imus:
        v = table.values[imu]
        acc = v[1:7].reshape(3, 2)
        off, half = acc.mean(axis=1), (acc[:, 1] - acc[:, 0]) / 2
        off += rng.uniform(-15, 15, 3)
        half *= rng.uniform(0.93, 1.07, 3)
        v[1:7] = np.stack([off - half, off + half], axis=1).ravel()
        v[0] = half.mean()
        mag = v[7:13].reshape(3, 2)
        moff = rng.uniform(-60, 60, 3)
        mhalf = np.minimum(rng.uniform(0.85, 1.15, 3) * (mag[:, 1] - mag[:, 0]) / 2,
                           500 - np.abs(moff))
        v[7:13] = np.stack([moff - mhalf, moff + mhalf], axis=1).ravel()
        v[13:16] += rng.uniform(-40, 40, 3)
    table.source = f"simulated truth (changed IMUs {list(imus)})"
    return table


def _basis_with_row(u: np.ndarray, yaw: float) -> np.ndarray:
    """A DCM (filter frame → world NED) whose third row is the unit vector ``u`` (so the
    filter-frame gravity direction ``Rᵀ ẑ`` is ``u``), with a yaw about the vertical."""
    u = u / np.linalg.norm(u)
    helper = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    a = np.cross(helper, u)
    a /= np.linalg.norm(a)
    b = np.cross(u, a)
    R = np.stack([a, b, u])  # rows; right-handed: a × b = u
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ R


@dataclass
class CalibrationSuit:
    """The simulated suit during calibration: raw frames of the operator's poses.

    table: the *true* calibration table (default: the factory one); ellipsoids: optional true
    soft-iron magnetometer distortions per IMU (the truth is then the ellipsoid, not min/max).
    Noise and the magnetic dip come from ``model``; ``seed`` makes every call reproducible in
    sequence. ``mag_clip``: the magnetometer saturates at ±mag_clip counts (None: never).
    ``sensors``: the chips' true axis polarities, any object with ``accel_signs``, ``mag_signs``
    and ``gyro_signs`` (default: the specification's, :data:`.sensors.POLARITY`; the host's
    sign vectors must undo them). ``ellipsoids``: objects with ``center`` and ``matrix``.
    Raw counts come from the simulated suit's own forward model
    (:func:`bpms.firmware.sim.sensors.to_raw`), never from the product's calibration code.
    """

    table: TrueTable = field(default_factory=table_2_2)
    ellipsoids: dict = field(default_factory=dict)
    model: SensorModel = field(default_factory=SensorModel)
    sensors: object | None = None
    seed: int = 0
    mag_clip: int | None = None

    def __post_init__(self) -> None:
        self.polarity = (dict(POLARITY) if self.sensors is None else
                         {s: tuple(getattr(self.sensors, f"{s}_signs"))
                          for s in ("accel", "mag", "gyro")})
        self._rng = np.random.default_rng(self.seed)
        self._rest = np.stack([_basis_with_row(np.array([0.0, 0.0, 1.0]), 0.3 * k)
                               for k in range(N_IMUS)])  # lying flat, spread headings

    # -- building blocks -----------------------------------------------------------------
    def raw_for(self, R: np.ndarray) -> np.ndarray:
        """Raw counts ``int16 [N, 18, 9]`` for true filter-frame DCMs ``R [N, 18, 3, 3]``
        (no linear acceleration; the gyro reads the rotation between samples)."""
        n = len(R)
        ideal = ideal_sensors(R, np.zeros((n, N_IMUS, 3)), self.model.dip_deg, None, DT)
        bias_rng = np.random.default_rng(self.seed + 1)  # same bias every call
        noise = draw_noise(n, self.model, self._rng, bias_rng)
        raw = to_raw(ideal, self.table, self.model, noise, self.polarity,
                     self.ellipsoids or None)
        if self.mag_clip is not None:
            raw[..., 3:6] = np.clip(raw[..., 3:6], -self.mag_clip, self.mag_clip - 1)
        return raw

    def _hold(self, R0: np.ndarray, n: int, tremor_deg: float = 0.05) -> np.ndarray:
        """``[n, 18, 3, 3]``: the orientations ``R0 [18, 3, 3]`` held by hand (a slow tremor
        of ``tremor_deg`` amplitude at 0.3–1.5 Hz: well below the gyro's noise)."""
        t = np.arange(n)[:, None, None] * DT
        freq = self._rng.uniform(0.3, 1.5, (1, N_IMUS, 3))
        phase = self._rng.uniform(0, 2 * np.pi, (1, N_IMUS, 3))
        wobble = np.deg2rad(tremor_deg) * np.sin(2 * np.pi * freq * t + phase)
        return R0[None] @ expm(wobble)

    # -- the operator's moves ------------------------------------------------------------
    def pose_orientation(self, imu: int, axis: int, sign: int) -> np.ndarray:
        """True DCM of ``imu`` with raw board ``axis`` (0 x, 1 y, 2 z) reading its maximum
        (sign +1) or minimum (sign -1): that axis points along gravity's reading."""
        # The board axis reads +1 g (its maximum) when polarity × (its direction · down) = 1.
        polarity = float(self.polarity["accel"][axis])
        u = BOARD_AXES[imu, axis] * (sign * polarity)
        return _basis_with_row(u, 0.2 * imu)

    def accel_pose(self, imu: int, axis: int, sign: int, n: int) -> np.ndarray:
        """``n`` raw frames: ``imu`` held still in the (axis, sign) pose, the rest lying flat."""
        R0 = self._rest.copy()
        R0[imu] = self.pose_orientation(imu, axis, sign)
        return self.raw_for(self._hold(R0, n))

    def still(self, n: int) -> np.ndarray:
        """``n`` raw frames of the suit lying still."""
        return self.raw_for(self._hold(self._rest, n))

    def moving(self, n: int, rate_dps: float = 40.0) -> np.ndarray:
        """``n`` raw frames of the suit being turned (about a slowly varying axis)."""
        t = np.arange(n) * DT
        axis = np.stack([np.cos(0.7 * t), np.sin(0.7 * t), 0.5 * np.ones(n)], -1)
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        angle = np.deg2rad(rate_dps) * t
        R = self._rest[None] @ expm((axis * angle[:, None])[:, None, :])
        return self.raw_for(R)

    def sweep(self, n: int, rate_dps: float = 120.0) -> np.ndarray:
        """``n`` raw frames of every IMU rotated smoothly through random orientations (a
        random walk of the body rate, mean speed ≈ ``rate_dps``)."""
        start = random_rotations(self._rng, N_IMUS)
        rate = np.zeros((N_IMUS, 3))
        out = np.empty((n, N_IMUS, 3, 3))
        R = start
        speed = np.deg2rad(rate_dps)
        for k in range(n):
            rate = 0.97 * rate + 0.25 * speed * self._rng.normal(0, 1, (N_IMUS, 3))
            R = R @ expm(rate * DT)
            out[k] = R
        return self.raw_for(out)


SCENES = ("still", "moving", "accel", "sweep")


class ScriptedCalibrationSource:
    """A :class:`bpms.io.events.FrameSource` streaming a :class:`CalibrationSuit` that does
    what the caller says (:meth:`set_scene`): ``still``, ``moving``, ``accel`` (imu, axis,
    sign) or ``sweep``. ``speed``: 1.0 paces frames at 50/s, 0 delivers ``burst`` frames per
    :meth:`read` as fast as asked (tests and fast simulations)."""

    def __init__(self, suit: CalibrationSuit | None = None, speed: float = 1.0,
                 burst: int = 50) -> None:
        self.suit = suit or CalibrationSuit()
        self.speed = speed
        self.burst = burst
        self._lock = threading.Lock()
        self._scene: tuple = ("still",)
        self._buffer = np.empty((0, N_IMUS, 9), np.int16)
        self._count = 0
        self._t0 = time.monotonic()
        self._closed = False

    def set_scene(self, scene: str, imu: int = 0, axis: int = 0, sign: int = 1) -> None:
        """What the operator does from the next frame on."""
        if scene not in SCENES:
            raise ValueError(f"unknown scene {scene!r}; one of {SCENES}")
        with self._lock:
            self._scene = (scene, imu, axis, sign) if scene == "accel" else (scene,)
            self._buffer = self._buffer[:0]

    def _generate(self, n: int) -> np.ndarray:
        scene = self._scene
        if scene[0] == "accel":
            return self.suit.accel_pose(scene[1], scene[2], scene[3], n)
        return {"still": self.suit.still, "moving": self.suit.moving,
                "sweep": self.suit.sweep}[scene[0]](n)

    def next_raw(self, n: int) -> np.ndarray:
        """The next ``n`` raw frames ``[n, 18, 9]`` of the current scene (unpaced)."""
        with self._lock:
            while len(self._buffer) < n:
                self._buffer = np.concatenate([self._buffer, self._generate(max(n, 100))])
            out, self._buffer = self._buffer[:n], self._buffer[n:]
            self._count += n
            return out

    def read(self, timeout: float = 0.1) -> list[FrameEvent]:
        if self._closed:
            return []
        if self.speed > 0:
            due = int((time.monotonic() - self._t0) * 50.0 * self.speed) - self._count
            if due <= 0:
                time.sleep(min(timeout, 0.02 / self.speed))
                due = int((time.monotonic() - self._t0) * 50.0 * self.speed) - self._count
            n = max(0, min(due, 500))
        else:
            n = self.burst
        if n == 0:
            return []
        start = self._count
        raw = self.next_raw(n)
        data = encode_frames(raw)
        now = time.time()
        return [FrameEvent(now, data[k * 340:(k + 1) * 340], start + k, k == 0 and start == 0)
                for k in range(n)]

    def status(self) -> SourceStatus:
        return SourceStatus(description="simulated suit (calibration poses)",
                            state="closed" if self._closed else "streaming",
                            counters={"frames": self._count})

    def close(self) -> None:
        self._closed = True
