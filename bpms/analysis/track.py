"""Dead-reckoning walked path (docs/body-model.md, dissertation chapter 3.4).

Heel strikes are peaks of the foot accelerometer magnitude (g) above
``options.track.heel_strike_g``, at least ``min_step_interval_s`` apart on each foot, or come
from the gyroscope detector of :mod:`bpms.analysis.gait_events` (recordings at ±2 g). At each
strike the vector between the feet (trailing ankle → leading ankle, from the lower-body chain
thigh + shank of ``Result.joint_positions``, each leg measured from its own hip joint so that
the pelvis width does not zig-zag the path) is added to the running position, after a
rotation by the magnetic declination (east positive) about the vertical, so that x points to
true north.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bpms.filter.body_model import POINT_INDEX
from bpms.filter.rotations import rot_z

FOOT_IMUS = {"right": 1, "left": 13}


@dataclass
class Track:
    """Heel strikes and the path, metres, world axes x north (true), y east, z down.

    times ``[K]`` s; sides ``[K]`` "right"/"left"; peaks ``[K]`` g; steps ``[K, 3]`` the
    per-step vectors; positions ``[K, 3]`` the running position after each step (starting at
    the origin before the first step).
    """

    times: np.ndarray
    sides: list[str]
    peaks: np.ndarray
    steps: np.ndarray
    positions: np.ndarray

    @property
    def length_m(self) -> float:
        """Horizontal path length, m."""
        return float(np.linalg.norm(self.steps[:, :2], axis=1).sum())


def _peaks(mag: np.ndarray, threshold: float) -> np.ndarray:
    """Indices of local maxima above ``threshold``."""
    if len(mag) < 3:
        return np.zeros(0, dtype=int)
    mid = mag[1:-1]
    idx = np.flatnonzero((mid > threshold) & (mid >= mag[:-2]) & (mid > mag[2:])) + 1
    return idx


def heel_strikes(accel_g: dict[str, np.ndarray], t: np.ndarray, threshold_g: float,
                 min_interval_s: float) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Heel strikes from the feet's accelerometer magnitude ``{"right": [N], "left": [N]}``
    (g): candidates above the threshold, at least ``min_interval_s`` apart **on the same
    foot** (the larger peak wins; the feet are independent, so fast steps are kept), both
    feet merged in time order. Returns frame indices, sides and peak values (g). On a
    recording made at ±2 g the peaks clip at the threshold: use
    :func:`bpms.analysis.gait_events.gyro_heel_strikes` there."""
    cand: list[tuple[int, str, float]] = []
    for side, mag in accel_g.items():
        kept: list[tuple[int, str, float]] = []
        for k in _peaks(np.nan_to_num(mag), threshold_g):
            c = (int(k), side, float(mag[k]))
            if kept and t[c[0]] - t[kept[-1][0]] < min_interval_s:
                if c[2] > kept[-1][2]:
                    kept[-1] = c
                continue
            kept.append(c)
        cand += kept
    cand.sort()
    return (np.array([k for k, _, _ in cand], dtype=int), [s for _, s, _ in cand],
            np.array([p for _, _, p in cand]))


def walked_path(t: np.ndarray, accel_g: dict[str, np.ndarray], joint_positions: np.ndarray,
                threshold_g: float = 2.0, min_interval_s: float = 0.4,
                declination_deg: float = 0.0, include_hips: bool = False,
                strikes: tuple[np.ndarray, list[str], np.ndarray] | None = None) -> Track:
    """The walked path: heel strikes, per-step vectors (leading minus trailing leg, hip joint
    to ankle, ``joint_positions[N, 21, 3]`` m NED), rotated by the declination, summed.

    include_hips: measure each foot from the pelvis centre as eq. 3.13–3.14 of the
    dissertation do (hip + thigh + shank); the path then zig-zags by 2 × hip per step.
    strikes: heel strikes found otherwise (indices, sides, peak values — e.g. from
    :func:`bpms.analysis.gait_events.gyro_heel_strikes`); ``accel_g`` is then unused."""
    idx, sides, peaks = (heel_strikes(accel_g, t, threshold_g, min_interval_s)
                         if strikes is None else strikes)
    pos = joint_positions[idx]
    origin_r = "pelvis" if include_hips else "hip_r"
    origin_l = "pelvis" if include_hips else "hip_l"
    right = pos[:, POINT_INDEX["ankle_r"]] - pos[:, POINT_INDEX[origin_r]]
    left = pos[:, POINT_INDEX["ankle_l"]] - pos[:, POINT_INDEX[origin_l]]
    lead_right = np.array([s == "right" for s in sides])[:, None]
    steps = np.where(lead_right, right - left, left - right).reshape(-1, 3)
    steps = np.nan_to_num(steps) @ rot_z(np.radians(declination_deg)).T
    return Track(t[idx], sides, peaks, steps, np.cumsum(steps, axis=0))
