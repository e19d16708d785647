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


def local_peaks(mag: np.ndarray, threshold: float) -> np.ndarray:
    """Indices of local maxima above ``threshold``."""
    if len(mag) < 3:
        return np.zeros(0, dtype=int)
    mid = mag[1:-1]
    idx = np.flatnonzero((mid > threshold) & (mid >= mag[:-2]) & (mid > mag[2:])) + 1
    return idx


def keep_apart(kept: list[tuple], item: tuple, min_interval_s: float) -> None:
    """Append ``item`` (time s, peak, ...) to ``kept``, one foot's strikes in time order,
    unless it comes less than ``min_interval_s`` after the last one: then the larger peak of
    the two stays."""
    if kept and item[0] - kept[-1][0] < min_interval_s:
        if item[1] > kept[-1][1]:
            kept[-1] = item
    else:
        kept.append(item)


def heel_strikes(accel_g: dict[str, np.ndarray], t: np.ndarray, threshold_g: float,
                 min_interval_s: float) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Heel strikes from the feet's accelerometer magnitude ``{"right": [N], "left": [N]}``
    (g): candidates above the threshold, at least ``min_interval_s`` apart **on the same
    foot** (the larger peak wins; the feet are independent, so fast steps are kept), both
    feet merged in time order. Returns frame indices, sides and peak values (g). On a
    recording made at ±2 g the peaks clip at the threshold: use
    :func:`bpms.analysis.gait_events.gyro_heel_strikes` there."""
    cand: list[tuple[float, float, int, str]] = []
    for side, mag in accel_g.items():
        kept: list[tuple[float, float, int, str]] = []
        for k in local_peaks(np.nan_to_num(mag), threshold_g):
            keep_apart(kept, (t[k], float(mag[k]), int(k), side), min_interval_s)
        cand += kept
    cand.sort(key=lambda c: (c[2], c[3]))
    return (np.array([c[2] for c in cand], dtype=int), [c[3] for c in cand],
            np.array([c[1] for c in cand]))


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
    return _track(np.asarray(t)[idx], list(sides), np.asarray(peaks), joint_positions[idx],
                  include_hips, declination_deg)


class _Chunks:
    """Consecutive chunks of frames seen as one run: two frames of history (times, joint
    positions, each foot's signal) carry over, as a peak needs both its neighbours. Holds
    the path settings both accumulators share."""

    def __init__(self, min_interval_s: float, declination_deg: float,
                 include_hips: bool) -> None:
        self.min_interval_s = min_interval_s
        self.declination_deg = declination_deg
        self.include_hips = include_hips
        self._next = 0  # global index of the next frame
        self._tail_t = np.zeros(0)
        self._tail_pos = np.zeros((0, len(POINT_INDEX), 3))
        self._tail: dict[str, np.ndarray] = {}

    def _extend(self, t: np.ndarray, signals: dict[str, np.ndarray],
                joint_positions: np.ndarray) -> tuple[int, np.ndarray, dict[str, np.ndarray],
                                                      np.ndarray]:
        """The chunk with the history before it: (global index of its first row, times,
        each foot's signal with NaN as 0, joint positions); the history moves on."""
        base = self._next - len(self._tail_t)
        t_ext = np.concatenate([self._tail_t, t])
        pos_ext = np.concatenate([self._tail_pos, joint_positions])
        ext = {side: np.concatenate([self._tail.get(side, np.zeros(0)), np.nan_to_num(v)])
               for side, v in signals.items()}
        self._tail_t = t_ext[-2:].copy()
        self._tail_pos = pos_ext[-2:].copy()
        self._tail.update({side: v[-2:] for side, v in ext.items()})
        self._next += len(t)
        return base, t_ext, ext, pos_ext


class TrackAccumulator(_Chunks):
    """:func:`walked_path` computed chunk by chunk (constant memory, the same numbers):
    feed consecutive chunks with :meth:`add`, then :meth:`track`. Only the candidate heel
    strikes and two frames of history are kept between chunks."""

    def __init__(self, threshold_g: float = 2.0, min_interval_s: float = 0.4,
                 declination_deg: float = 0.0, include_hips: bool = False) -> None:
        super().__init__(min_interval_s, declination_deg, include_hips)
        self.threshold_g = threshold_g
        # kept strikes per side: (time s, peak g, frame, side, joint positions [21, 3])
        self._kept: dict[str, list[tuple[float, float, int, str, np.ndarray]]] = {}

    def add(self, t: np.ndarray, accel_g: dict[str, np.ndarray],
            joint_positions: np.ndarray) -> None:
        """The next chunk: ``t[N]`` s, feet accelerometer magnitudes ``{"right": [N],
        "left": [N]}`` g, ``joint_positions[N, 21, 3]`` m NED."""
        if len(t) == 0:
            return
        base, t_ext, mags, pos_ext = self._extend(t, accel_g, joint_positions)
        for side, m in mags.items():  # the minimum gap holds per foot, as in heel_strikes
            kept = self._kept.setdefault(side, [])
            for k in local_peaks(m, self.threshold_g):
                keep_apart(kept, (float(t_ext[k]), float(m[k]), int(base + k), side,
                                   pos_ext[k].copy()), self.min_interval_s)

    def track(self) -> Track:
        """The walked path so far."""
        kept = sorted((c for side in self._kept.values() for c in side),
                      key=lambda c: (c[2], c[3]))
        return _track(np.array([c[0] for c in kept]), [c[3] for c in kept],
                      np.array([c[1] for c in kept]), np.array([c[4] for c in kept]),
                      self.include_hips, self.declination_deg)


class GyroTrackAccumulator(_Chunks):
    """:func:`walked_path` with the gyroscope heel strikes of
    :func:`bpms.analysis.gait_events.gyro_heel_strikes`, chunk by chunk.

    Feed each chunk's shank lateral rates ``{"right": [N], "left": [N]}`` rad/s
    (:func:`bpms.analysis.gait_events.lateral_gyro_rate`) with :meth:`add`, then
    :meth:`track`. Streamed: two samples of history carry over between chunks; every mid-swing
    peak above ``min_swing_rate`` is kept with its heel strike (the first sample after it at
    which the rate reaches zero or a local minimum, the one nearer zero) and the joint
    positions there. The walk's typical swing peak (90th percentile) is known only at the end,
    so the peak filter and the per-foot gap run in :meth:`track`. Memory grows with the number
    of swings (a few numbers and 21 × 3 positions per stride), not with the frames."""

    def __init__(self, min_interval_s: float = 0.4, declination_deg: float = 0.0,
                 include_hips: bool = False, min_swing_rate: float = 0.5,
                 swing_fraction: float = 0.25) -> None:
        super().__init__(min_interval_s, declination_deg, include_hips)
        self.min_swing_rate = min_swing_rate
        self.swing_fraction = swing_fraction
        # per side: the peak whose strike is still to come (peak time s, peak rad/s, frame)
        self._pending: dict[str, tuple[float, float, int] | None] = {}
        # per side: (peak time s, peak rad/s, peak frame, strike time s, positions [21, 3])
        self._swings: dict[str, list[tuple[float, float, int, float, np.ndarray]]] = {}

    def add(self, t: np.ndarray, rates: dict[str, np.ndarray],
            joint_positions: np.ndarray) -> None:
        """The next chunk: ``t[N]`` s, shank lateral rates rad/s, ``joint_positions[N, 21, 3]``
        m NED."""
        if len(t) == 0:
            return
        base, t_ext, ext, pos_ext = self._extend(t, rates, joint_positions)
        for side, r in ext.items():
            self._scan(side, r, t_ext, pos_ext, base, 1, len(r) - 1)

    def _scan(self, side: str, r: np.ndarray, t: np.ndarray, pos: np.ndarray, base: int,
              lo: int, hi: int) -> None:
        """Peaks and stops at ext indices ``lo..hi-1`` (each needs its two neighbours)."""
        if hi <= lo:
            return
        j = np.arange(lo, hi)
        peak = (r[j] > self.min_swing_rate) & (r[j] >= r[j - 1]) & (r[j] > r[j + 1])
        stop = (r[j] <= 0.0) | ((r[j] <= r[j - 1]) & (r[j] < r[j + 1]))
        self._swings.setdefault(side, [])
        for k in j[peak | stop]:
            pending = self._pending.get(side)
            if r[k] > self.min_swing_rate and r[k] >= r[k - 1] and r[k] > r[k + 1]:
                if pending is not None:  # no minimum since the last peak: strike just before
                    self._strike(side, pending, k - 1, r, t, pos, base)
                self._pending[side] = (float(t[k]), float(r[k]), int(base + k))
            elif pending is not None and base + k > pending[2]:
                self._strike(side, pending, k, r, t, pos, base)

    def _strike(self, side: str, pending: tuple[float, float, int], k: int, r: np.ndarray,
                t: np.ndarray, pos: np.ndarray, base: int) -> None:
        if base + k > pending[2] + 1 and abs(r[k - 1]) < abs(r[k]):
            k -= 1  # the sample nearer the zero crossing
        self._swings[side].append((*pending, float(t[k]), pos[k].copy()))
        self._pending[side] = None

    def track(self) -> Track:
        """The walked path (peaks column: the mid-swing peak rate, rad/s)."""
        events = []
        for side, swings in self._swings.items():
            swings = list(swings)
            pending = self._pending.get(side)
            if pending is not None and len(self._tail_t):  # the recording ends mid-swing
                r = self._tail[side]
                k = len(r) - 1
                if self._next - 1 > pending[2] + 1 and len(r) > 1 and abs(r[-2]) < abs(r[-1]):
                    k -= 1
                swings.append((*pending, float(self._tail_t[k]), self._tail_pos[k].copy()))
            if not swings:
                continue
            typical = float(np.percentile([s[1] for s in swings], 90))
            kept: list[tuple[float, float, int, float, np.ndarray]] = []
            for s in swings:
                if s[1] >= self.swing_fraction * typical:
                    keep_apart(kept, s, self.min_interval_s)
            events += [(s[3], side, s[1], s[4]) for s in kept]
        events.sort(key=lambda e: (e[0], e[1]))
        return _track(np.array([e[0] for e in events]), [e[1] for e in events],
                      np.array([e[2] for e in events]), np.array([e[3] for e in events]),
                      self.include_hips, self.declination_deg)


def _track(times: np.ndarray, sides: list[str], peaks: np.ndarray, pos: np.ndarray,
           include_hips: bool, declination_deg: float) -> Track:
    """Steps (leading minus trailing leg, ``pos[K, 21, 3]`` at the strikes) and the path."""
    pos = pos.reshape(-1, len(POINT_INDEX), 3)  # no strike: np.array([]) of shape (0,)
    origin_r = "pelvis" if include_hips else "hip_r"
    origin_l = "pelvis" if include_hips else "hip_l"
    right = pos[:, POINT_INDEX["ankle_r"]] - pos[:, POINT_INDEX[origin_r]]
    left = pos[:, POINT_INDEX["ankle_l"]] - pos[:, POINT_INDEX[origin_l]]
    lead_right = np.array([s == "right" for s in sides], dtype=bool)[:, None]
    steps = np.where(lead_right, right - left, left - right).reshape(-1, 3)
    steps = np.nan_to_num(steps) @ rot_z(np.radians(declination_deg)).T
    return Track(times.reshape(-1), sides, peaks.reshape(-1), steps, np.cumsum(steps, axis=0))
