"""Drift check: how far each sensor's attitude moved between the start and end calibration
pauses of a trial (the subject stands in the same pose at both, so a perfect filter shows no
change).

1. **Still periods**: frames where every valid IMU (``still_fraction``) turns slower than
   ``rate_th`` (rad/s, gyro magnitude averaged over ``smooth_s``) and read within
   ``acc_th_g`` of 1 g, lasting ``min_still_s`` or longer.
2. **The start pause** is the first still period; **the end pause** the last one that starts
   in the final ``end_window`` fraction of the trial (or its last ``end_window_s`` seconds,
   whichever is longer) and matches the start pose: the gravity direction each IMU measures
   (its accelerometer, independent of any filter) within ``pose_th_deg`` of the start's, for
   at least ``pose_fraction`` of the IMUs.
3. **The change** of each IMU between the last frame of the start pause and the first frame
   of the end pause: ``ΔR = R_end R_startᵀ`` (earth frame), total angle, heading (about the
   vertical) ``2 atan|z/w|`` and inclination ``2 acos √(w² + z²)`` of its quaternion — the
   BROAD definitions (docs/filters.md), in degrees. The mounting cancels: the same change
   holds for the segment.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from bpms.filter.rotations import dcm_to_quaternion


@dataclass
class DriftSettings:
    rate_th: float = 0.15        # rad/s
    acc_th_g: float = 0.1        # g
    smooth_s: float = 0.3        # s
    min_still_s: float = 1.0     # s
    still_fraction: float = 1.0  # of the valid IMUs still for the body to be still
    pose_fraction: float = 0.8   # of the IMUs in the start pose for a matching end pause
    end_window: float = 0.25     # fraction of the trial
    end_window_s: float = 30.0   # s
    pose_th_deg: float = 15.0    # degrees between gravity directions


@dataclass
class DriftReport:
    """Pauses as (first, last) frame indices and times (s); per IMU ``[n]`` the attitude
    change in degrees (NaN for an IMU without a filter output at either frame); ``pose_deg``
    ``[n]`` the angle between the gravity directions at the two pauses; ``problem``: why no
    report could be made (empty when all is well)."""

    start_pause: tuple[int, int] | None = None
    end_pause: tuple[int, int] | None = None
    t_start: float = float("nan")  # time of the start-pause frame compared, s
    t_end: float = float("nan")    # time of the end-pause frame compared, s
    total_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    heading_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    inclination_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pose_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    problem: str = ""

    @property
    def ok(self) -> bool:
        return not self.problem


def _smooth(x: np.ndarray, n: int) -> np.ndarray:
    if n <= 1:
        return x
    kernel = np.ones(n) / n
    pad = np.pad(x, [(n // 2, n - 1 - n // 2)] + [(0, 0)] * (x.ndim - 1), mode="edge")
    return np.apply_along_axis(lambda v: np.convolve(v, kernel, mode="valid"), 0, pad)


def still_periods(acc: np.ndarray, gyr: np.ndarray, gravity: np.ndarray, dt: float,
                  valid: np.ndarray | None = None,
                  settings: DriftSettings | None = None) -> list[tuple[int, int]]:
    """Still periods ``[(first, last), ...]`` (frame indices, inclusive) of the whole body.
    acc ``[N, n, 3]`` in units of ``gravity[n]`` per g, gyr ``[N, n, 3]`` rad/s, valid
    ``[N, n]`` bool (False: a failed sensor, ignored). A frame with no valid sensor at all (a
    damaged slot of the recording) does not end a still period, nor make one."""
    s = settings or DriftSettings()
    w = _smooth(np.linalg.norm(gyr, axis=-1), max(1, round(s.smooth_s / dt)))
    a = np.abs(np.linalg.norm(acc, axis=-1) / gravity - 1.0)
    ok = np.ones(w.shape, bool) if valid is None else np.asarray(valid, bool)
    quiet = (w < s.rate_th) & (a < s.acc_th_g) & ok
    frac = quiet.sum(axis=1) / np.maximum(ok.sum(axis=1), 1)
    unknown = ~ok.any(axis=1)
    still = (frac >= s.still_fraction - 1e-9) | unknown
    edges = np.flatnonzero(np.diff(np.r_[0, still.astype(int), 0]))
    min_n = round(s.min_still_s / dt)
    return [(int(a0), int(b0) - 1) for a0, b0 in zip(edges[::2], edges[1::2], strict=True)
            if b0 - a0 >= min_n and not unknown[a0:b0].all()]


def _angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    u = u / np.linalg.norm(u, axis=-1, keepdims=True)
    v = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip((u * v).sum(axis=-1), -1.0, 1.0)))


def drift_report(t: np.ndarray, R: np.ndarray, acc: np.ndarray, gyr: np.ndarray,
                 gravity: np.ndarray, errors: np.ndarray | None = None,
                 settings: DriftSettings | None = None) -> DriftReport:
    """The drift report of one trial: t ``[N]`` s, R ``[N, n, 3, 3]`` the filter's DCMs
    (sensor → NED), acc/gyr ``[N, n, 3]`` calibrated (accel in ``gravity[n]`` units per g),
    errors ``[N, n, 3]`` failed-sensor flags. A report without pauses says why in
    ``problem``."""
    s = settings or DriftSettings()
    n_frames = len(t)
    dt = float(np.median(np.diff(t))) if n_frames > 1 else 0.02
    valid = None if errors is None else ~np.asarray(errors, bool).any(axis=-1)
    periods = still_periods(acc, gyr, gravity, dt, valid, s)
    if not periods:
        return DriftReport(problem="no still period of "
                           f"{s.min_still_s:g} s: the trial has no calibration pause")
    first = periods[0]
    g_start = np.mean(acc[first[0]:first[1] + 1], axis=0)
    window_start = min(n_frames * (1.0 - s.end_window), n_frames - s.end_window_s / dt)
    end = None
    pose = np.zeros(0)
    for p in reversed(periods[1:]):
        if p[0] < window_start:
            break
        g_end = np.mean(acc[p[0]:p[1] + 1], axis=0)
        pose = _angle(g_start, g_end)
        if np.mean(pose < s.pose_th_deg) >= s.pose_fraction:
            end = p
            break
    if end is None:
        return DriftReport(start_pause=first, t_start=float(t[first[1]]), problem=(
            "no still period near the end matching the start pose (stand in the "
            "calibration pose for a few seconds at the end of the trial)"))
    k0, k1 = first[1], end[0]
    dR = R[k1] @ np.swapaxes(R[k0], -1, -2)
    q = np.full((len(dR), 4), np.nan)
    finite = np.isfinite(dR).all(axis=(-1, -2))
    if finite.any():
        q[finite] = dcm_to_quaternion(dR[finite])
    w, z = np.abs(q[:, 0]), q[:, 3]
    with np.errstate(invalid="ignore", divide="ignore"):
        total = 2 * np.arccos(np.clip(w, 0, 1))
        heading = 2 * np.arctan(np.abs(z / w))
        incl = 2 * np.arccos(np.clip(np.sqrt(w**2 + z**2), 0, 1))
    return DriftReport(first, end, float(t[k0]), float(t[k1]), np.degrees(total),
                       np.degrees(heading), np.degrees(incl), pose)


class DriftInputError(ValueError):
    """A recording the drift check cannot use: a filtered file (no sensors), or no frames."""


def drift_of_recording(opened, chunks: Iterable | None = None,
                       settings: DriftSettings | None = None) -> DriftReport:
    """:func:`drift_report` of a raw recording opened by
    :func:`bpms.filter.door.open_for_processing`, filtered through its door: ``chunks`` are
    its chunks (default ``opened.chunks()``; pass them to add progress). Raises
    :class:`DriftInputError` for a filtered file (no sensors) or a recording without frames."""
    if not opened.has_raw:
        raise DriftInputError(f"{opened.path}: the drift check needs the sensors: give the raw "
                         "recording, not a filtered file")
    proc = opened.processor
    columns = []
    for chunk in opened.chunks() if chunks is None else chunks:
        acc, _, gyr = proc.calibrate(chunk.raw)
        columns.append((chunk.result.t, chunk.result.R, acc, gyr, chunk.errors))
    if not columns:
        raise DriftInputError(f"{opened.path}: the recording holds no frames")
    t, R, acc, gyr, errors = (np.concatenate(column) for column in zip(*columns, strict=True))
    return drift_report(t, R, acc, gyr, proc.sensor_calibration.gravity, errors, settings)


__all__ = ["DriftInputError", "DriftReport", "DriftSettings", "drift_of_recording", "drift_report",
           "still_periods"]
