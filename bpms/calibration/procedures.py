"""The three calibration procedures (docs/units.md) as state machines fed with raw frames.

Each procedure takes raw readings ``feed(raw [18, 9] counts, errors [18, 3] bool | None)`` one
frame at a time (or :meth:`feed_many`), from whatever source: the suit link, the simulated
suit, a recording. Readings whose error bit is set are ignored for that IMU and sensor. They
never block, never print and never import Qt: the CLI and the GUI wizard drive them and show
their ``progress``, ``message`` and live values.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from bpms.calibration.ellipsoid import EllipsoidFit, fit_ellipsoid
from bpms.io.frames import N_IMUS

#: Channel slices of a raw ``[18, 9]`` reading.
ACC, MAG, GYR = slice(0, 3), slice(3, 6), slice(6, 9)
AXES = "xyz"
#: The order the guided procedure runs the sensors in (gyro first: the suit lies still).
SENSORS = ("gyro", "accel", "mag")


@dataclass
class StillnessCheck:
    """Is a sensor still? Per-axis standard deviation over the last ``window`` frames.

    limits in raw counts: gyro 20 counts ≈ 1.4 °/s (the ITG-3200's noise is ≈ 5 counts rms),
    accelerometer 8 counts ≈ 0.03 g (noise ≈ 1.5 counts rms).
    """

    window: int = 25
    gyro_std_counts: float = 20.0
    accel_std_counts: float = 8.0


def _std(block: np.ndarray) -> np.ndarray:
    """Per-IMU worst axis std of ``block [n, k, 3]`` (NaN = missing) → ``[k]``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns (failed sensor)
        s = np.nanstd(block, axis=0)
    return np.nan_to_num(s, nan=0.0).max(axis=-1)


def _masked(raw: np.ndarray, errors: np.ndarray | None, sensor: int) -> np.ndarray:
    """``[18, 3]`` float values of one sensor (0 accel, 1 mag, 2 gyro), NaN where failed."""
    values = np.asarray(raw, dtype=np.float64)[:, 3 * sensor:3 * sensor + 3].copy()
    if errors is not None:
        values[np.asarray(errors)[:, sensor]] = np.nan
    return values


class _FedByFrame:
    """What the procedures share: readings come one frame at a time (``feed``)."""

    def feed_many(self, raw: np.ndarray, errors: np.ndarray | None = None) -> None:
        """Frames ``raw [n, 18, 9]`` (``errors [n, 18, 3]`` or None) fed one by one."""
        for k in range(len(raw)):
            self.feed(raw[k], None if errors is None else errors[k])  # type: ignore[attr-defined]


# -- gyroscope ---------------------------------------------------------------------------
class GyroProcedure(_FedByFrame):
    """Keep the suit still; average ``samples`` readings per axis of each chosen IMU.

    The stillness check runs on every block of ``check.window`` frames (gyro and accel std);
    when the suit moved the capture is *rejected* (``state == "rejected"``, the reason in
    ``message``) and must be started again with :meth:`restart`.
    States: ``collecting`` → ``done`` | ``rejected``.
    """

    def __init__(self, imus: list[int], samples: int = 500,
                 check: StillnessCheck | None = None) -> None:
        if samples < 1:
            raise ValueError("gyro samples must be at least 1")
        self.imus = list(imus)
        self.samples = samples
        self.check = check or StillnessCheck()
        self.attempts = 0
        self.restart()

    def restart(self) -> None:
        """Start (again) from nothing."""
        self.state = "collecting"
        self.message = "keep the suit still"
        self._sum = np.zeros((N_IMUS, 3))
        self._n = np.zeros((N_IMUS, 3))
        self._block: list[tuple[np.ndarray, np.ndarray]] = []
        self.frames = 0
        self.motion = 0.0  # last block's worst gyro std, counts
        self.attempts += 1

    @property
    def progress(self) -> float:
        """Fraction of the samples averaged, 0..1."""
        return min(1.0, self.frames / self.samples)

    def feed(self, raw: np.ndarray, errors: np.ndarray | None = None) -> None:
        if self.state != "collecting":
            return
        self._block.append((_masked(raw, errors, 2), _masked(raw, errors, 0)))
        if len(self._block) < self.check.window and self.frames + len(self._block) < self.samples:
            return
        gyr = np.stack([b[0] for b in self._block])[:, self.imus]
        acc = np.stack([b[1] for b in self._block])[:, self.imus]
        self._block = []
        g_std, a_std = _std(gyr), _std(acc)
        self.motion = float(g_std.max(initial=0.0))
        worst = int(np.argmax(g_std / self.check.gyro_std_counts
                              + a_std / self.check.accel_std_counts))
        if (g_std > self.check.gyro_std_counts).any() or (a_std > self.check.accel_std_counts
                                                          ).any():
            self.state = "rejected"
            self.message = (f"the suit moved (IMU {self.imus[worst]}: gyro std "
                            f"{g_std[worst]:.0f} counts, accel std {a_std[worst]:.0f} counts) "
                            "— keep it still and start again")
            return
        ok = ~np.isnan(gyr)
        self._sum[self.imus] += np.where(ok, gyr, 0.0).sum(axis=0)
        self._n[self.imus] += ok.sum(axis=0)
        self.frames += len(gyr)
        if self.frames >= self.samples:
            if (self._n[self.imus] == 0).any():
                self.state = "rejected"
                self.message = "no valid gyro reading for some IMU (error bits) — check the suit"
                return
            self.state = "done"
            self.message = f"{self.frames} readings averaged"

    @property
    def averages(self) -> dict[int, np.ndarray]:
        """Per chosen IMU, the gyro averages ``[3]`` (counts); only when done."""
        if self.state != "done":
            return {}
        return {i: self._sum[i] / self._n[i] for i in self.imus}


# -- accelerometer -----------------------------------------------------------------------
#: Guided order of the 6 poses: lying flat (z up, then upside down), then on each side.
POSE_ORDER: tuple[tuple[int, int], ...] = ((2, 1), (2, -1), (0, 1), (0, -1), (1, 1), (1, -1))


def pose_name(axis: int, sign: int) -> str:
    return f"{'+' if sign > 0 else '-'}{AXES[axis]}"


@dataclass
class AccelCapture:
    """A captured pose: the 200-sample mean of all three accel axes (counts) and its spread."""

    imu: int
    axis: int
    sign: int
    mean: np.ndarray
    std: np.ndarray


@dataclass
class AccelProcedure(_FedByFrame):
    """For each chosen IMU, the 6 axis-extreme poses in :data:`POSE_ORDER`.

    For the current step the operator holds the IMU still with the axis at its extreme and
    confirms (:meth:`capture`); ``samples`` readings are then averaged. A capture restarts
    when the IMU moves (stillness check) and is refused when the axis is not the dominant one
    with the right sign (wrong pose). :meth:`skip` leaves a pose out (the old value is kept),
    :meth:`redo` goes back to any pose. ``live`` is the current raw accel of the IMU (counts).
    """

    imus: list[int]
    samples: int = 200
    check: StillnessCheck = field(default_factory=StillnessCheck)
    auto: bool = False  # capture by itself once the pose is held still

    def __post_init__(self) -> None:
        self.steps = [(imu, axis, sign) for imu in self.imus for axis, sign in POSE_ORDER]
        self.index = 0
        self.captures: dict[tuple[int, int, int], AccelCapture] = {}
        self.skipped: set[tuple[int, int, int]] = set()
        self.live = np.zeros(3)
        self.best = float("nan")  # the most extreme reading of the axis in this step, counts
        self._recent: list[np.ndarray] = []
        self._capturing = False
        self._buffer: list[np.ndarray] = []
        self.message = ""
        self.still = False

    @property
    def done(self) -> bool:
        return self.index >= len(self.steps)

    @property
    def current(self) -> tuple[int, int, int] | None:
        return None if self.done else self.steps[self.index]

    @property
    def capturing(self) -> bool:
        return self._capturing

    @property
    def progress(self) -> float:
        """Progress of the running capture, 0..1."""
        return len(self._buffer) / self.samples if self._capturing else 0.0

    @property
    def at_extreme(self) -> bool:
        """Is the current axis the dominant one, with the right sign?"""
        if self.done:
            return False
        _, axis, sign = self.steps[self.index]
        v = self.live
        return bool(sign * v[axis] > 0.9 * np.linalg.norm(v) and np.linalg.norm(v) > 0)

    def prompt(self) -> str:
        if self.done:
            return "all poses done"
        imu, axis, sign = self.steps[self.index]
        where, end = ("up", "max") if sign > 0 else ("down", "min")
        return (f"IMU {imu}: pose {pose_name(axis, sign)} — hold the IMU still with its "
                f"{AXES[axis]} axis pointing {where} (reading at its {end})")

    def capture(self) -> bool:
        """Confirm the pose: start averaging. False (with a message) when not at the extreme."""
        if self.done:
            return False
        if self._capturing:
            return True  # confirming twice does not restart the capture
        if not self.at_extreme:
            self.message = "not at the extreme: turn the IMU until the axis reads its extreme"
            return False
        self._capturing = True
        self._buffer = []
        self.message = "capturing — keep still"
        return True

    def skip(self) -> None:
        """Leave the current pose out (the existing value is kept)."""
        if not self.done:
            self.skipped.add(self.steps[self.index])
            self._advance()

    def redo(self, step: int | tuple[int, int, int]) -> None:
        """Go back to a step (by index or (imu, axis, sign)); its capture is dropped."""
        index = step if isinstance(step, int) else self.steps.index(step)
        self.index = index
        self.captures.pop(self.steps[index], None)
        self.skipped.discard(self.steps[index])
        self.best = float("nan")
        self._capturing = False
        self._buffer = []

    def _advance(self) -> None:
        self._capturing = False
        self._buffer = []
        self._recent = []
        self.best = float("nan")
        self.index += 1
        while not self.done and (self.steps[self.index] in self.captures):
            self.index += 1

    def feed(self, raw: np.ndarray, errors: np.ndarray | None = None) -> None:
        if self.done:
            return
        imu, axis, sign = self.steps[self.index]
        if errors is not None and np.asarray(errors)[imu, 0]:
            return
        value = np.asarray(raw[imu, ACC], dtype=np.float64)
        self.live = value
        if not np.isfinite(self.best) or sign * value[axis] > sign * self.best:
            self.best = float(value[axis])
        self._recent = [*self._recent[-(self.check.window - 1):], value]
        std = np.std(self._recent, axis=0).max() if len(self._recent) > 2 else 0.0
        self.still = bool(len(self._recent) >= self.check.window // 2
                          and std <= self.check.accel_std_counts)
        if not self._capturing:
            if self.auto and self.still and len(self._recent) >= self.check.window:
                self.capture()
            return
        if std > self.check.accel_std_counts and len(self._buffer) > 2:
            self._buffer = []
            self._recent = [value]
            self.message = "the IMU moved — capture restarted, keep still"
            return
        self._buffer.append(value)
        if len(self._buffer) >= self.samples:
            block = np.array(self._buffer)
            mean = block.mean(axis=0)
            if sign * mean[axis] <= 0.9 * np.linalg.norm(mean):
                self.message = "the pose changed during the capture — capture again"
                self._capturing = False
                self._buffer = []
                return
            self.captures[(imu, axis, sign)] = AccelCapture(imu, axis, sign, mean,
                                                            block.std(axis=0))
            self.message = (f"IMU {imu} {pose_name(axis, sign)}: {mean[axis]:.1f} counts "
                            f"(±{block.std(axis=0)[axis]:.1f})")
            self._advance()

    def extremes(self) -> dict[int, np.ndarray]:
        """Per IMU ``[3, 2]`` (min, max) per axis in counts, NaN where not captured."""
        out: dict[int, np.ndarray] = {}
        for (imu, axis, sign), cap in self.captures.items():
            ext = out.setdefault(imu, np.full((3, 2), np.nan))
            ext[axis, 0 if sign < 0 else 1] = cap.mean[axis]
        return out


# -- magnetometer ------------------------------------------------------------------------
SPHERE_BANDS, SPHERE_SECTORS = 8, 16  # 128 equal-area cells for the coverage indicator


@dataclass
class MagProcedure(_FedByFrame):
    """The timed magnetometer sweep of all chosen IMUs at once (2 minutes by default).

    Tracks min/max per axis (counts) and the fraction of the sphere seen per IMU (directions
    of ``raw - centre`` binned into 128 equal-area cells: 8 bands of equal height × 16 sectors;
    the centre is the running (min+max)/2). The duration counts frames at 50 frames/s, so a
    faster-than-real-time feed finishes sooner. Warnings: a range that reaches ``limit``
    counts (saturated) or whose half-range is below ``min_half_range`` counts (too small).
    When the sweep is over, also a sphere coverage below ``min_coverage`` (0..1).
    ``ellipsoid``: also fit an ellipsoid (hard and soft iron) per IMU at the end.
    """

    imus: list[int]
    duration_s: float = 120.0
    limit: int = 512
    min_half_range: float = 150.0
    min_coverage: float = 0.8
    ellipsoid: bool = False
    frame_rate_hz: float = 50.0

    def __post_init__(self) -> None:
        self.mins = np.full((N_IMUS, 3), np.inf)
        self.maxs = np.full((N_IMUS, 3), -np.inf)
        self._samples: list[np.ndarray] = []
        self.frames = 0
        self.state = "sweeping"
        self.fits: dict[int, EllipsoidFit | None] = {}

    @property
    def needed(self) -> int:
        return max(1, round(self.duration_s * self.frame_rate_hz))

    @property
    def progress(self) -> float:
        return min(1.0, self.frames / self.needed)

    @property
    def remaining_s(self) -> float:
        return max(0.0, (self.needed - self.frames) / self.frame_rate_hz)

    def feed(self, raw: np.ndarray, errors: np.ndarray | None = None) -> None:
        if self.state != "sweeping":
            return
        m = _masked(raw, errors, 1)
        self._samples.append(m[self.imus])
        self.mins = np.fmin(self.mins, m)
        self.maxs = np.fmax(self.maxs, m)
        self.frames += 1
        if self.frames >= self.needed:
            self.finish()

    def finish(self) -> None:
        """End the sweep now (also called when the time is up); runs the ellipsoid fits."""
        if self.state == "done":
            return
        self.state = "done"
        if self.ellipsoid:
            data = self.samples()
            for j, imu in enumerate(self.imus):
                pts = data[:, j]
                self.fits[imu] = fit_ellipsoid(pts[~np.isnan(pts).any(axis=1)])

    def samples(self) -> np.ndarray:
        """All readings so far ``[n, len(imus), 3]`` counts (NaN = failed)."""
        if not self._samples:
            return np.empty((0, len(self.imus), 3))
        return np.stack(self._samples)

    def coverage(self) -> dict[int, float]:
        """Per chosen IMU, the fraction (0..1) of the 128 sphere cells seen so far."""
        data = self.samples()
        out = {}
        bands, sectors = SPHERE_BANDS, SPHERE_SECTORS
        for j, imu in enumerate(self.imus):
            pts = data[:, j]
            pts = pts[~np.isnan(pts).any(axis=1)]
            if len(pts) == 0 or not np.isfinite(self.mins[imu]).all():
                out[imu] = 0.0
                continue
            centre = (self.mins[imu] + self.maxs[imu]) / 2
            half = np.maximum((self.maxs[imu] - self.mins[imu]) / 2, 1.0)
            u = (pts - centre) / half
            norm = np.linalg.norm(u, axis=1)
            u = u[norm > 1e-9] / norm[norm > 1e-9, None]
            band = np.clip(((u[:, 2] + 1) / 2 * bands).astype(int), 0, bands - 1)
            sector = ((np.arctan2(u[:, 1], u[:, 0]) + np.pi) / (2 * np.pi) * sectors
                      ).astype(int) % sectors
            out[imu] = len(np.unique(band * sectors + sector)) / (bands * sectors)
        return out

    def warnings(self) -> list[str]:
        """Saturated or too-small ranges, one line per IMU and axis; poor coverage at the end."""
        out = []
        if self.state == "done":
            for imu, cov in self.coverage().items():
                if cov < self.min_coverage:
                    out.append(f"IMU {imu}: only {100 * cov:.0f} % of the sphere seen (want "
                               f"{100 * self.min_coverage:.0f} %) — sweep longer, in every "
                               "orientation")
        for imu in self.imus:
            for a in range(3):
                lo, hi = self.mins[imu, a], self.maxs[imu, a]
                if not np.isfinite(lo):
                    continue
                if lo <= -self.limit or hi >= self.limit - 1:
                    out.append(f"IMU {imu} m{AXES[a]}: range {lo:.0f}..{hi:.0f} counts reaches "
                               f"±{self.limit} — saturated; move away from magnets/metal")
                elif (hi - lo) / 2 < self.min_half_range:
                    out.append(f"IMU {imu} m{AXES[a]}: half-range {(hi - lo) / 2:.0f} counts "
                               f"< {self.min_half_range:.0f} — too small; rotate through every "
                               "orientation")
        return out

    def extremes(self) -> dict[int, np.ndarray]:
        """Per chosen IMU with data, ``[3, 2]`` (min, max) counts."""
        return {i: np.stack([self.mins[i], self.maxs[i]], axis=1) for i in self.imus
                if np.isfinite(self.mins[i]).all() and (self.maxs[i] > self.mins[i]).all()}
