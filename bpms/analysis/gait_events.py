"""Gait events from the legs' angular velocity, and the accelerometer range of a recording.

Why a gyroscope detector: the suit's original firmware sets the ADXL345 to ±2 g, and the
heel-strike threshold of the accelerometer detector is 2 g, so on such recordings the impact
peaks are clipped at the threshold and most strikes are lost. The gyroscope (±2000 °/s) never
saturates in walking.

Method (the shank-gyroscope detectors of the gait literature, e.g. Aminian et al. 2002,
Salarian et al. 2004): the shank's angular velocity about its lateral axis (sagittal plane,
positive when the foot swings forward) has one large positive peak per stride, at mid-swing.
The heel strike ends the swing: the first sample after the mid-swing peak where the rate
falls to zero or reaches a local minimum. Mid-swing peaks count when they exceed
``min_swing_rate`` (rad/s) and ``swing_fraction`` of the walk's typical swing peak (the 90th
percentile of that leg's positive peaks), and are at least ``min_gap_s`` apart **on the same
foot** — the two feet are independent, so fast walking (0.35 s between steps) keeps every
strike.

The lateral-axis rate is taken from consecutive segment orientations (``Result.C`` after Reset
Zero, the filter's ``R`` where C is not yet defined): ``ω = log(C_{k−1}ᵀ C_k) / dt`` in segment
axes (x forward, y right, z down), its y component. Inputs: orientations ``[N, 18, 3, 3]``
segment → NED, times ``[N]`` s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from bpms.analysis.track import keep_apart, local_peaks
from bpms.filter.rotations import rotation_vector

#: Shank IMUs of the suit (numbering of docs/suit.md, 0-based).
SHANK_IMUS = {"right": 2, "left": 14}
#: The ADXL345 range of recordings that do not say (the original firmware's ±2 g).
LEGACY_ACCEL_RANGE_G = 2.0


@dataclass
class GaitEvents:
    """Heel strikes of both feet, in time order: frame indices ``[K]``, times ``[K]`` s,
    sides ``[K]`` "right"/"left", and the mid-swing peak rate before each ``[K]`` rad/s."""

    index: np.ndarray
    times: np.ndarray
    sides: list[str]
    swing_peak: np.ndarray

    def __len__(self) -> int:
        return len(self.index)


def lateral_rate(C: np.ndarray, dt: float) -> np.ndarray:
    """``[N]`` angular velocity (rad/s) about the segment's own y (right) axis from the
    orientations ``C[N, 3, 3]`` (segment → world); 0 at the first sample, NaN where C is."""
    rel = np.einsum("nji,njk->nik", C[:-1], C[1:])  # C_{k-1}ᵀ C_k, segment axes
    out = np.zeros(len(C))
    out[1:] = rotation_vector(rel)[:, 1] / dt
    return out


def lateral_gyro_rate(C: np.ndarray, R: np.ndarray, gyro: np.ndarray) -> np.ndarray:
    """``[N]`` rad/s: one IMU's calibrated gyro ``gyro[N, 3]`` (filter frame) turned into its
    segment's axes, ``(Cᵀ R ω)_y`` — the rate about the segment's right axis. C ``[N, 3, 3]``
    segment → NED (NaN before Reset Zero: R stands in), R ``[N, 3, 3]`` filter frame → NED."""
    C = np.where(np.isfinite(C).all(axis=(-1, -2))[:, None, None], C, R)
    M = np.einsum("nji,njk->nik", C, R)
    return np.einsum("nk,nk->n", M[:, 1], gyro)


def _swing_strikes(rate: np.ndarray, t: np.ndarray, min_swing_rate: float,
                   swing_fraction: float, min_gap_s: float) -> tuple[list[int], list[float]]:
    r = np.nan_to_num(rate)
    peaks = local_peaks(r, min_swing_rate)
    if len(peaks) == 0:
        return [], []
    typical = float(np.percentile(r[peaks], 90))
    # minimum gap per foot: of two peaks closer than the gap, the larger stays
    apart: list[tuple[float, float, int]] = []
    for k in peaks[r[peaks] >= swing_fraction * typical]:
        keep_apart(apart, (t[k], r[k], int(k)), min_gap_s)
    kept = [k for _, _, k in apart]
    strikes, swing = [], []
    for n, k in enumerate(kept):
        end = kept[n + 1] if n + 1 < len(kept) else len(r)
        j = k + 1
        while j < end - 1 and r[j] > 0.0 and not (r[j] <= r[j - 1] and r[j] < r[j + 1]):
            j += 1
        if j < end:
            if j > k + 1 and abs(r[j - 1]) < abs(r[j]):
                j -= 1  # the sample nearer the zero crossing
            strikes.append(j)
            swing.append(float(r[k]))
    return strikes, swing


def gyro_heel_strikes(t: np.ndarray, C: np.ndarray, R: np.ndarray | None = None,
                      gyro: np.ndarray | None = None,
                      imus: dict[str, int] | None = None, min_swing_rate: float = 0.5,
                      swing_fraction: float = 0.25, min_gap_s: float = 0.4,
                      window: np.ndarray | None = None) -> GaitEvents:
    """Heel strikes from the shanks' lateral angular velocity (module docstring).

    t ``[N]`` s; C ``[N, 18, 3, 3]`` segment orientations (NaN before Reset Zero), R the
    filter's DCMs ``[N, 18, 3, 3]`` used where C is NaN; gyro ``[N, 18, 3]`` rad/s the
    calibrated gyroscope (filter frame): when given (with R), the rate is the gyro itself
    turned into segment axes, ``(Cᵀ R ω)_y`` — independent of how well the filter tracks
    the swing; otherwise it comes from consecutive orientations; imus: side → IMU (default the
    shanks); min_swing_rate rad/s; swing_fraction of the typical swing peak; min_gap_s per
    foot; window ``[N]`` bool: only events inside it."""
    imus = imus or SHANK_IMUS
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.02
    events: list[tuple[int, str, float]] = []
    for side, imu in imus.items():
        Ci = C[:, imu]
        if gyro is not None and R is not None:
            # segment axes: C_kᵀ R_k maps the IMU's filter frame into the segment's
            rate = lateral_gyro_rate(Ci, R[:, imu], gyro[:, imu])
        else:
            if R is not None:
                Ci = np.where(np.isfinite(Ci).all(axis=(-1, -2))[:, None, None], Ci, R[:, imu])
            rate = lateral_rate(Ci, dt)
        if window is not None:
            rate = np.where(window, rate, 0.0)
        idx, peak = _swing_strikes(rate, t, min_swing_rate, swing_fraction, min_gap_s)
        events += [(k, side, p) for k, p in zip(idx, peak, strict=True)]
    events.sort()
    index = np.array([e[0] for e in events], dtype=int)
    return GaitEvents(index, t[index] if len(index) else np.zeros(0), [e[1] for e in events],
                      np.array([e[2] for e in events]))


def accel_range_g(header: dict[str, Any] | None, options: Any = None) -> float:
    """The accelerometer range (± g) a recording was made with: its header's stored options
    (``sensors.accel_range_g``, or a top-level ``accel_range_g``), else the given options'
    ``sensors.accel_range_g`` for a live stream, else ±2 g (recordings from before the range
    was recorded come from the original ±2 g firmware)."""
    if header:
        stored = header.get("options")
        if isinstance(stored, dict):
            value = (stored.get("sensors") or {}).get("accel_range_g")
            if isinstance(value, int | float):
                return float(value)
        if isinstance(header.get("accel_range_g"), int | float):
            return float(header["accel_range_g"])
        return LEGACY_ACCEL_RANGE_G
    if options is not None:
        return float(options.sensors.accel_range_g)
    return LEGACY_ACCEL_RANGE_G


def accel_detector_usable(range_g: float, threshold_g: float, margin: float = 1.25) -> bool:
    """Whether accelerometer heel-strike peaks above ``threshold_g`` are measurable at
    ±``range_g``: the range must exceed the threshold by ``margin`` (impacts overshoot it)."""
    return range_g >= threshold_g * margin


__all__ = ["LEGACY_ACCEL_RANGE_G", "SHANK_IMUS", "GaitEvents", "accel_detector_usable",
           "accel_range_g", "gyro_heel_strikes", "lateral_gyro_rate", "lateral_rate"]
