"""Hinge-joint heading constraint for the knees and elbows (numba).

A hinge turns about one axis fixed in both of its segments (the lateral axis: the flexion of a
knee or an elbow). Estimated well, the two sensors put that axis in the same world direction;
a heading error of one of them (a magnet beside the forearm) turns its copy of the axis about
the vertical. The constraint measures that turn and takes it out again, as the
magnetometer-free joint-angle methods do (D. Laidig, T. Seel et al., "Exploiting kinematic
constraints to compensate magnetic disturbances when calculating joint angles of approximate
hinge joints from orientation estimates of inertial sensors", ICORR 2017). Per hinge
(proximal p, distal d), every frame:

1. **The axis in each sensor's axes**, ``j_p`` and ``j_d``: first the lateral axis of Reset
   Zero's segment frame (``Rᵀ C e_y``); then learnt from the joint's own motion, as the axis
   identification methods do (T. Seel et al. 2012): the rate of the distal segment relative to
   the proximal one always points along the hinge, so ``j`` is the main direction of
   ``r = Q ω_d − ω_p`` (proximal axes, ``Q = R_pᵀ R_d``) and of ``Qᵀ r`` (distal axes) —
   the leading eigenvector of ``prior·j₀j₀ᵀ + Σ r rᵀ dt``, one power step per frame, taught
   only while neither segment is suspect and the joint turns faster than ``min_rate``. Reset
   Zero's axis carries each sensor's heading error at the capture as a turn about the long
   axis, which a flexed joint reads as heading; the learnt axis does not.
2. **The relative heading** ``δ = ∠(h_d → h_p)`` about the vertical between the horizontal
   parts of ``R_p j_p`` and ``R_d j_d``, weight ``w = |h_p| |h_d|`` (a vertical axis says
   nothing about heading), averaged: ``δ̂ ← δ̂ + w k (δ − δ̂)``, ``k = 1 − exp(−dt/τ)``
   (``tau_s``, 1 s).
3. **Who is wrong.** Each segment has a heading uncertainty ``σ``: while its magnetometer
   is flagged (:mod:`bpms.filter.disturbance`) it grows by ``(drift + follow_rate·|Δψ|)·dt``
   up to ``|Δψ|``, the field's heading deviation (``mag_heading_deg``): a filter whose
   heading follows the field with gain ``follow_rate`` (1/s) turns towards it, one that
   coasts on its gyro only drifts (``drift_dps``); after the flag it fades as
   ``exp(−t/recover_s)`` (5 s: the filters' heading needs about
   that long to come back). While both ``σ`` are under ``clean_deg``, ``δ̂`` is the hinge's
   clean value ``δ̂₀`` and nothing is turned. Otherwise the change ``e = δ̂ − δ̂₀`` is shared:
   the distal segment turns by ``e σ_d² / (σ_p² + σ_d² + floor²)``, the proximal one by
   ``−e σ_p² / (…)`` (``floor_deg``, 2°: the constraint's own error). With every segment
   uncertain alike (no field at all, the 6D mode) each hinge splits its offset in halves.

The correction is a turn about the world vertical, applied to the sensor's attitude and the
segment orientation alike (``R' = Rz(ψ) R``, ``C' = Rz(ψ) C``): inclination is untouched and
the attitude filters' own states are not changed (a stage after the filter bank). The suit's
four hinges share no segment.

Limitations: until a joint has moved, its axes are Reset Zero's (on the simulated suit a few
degrees off, which caps what the constraint removes in a disturbance during the joint's first
flexions); a real knee also rotates a little about its long axis, and a forearm sensor near
the wrist turns with pronation, both read as heading offset. The simulated suit's knees and
elbows are exact hinges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np

from bpms.filter.joints import HINGE_JOINTS
from bpms.io.frames import N_IMUS

#: (proximal, distal) IMU ids of the hinges: right and left elbow, right and left knee.
HINGES = np.array([(j.proximal, j.distal) for j in HINGE_JOINTS], dtype=np.int64)
_FLOAT64 = np.dtype(np.float64)


@dataclass
class HingeSettings:
    """Settings of the constraint (physical units).

    tau_s: s, averaging of the relative heading. The heading uncertainty σ of a segment grows
    while its magnetometer is flagged, by ``drift_dps`` (°/s, the gyro's residual drift) plus
    ``follow_rate`` (1/s) × the field's heading deviation, up to that deviation: the filter's
    heading gain towards a disturbed field (the original Mahony's ``kp_yaw``; for the observer
    and the adaptive observer their ``k_head`` times the trust they keep in a flagged field);
    after the flag, σ fades with ``recover_s``. floor_deg: the constraint's own error (Reset
    Zero's axes before the joint has moved are a few degrees off): what it measures is shared
    as ``σ_d² / (σ_p² + σ_d² + floor²)``. clean_deg: both segments below this σ: the hinge's
    present offset is its clean value. prior: rad², the weight of Reset Zero's axis against
    the joint's own motion (≈ 1 s of flexing at 1.4 rad/s); min_rate: rad/s, slower joint
    motion does not teach the axis."""

    tau_s: float = 1.0
    recover_s: float = 5.0
    follow_rate: float = 1.2
    drift_dps: float = 0.05
    floor_deg: float = 2.0
    clean_deg: float = 0.5
    prior: float = 2.0
    min_rate: float = 0.3

    def params(self, dt: float) -> np.ndarray:
        return np.array([self.tau_s, self.recover_s, dt, self.prior, self.min_rate,
                         self.follow_rate, math.radians(self.drift_dps),
                         math.radians(self.floor_deg), math.radians(self.clean_deg)])


#: Per-hinge state columns: the axis in the proximal and distal sensor frames, their
#: scatter matrices (row-major), the relative-heading estimate, initialised.
(H_JP, H_JD, H_MP, H_MD, H_OFFSET, H_BASE, H_INIT) = (0, 3, 6, 15, 24, 25, 26)
N_HINGE_STATE = 27


@dataclass
class HingeState:
    """hinges ``[h, N_HINGE_STATE]`` (the axis in each sensor frame, what teaches it, the
    relative heading δ̂ and its clean value δ̂₀, rad); sigma ``[18]`` rad, each segment's
    heading uncertainty."""

    n_hinges: int = len(HINGES)
    hinges: np.ndarray = field(init=False)
    sigma: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.hinges = np.zeros((self.n_hinges, N_HINGE_STATE))
        self.sigma = np.zeros(N_IMUS)

    def reset(self) -> None:
        self.hinges[:] = 0.0
        self.sigma[:] = 0.0


@numba.njit(cache=True)
def _mat_vec(s, col, v0, v1, v2):
    return (s[col] * v0 + s[col + 1] * v1 + s[col + 2] * v2,
            s[col + 3] * v0 + s[col + 4] * v1 + s[col + 5] * v2,
            s[col + 6] * v0 + s[col + 7] * v1 + s[col + 8] * v2)


@numba.njit(cache=True)
def _teach(s, col, jcol, v0, v1, v2, dt):
    """Add ``v vᵀ dt`` to the scatter at ``col`` and take one power step for the axis."""
    v = (v0, v1, v2)
    for a in range(3):
        for b in range(3):
            s[col + 3 * a + b] += v[a] * v[b] * dt
    x0, x1, x2 = _mat_vec(s, col, s[jcol], s[jcol + 1], s[jcol + 2])
    n = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    if n > 0.0:
        s[jcol], s[jcol + 1], s[jcol + 2] = x0 / n, x1 / n, x2 / n


@numba.njit(cache=True)
def _world_xy(R, t, i, s, col):
    """North and east of ``R[t, i] @ s[col:col + 3]``."""
    return (R[t, i, 0, 0] * s[col] + R[t, i, 0, 1] * s[col + 1] + R[t, i, 0, 2] * s[col + 2],
            R[t, i, 1, 0] * s[col] + R[t, i, 1, 1] * s[col + 1] + R[t, i, 1, 2] * s[col + 2])


@numba.njit(cache=True)
def _turn_about_vertical(M, t, i, angle):
    """``M[t, i] ← Rz(angle) · M[t, i]`` (NED z: the first two rows mix)."""
    c, s = math.cos(angle), math.sin(angle)
    for b in range(3):
        x, y = M[t, i, 0, b], M[t, i, 1, b]
        M[t, i, 0, b] = c * x - s * y
        M[t, i, 1, b] = s * x + c * y


@numba.njit(cache=True, nogil=True)
def run_hinges(R, C, gyr, mag_flag, mag_heading_deg, hinges, p, hs, sigma, turn, apply):
    """N frames: R ``[N, n, 3, 3]`` sensor → NED, C ``[N, n, 3, 3]`` segment orientations
    (Reset Zero; only their first finite frame is used, for the starting axis), gyr
    ``[N, n, 3]`` rad/s sensor axes, mag_flag ``[N, n]`` bool and mag_heading_deg ``[N, n]`` °
    (:class:`bpms.filter.disturbance.Disturbance` ``mag``, ``mag_heading_deg``), hinges
    ``[h, 2]`` (proximal, distal), p (:meth:`HingeSettings.params`), state hs
    ``[h, N_HINGE_STATE]`` / sigma ``[n]`` updated in place. Writes turn ``[N, n]`` rad: the
    rotation about the world vertical (NED z) to apply to each segment (0 elsewhere); with
    ``apply``, also turns R and C of those segments in place, frame by frame (a frame's turn
    depends only on that frame's and earlier attitudes)."""
    tau, recover, dt, prior, min_rate = p[0], p[1], p[2], p[3], p[4]
    follow, drift, floor, clean = p[5], p[6], p[7], p[8]
    k = 1.0 - math.exp(-dt / tau)
    decay = math.exp(-dt / recover) if recover > 0.0 else 0.0
    q = np.empty((3, 3))
    for t in range(R.shape[0]):
        for i in range(R.shape[1]):
            turn[t, i] = 0.0
            if mag_flag[t, i]:
                heading = mag_heading_deg[t, i]
                dev = abs(heading) * (math.pi / 180.0) if math.isfinite(heading) else 0.0
                # towards the field's deviation as the filter follows it, plus the drift
                sigma[i] = min(sigma[i] + follow * dev * dt, max(sigma[i], dev)) + drift * dt
            else:
                sigma[i] *= decay
        for j in range(hinges.shape[0]):
            ip, id_ = hinges[j, 0], hinges[j, 1]
            s = hs[j]
            ok = True
            for a in range(3):
                for b in range(3):
                    ok = ok and math.isfinite(R[t, ip, a, b]) and math.isfinite(R[t, id_, a, b])
            if not ok:
                continue
            if s[H_INIT] == 0.0:
                cok = True
                for a in range(3):
                    cok = cok and math.isfinite(C[t, ip, a, 1]) and math.isfinite(C[t, id_, a, 1])
                if not cok:
                    continue
                # the lateral axis in each sensor frame, from Reset Zero: Rᵀ C e_y
                for a in range(3):
                    s[H_JP + a] = (R[t, ip, 0, a] * C[t, ip, 0, 1] + R[t, ip, 1, a] * C[t, ip, 1, 1]
                                   + R[t, ip, 2, a] * C[t, ip, 2, 1])
                    s[H_JD + a] = (R[t, id_, 0, a] * C[t, id_, 0, 1]
                                   + R[t, id_, 1, a] * C[t, id_, 1, 1]
                                   + R[t, id_, 2, a] * C[t, id_, 2, 1])
                for a in range(3):
                    for b in range(3):
                        s[H_MP + 3 * a + b] = prior * s[H_JP + a] * s[H_JP + b]
                        s[H_MD + 3 * a + b] = prior * s[H_JD + a] * s[H_JD + b]
                s[H_OFFSET] = 0.0
                s[H_BASE] = 0.0
                s[H_INIT] = 1.0
            # Q = R_pᵀ R_d: distal sensor axes → proximal sensor axes
            for a in range(3):
                for b in range(3):
                    q[a, b] = (R[t, ip, 0, a] * R[t, id_, 0, b] + R[t, ip, 1, a] * R[t, id_, 1, b]
                               + R[t, ip, 2, a] * R[t, id_, 2, b])
            wp0, wp1, wp2 = gyr[t, ip, 0], gyr[t, ip, 1], gyr[t, ip, 2]
            wd0, wd1, wd2 = gyr[t, id_, 0], gyr[t, id_, 1], gyr[t, id_, 2]
            # the joint's own rate, along the hinge axis: in proximal and in distal axes
            r0 = q[0, 0] * wd0 + q[0, 1] * wd1 + q[0, 2] * wd2 - wp0
            r1 = q[1, 0] * wd0 + q[1, 1] * wd1 + q[1, 2] * wd2 - wp1
            r2 = q[2, 0] * wd0 + q[2, 1] * wd1 + q[2, 2] * wd2 - wp2
            if math.sqrt(r0 * r0 + r1 * r1 + r2 * r2) > min_rate:
                d0 = q[0, 0] * r0 + q[1, 0] * r1 + q[2, 0] * r2
                d1 = q[0, 1] * r0 + q[1, 1] * r1 + q[2, 1] * r2
                d2 = q[0, 2] * r0 + q[1, 2] * r1 + q[2, 2] * r2
                if r0 * s[H_JP] + r1 * s[H_JP + 1] + r2 * s[H_JP + 2] < 0.0:
                    r0, r1, r2, d0, d1, d2 = -r0, -r1, -r2, -d0, -d1, -d2
                # only while both headings are trusted: the relative orientation Q carries a
                # suspect segment's heading error into the axes
                if sigma[ip] < clean and sigma[id_] < clean:
                    _teach(s, H_MP, H_JP, r0, r1, r2, dt)
                    _teach(s, H_MD, H_JD, d0, d1, d2, dt)
            # the axis in the world from each side, horizontal parts
            px, py = _world_xy(R, t, ip, s, H_JP)
            dx, dy = _world_xy(R, t, id_, s, H_JD)
            w = math.sqrt(px * px + py * py) * math.sqrt(dx * dx + dy * dy)
            if w > 1e-9:
                e = math.atan2(dx * py - dy * px, dx * px + dy * py) - s[H_OFFSET]
                s[H_OFFSET] += w * k * math.atan2(math.sin(e), math.cos(e))
            vp, vd = sigma[ip] * sigma[ip], sigma[id_] * sigma[id_]
            if sigma[ip] < clean and sigma[id_] < clean:
                s[H_BASE] = s[H_OFFSET]  # both trusted: the hinge's clean offset
                continue
            e = s[H_OFFSET] - s[H_BASE]
            e = math.atan2(math.sin(e), math.cos(e)) / (vp + vd + floor * floor)
            turn[t, id_] += e * vd
            turn[t, ip] -= e * vp
        if apply:
            for i in range(R.shape[1]):
                if turn[t, i] != 0.0:
                    _turn_about_vertical(R, t, i, turn[t, i])
                    _turn_about_vertical(C, t, i, turn[t, i])


class HingeConstraint:
    """The constraint for the suit's four hinges, state kept between calls (batch = live)."""

    def __init__(self, dt: float, settings: HingeSettings | None = None) -> None:
        self.settings = settings or HingeSettings()
        self.params = self.settings.params(dt)
        self.state = HingeState()

    def set_follow_rate(self, rate: float) -> None:
        """The filter's heading gain towards a flagged field, 1/s (:class:`HingeSettings`)."""
        self.settings.follow_rate = float(rate)
        self.params[5] = float(rate)

    def reset(self) -> None:
        self.state.reset()

    def turns(self, R: np.ndarray, C: np.ndarray, gyr: np.ndarray, mag_flag: np.ndarray,
              mag_heading_deg: np.ndarray) -> np.ndarray:
        """``[N, 18]`` rad: the turn about the vertical for each segment (R, C
        ``[N, 18, 3, 3]``, gyr ``[N, 18, 3]`` rad/s, the flags' mag ``[N, 18]`` bool and
        mag_heading_deg ``[N, 18]``); R and C are left as they are."""
        return self._run(np.ascontiguousarray(R, dtype=np.float64),
                         np.ascontiguousarray(C, dtype=np.float64), gyr, mag_flag,
                         mag_heading_deg, False)

    def apply_in_place(self, R: np.ndarray, C: np.ndarray, gyr: np.ndarray,
                       mag_flag: np.ndarray, mag_heading_deg: np.ndarray) -> np.ndarray:
        """Turn the segments of ``R``, ``C`` (C-contiguous float64 ``[N, 18, 3, 3]``) by
        :meth:`turns`, in place; the turns."""
        for a in (R, C):
            if a.dtype != _FLOAT64 or not a.flags.c_contiguous or not a.flags.writeable:
                raise ValueError("apply_in_place needs writeable C-contiguous float64 arrays")
        return self._run(R, C, gyr, mag_flag, mag_heading_deg, True)

    def apply(self, R: np.ndarray, C: np.ndarray, gyr: np.ndarray, mag_flag: np.ndarray,
              mag_heading_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(R', C'): copies of sensor attitudes and segment orientations turned by
        :meth:`turns`."""
        R2 = np.array(R, dtype=np.float64)
        C2 = np.array(C, dtype=np.float64)
        self.apply_in_place(R2, C2, gyr, mag_flag, mag_heading_deg)
        return R2, C2

    def _run(self, R, C, gyr, mag_flag, mag_heading_deg, apply: bool) -> np.ndarray:
        """The kernel on R, C (C-contiguous float64, as the callers made sure)."""
        out = np.zeros(R.shape[:2])
        run_hinges(R, C, np.ascontiguousarray(gyr, dtype=np.float64),
                   np.ascontiguousarray(mag_flag, dtype=np.bool_),
                   np.ascontiguousarray(mag_heading_deg, dtype=np.float64),
                   HINGES, self.params, self.state.hinges, self.state.sigma, out, apply)
        return out


def vertical_turn(angle: np.ndarray) -> np.ndarray:
    """``[..., 3, 3]`` rotations by ``angle`` (rad) about the world vertical (NED z)."""
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros((*np.shape(angle), 3, 3))
    out[..., 0, 0], out[..., 0, 1] = c, -s
    out[..., 1, 0], out[..., 1, 1] = s, c
    out[..., 2, 2] = 1.0
    return out


__all__ = ["HINGES", "N_HINGE_STATE", "HingeConstraint", "HingeSettings", "HingeState",
           "run_hinges", "vertical_turn"]
