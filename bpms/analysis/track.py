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
    return _track(np.asarray(t)[idx], list(sides), np.asarray(peaks), joint_positions[idx],
                  include_hips, declination_deg)


class TrackAccumulator:
    """:func:`walked_path` computed chunk by chunk (constant memory, the same numbers):
    feed consecutive chunks with :meth:`add`, then :meth:`track`. Only the candidate heel
    strikes and two frames of history are kept between chunks."""

    def __init__(self, threshold_g: float = 2.0, min_interval_s: float = 0.4,
                 declination_deg: float = 0.0, include_hips: bool = False) -> None:
        self.threshold_g = threshold_g
        self.min_interval_s = min_interval_s
        self.declination_deg = declination_deg
        self.include_hips = include_hips
        self._next = 0  # global index of the next frame
        self._tail_t = np.zeros(0)
        self._tail_mag: dict[str, np.ndarray] = {}
        self._tail_pos = np.zeros((0, len(POINT_INDEX), 3))
        # kept strikes: (frame, side, peak g, time s, joint positions [21, 3])
        self._kept: list[tuple[int, str, float, float, np.ndarray]] = []
        self._last_of: dict[str, int] = {}  # side → index in _kept of its latest strike

    def add(self, t: np.ndarray, accel_g: dict[str, np.ndarray],
            joint_positions: np.ndarray) -> None:
        """The next chunk: ``t[N]`` s, feet accelerometer magnitudes ``{"right": [N],
        "left": [N]}`` g, ``joint_positions[N, 21, 3]`` m NED."""
        n = len(t)
        if n == 0:
            return
        tail = len(self._tail_t)
        base = self._next - tail
        t_ext = np.concatenate([self._tail_t, t])
        pos_ext = np.concatenate([self._tail_pos, joint_positions])
        cand = []
        for side, mag in accel_g.items():
            m = np.concatenate([self._tail_mag.get(side, np.zeros(0)), np.nan_to_num(mag)])
            for k in _peaks(m, self.threshold_g):
                cand.append((int(base + k), side, float(m[k]), float(t_ext[k]),
                             pos_ext[k].copy()))
            self._tail_mag[side] = m[-2:]
        cand.sort(key=lambda c: (c[0], c[1], c[2]))
        kept = self._kept
        for c in cand:  # the minimum gap holds per foot, as in heel_strikes
            last = self._last_of.get(c[1])
            if last is not None and c[3] - kept[last][3] < self.min_interval_s:
                if c[2] > kept[last][2]:
                    kept[last] = c
                continue
            self._last_of[c[1]] = len(kept)
            kept.append(c)
        self._tail_t = t_ext[-2:].copy()
        self._tail_pos = pos_ext[-2:].copy()
        self._next += n

    def track(self) -> Track:
        """The walked path so far."""
        kept = sorted(self._kept, key=lambda c: (c[0], c[1]))
        pos = (np.array([c[4] for c in kept]) if kept
               else np.zeros((0, len(POINT_INDEX), 3)))
        return _track(np.array([c[3] for c in kept]), [c[1] for c in kept],
                      np.array([c[2] for c in kept]), pos, self.include_hips,
                      self.declination_deg)


class GyroTrackAccumulator:
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
        self.min_interval_s = min_interval_s
        self.declination_deg = declination_deg
        self.include_hips = include_hips
        self.min_swing_rate = min_swing_rate
        self.swing_fraction = swing_fraction
        self._next = 0
        self._tail_t = np.zeros(0)
        self._tail_pos = np.zeros((0, len(POINT_INDEX), 3))
        self._tail_r: dict[str, np.ndarray] = {}
        self._pending: dict[str, tuple[int, float, float] | None] = {}
        # per side: (peak frame, peak rad/s, peak time s, strike time s, positions [21, 3])
        self._swings: dict[str, list[tuple[int, float, float, float, np.ndarray]]] = {}

    def add(self, t: np.ndarray, rates: dict[str, np.ndarray],
            joint_positions: np.ndarray) -> None:
        """The next chunk: ``t[N]`` s, shank lateral rates rad/s, ``joint_positions[N, 21, 3]``
        m NED."""
        n = len(t)
        if n == 0:
            return
        tail = len(self._tail_t)
        base = self._next - tail
        t_ext = np.concatenate([self._tail_t, t])
        pos_ext = np.concatenate([self._tail_pos, joint_positions])
        for side, rate in rates.items():
            r = np.concatenate([self._tail_r.get(side, np.zeros(0)), np.nan_to_num(rate)])
            self._scan(side, r, t_ext, pos_ext, base, 1, len(r) - 1)
            self._tail_r[side] = r[-2:]
        self._tail_t = t_ext[-2:].copy()
        self._tail_pos = pos_ext[-2:].copy()
        self._next += n

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
                self._pending[side] = (int(base + k), float(r[k]), float(t[k]))
            elif pending is not None and base + k > pending[0]:
                self._strike(side, pending, k, r, t, pos, base)

    def _strike(self, side: str, pending: tuple[int, float, float], k: int, r: np.ndarray,
                t: np.ndarray, pos: np.ndarray, base: int) -> None:
        if base + k > pending[0] + 1 and abs(r[k - 1]) < abs(r[k]):
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
                r = self._tail_r[side]
                k = len(r) - 1
                if self._next - 1 > pending[0] + 1 and len(r) > 1 and abs(r[-2]) < abs(r[-1]):
                    k -= 1
                swings.append((*pending, float(self._tail_t[k]), self._tail_pos[k].copy()))
            if not swings:
                continue
            typical = float(np.percentile([s[1] for s in swings], 90))
            kept: list[tuple[int, float, float, float, np.ndarray]] = []
            for s in swings:
                if s[1] < self.swing_fraction * typical:
                    continue
                if kept and s[2] - kept[-1][2] < self.min_interval_s:
                    if s[1] > kept[-1][1]:
                        kept[-1] = s
                    continue
                kept.append(s)
            events += [(s[3], side, s[1], s[4]) for s in kept]
        events.sort(key=lambda e: (e[0], e[1]))
        return _track(np.array([e[0] for e in events]), [e[1] for e in events],
                      np.array([e[2] for e in events]),
                      np.array([e[3] for e in events]) if events
                      else np.zeros((0, len(POINT_INDEX), 3)),
                      self.include_hips, self.declination_deg)


def _track(times: np.ndarray, sides: list[str], peaks: np.ndarray, pos: np.ndarray,
           include_hips: bool, declination_deg: float) -> Track:
    """Steps (leading minus trailing leg, ``pos[K, 21, 3]`` at the strikes) and the path."""
    origin_r = "pelvis" if include_hips else "hip_r"
    origin_l = "pelvis" if include_hips else "hip_l"
    right = pos[:, POINT_INDEX["ankle_r"]] - pos[:, POINT_INDEX[origin_r]]
    left = pos[:, POINT_INDEX["ankle_l"]] - pos[:, POINT_INDEX[origin_l]]
    lead_right = np.array([s == "right" for s in sides], dtype=bool)[:, None]
    steps = np.where(lead_right, right - left, left - right).reshape(-1, 3)
    steps = np.nan_to_num(steps) @ rot_z(np.radians(declination_deg)).T
    return Track(times.reshape(-1), sides, peaks.reshape(-1), steps, np.cumsum(steps, axis=0))
