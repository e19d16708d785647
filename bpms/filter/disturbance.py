"""Per-IMU disturbance flags from the calibrated sensors alone, whichever filter runs (one numba
kernel: its state recurs from frame to frame).

Per IMU the detector carries two world-fixed directions in sensor axes, turned by the gyro
every sample: the gravity direction ``ĝ`` (pulled towards the accelerometer with a 2 s time
constant while the sensor is not accelerating) and the horizontal direction of the earth's
field ``ĥ`` (pulled towards the measured one with 10 s while the field is clean). It knows
nothing of the attitude filter, so a filter's own errors cannot raise a flag. From them:

- **mag**: the field that should be measured, ``m̂ = N_ref (cos δ_ref ĥ + sin δ_ref ĝ)``
  (norm ``N_ref`` and dip ``δ_ref`` learnt in the first still period, the calibration pause),
  against the measured ``m``: ``|m − m̂| / N_ref`` (low-passed 0.1 s) above ``mag_th`` = 0.10
  of the earth's field, plus ``skew_s`` × |ω| (15 ms × the rate: the magnetometer's and the
  gyro's samples are not simultaneous and 50 Hz integration errs, so a fast turn alone shows
  a deviation). It sees a magnet whichever way it bends the field: norm, dip, or only the
  heading.
- **acc**: the linear acceleration ``|ĝ − a|`` (g), RMS over 0.25 s, above ``acc_th_g`` =
  0.2 g: the accelerometer is then no gravity reference.

Each flag comes with its strength (:attr:`Disturbance.mag_dev`, fraction of the earth's field;
:attr:`Disturbance.mag_heading_deg`, the heading error a filter trusting the field would take;
:attr:`Disturbance.acc_lin_g`, g) and the time it has been up (``mag_up_s``, ``acc_up_s``). The
rule, thresholds and measured precision and recall: docs/filters.md, "Disturbance flags".

Inputs: calibrated filter-frame vectors as the filters get them — accelerometer in
``gravity[n]`` units per g pointing down (the suite's counts of 1 g), magnetometer in any
unit, gyro rad/s.

:meth:`DisturbanceTracker.reset` forgets what was learnt (a new stream). The kernel calls only
kernels of this module (numba's cache is keyed by this file).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from bpms.filter.bank import checked_gravity

#: Indices into the detector's parameters (:meth:`DisturbanceSettings.params`).
(P_MAG_TH, P_ACC_TH, P_TAU_M, P_TAU_A, P_TAU_G, P_TAU_H, P_SKEW, P_ACC_GATE, P_REST_GYR,
 P_REST_ACC, P_REST_TIME, P_LEARN_S, P_BIAS_TAU, P_RECOVER_S, P_DT, P_HEAD_TH) = range(16)
N_FLAG_PARAMS = 16
#: Per-IMU state columns of the detector.
(F_G0, F_G1, F_G2, F_H0, F_H1, F_H2, F_B0, F_B1, F_B2, F_W0, F_W1, F_W2, F_INIT, F_REST_T,
 F_LEARN_T, F_REF_NORM, F_REF_DIP, F_READY, F_NORM_LP, F_DIP_LP, F_ACC_MEAN, F_ACC_MS,
 F_DEV_LP, F_HEAD_LP, F_MAG_UP, F_ACC_UP, F_MAG_FLAG, F_OK_T, F_M0, F_M1, F_M2) = range(31)
N_FLAG_STATE = 31
#: Degrees per radian (the detector's value output gives its angles in degrees).
DEG = 180.0 / math.pi
#: Columns of the detector's value output ``[N, n, N_VALUES]`` (angles in degrees).
(V_NORM_RATIO, V_DIP_DEV, V_ACC_MEAN, V_MAG_DEV, V_MAG_HEADING, V_ACC_LIN, V_MAG_UP,
 V_ACC_UP) = range(8)
N_VALUES = 8
#: Averaging time (s) of ``acc_dev_g``, the mean ||a| − 1 g| kept from the older indicators.
ACC_MEAN_TAU_S = 1.0
#: rad/s (≈ 1700 °/s): a gyro reading beyond is no body's motion but a fault (the suit's
#: ITG-3200 ends at ±2000 °/s); the detector holds and aligns anew after it.
RATE_MAX = 30.0


@dataclass
class DisturbanceSettings:
    """The detector's thresholds and time constants (physical units; docs/filters.md).

    Fixed before the precision and recall were measured (bench/disturbance.py): ``mag_th``
    and ``acc_th`` are the truth's thresholds, the rest follow from the sensors and the body."""

    mag_th: float = 0.10        # |m − m̂| / N_ref: fraction of the earth's field
    mag_turn_th: float = 0.05   # the horizontal field turned by this fraction of the earth's
    acc_th_g: float = 0.20      # g, RMS linear acceleration
    tau_mag_s: float = 0.1      # s, low-pass of the field's deviation (noise ≈ 1 % per sample)
    tau_acc_s: float = 0.25     # s, RMS window of the linear acceleration
    tau_gravity_s: float = 2.0  # s, ĝ follows the accelerometer
    tau_heading_s: float = 10.0  # s, ĥ follows the measured field while it is clean
    skew_s: float = 0.015       # s, × |ω| added to mag_th (sampling skew, 50 Hz integration)
    acc_gate_g: float = 0.2     # g, no gravity correction above this linear acceleration
    rest_gyr: float = 0.1       # rad/s, still: below this rate ...
    rest_acc_g: float = 0.05    # g, ... and |a| within this of 1 g ...
    rest_time_s: float = 1.0    # s, ... for this long
    rest_learn_s: float = 5.0   # s of the first still period averaged into N_ref, δ_ref
    bias_tau_s: float = 2.0     # s, gyro bias follows a still gyro
    recover_s: float = 20.0     # s flagged with norm and dip back: ĥ taken from the field

    def params(self, dt: float) -> np.ndarray:
        return np.array([self.mag_th, self.acc_th_g, self.tau_mag_s, self.tau_acc_s,
                         self.tau_gravity_s, self.tau_heading_s, self.skew_s, self.acc_gate_g,
                         self.rest_gyr, self.rest_acc_g, self.rest_time_s, self.rest_learn_s,
                         self.bias_tau_s, self.recover_s, dt,
                         self.mag_turn_th])


@numba.njit(cache=True)
def _turn(vx, vy, vz, x, y, z):
    """(x, y, z) turned by the rotation vector v (rad), Rodrigues."""
    ang = math.sqrt(vx * vx + vy * vy + vz * vz)
    if ang < 1e-15:
        return x, y, z
    kx, ky, kz = vx / ang, vy / ang, vz / ang
    c, s = math.cos(ang), math.sin(ang)
    d = (kx * x + ky * y + kz * z) * (1.0 - c)
    return (x * c + (ky * z - kz * y) * s + kx * d, y * c + (kz * x - kx * z) * s + ky * d,
            z * c + (kx * y - ky * x) * s + kz * d)


@numba.njit(cache=True)
def _hold(s, t, i, acc_th, flags, values):
    """Outputs of a frame whose sensor failed: the state's."""
    ready = s[F_READY] > 0.0
    flags[0, t, i] = s[F_MAG_FLAG] > 0.0
    flags[1, t, i] = math.sqrt(s[F_ACC_MS]) > acc_th
    values[V_NORM_RATIO, t, i] = s[F_NORM_LP] - 1.0 if ready else np.nan
    values[V_DIP_DEV, t, i] = (s[F_DIP_LP] - s[F_REF_DIP]) * DEG if ready else np.nan
    values[V_ACC_MEAN, t, i] = s[F_ACC_MEAN]
    values[V_MAG_DEV, t, i] = s[F_DEV_LP] if ready else np.nan
    values[V_MAG_HEADING, t, i] = s[F_HEAD_LP] * DEG if ready else np.nan
    values[V_ACC_LIN, t, i] = math.sqrt(s[F_ACC_MS])
    values[V_MAG_UP, t, i] = s[F_MAG_UP]
    values[V_ACC_UP, t, i] = s[F_ACC_UP]


@numba.njit(cache=True, nogil=True)
def run_disturbance(acc, mag, gyr, gravity, errors, p, state, counts, flags, values):
    """N frames × n IMUs. acc ``[N, n, 3]`` (``gravity[n]`` units per g, pointing down),
    mag ``[N, n, 3]`` any unit, gyr ``[N, n, 3]`` rad/s; errors ``[N, n, 3]`` bool per sensor
    (True: failed, its last good value is used, as the filters do) or ``[0, n, 3]`` (none
    failed); p ``[N_FLAG_PARAMS]``; state ``[n, N_FLAG_STATE]`` (zeros: a new stream). Writes
    flags ``[2, N, n]`` (mag, acc) and values ``[N_VALUES, N, n]`` (rows ``V_*``; NaN where
    the field reference is not learnt yet), each row a contiguous ``[N, n]`` array, and adds
    the flagged frames to counts ``[n, 2]``."""
    mag_th, acc_th, skew, gate = p[P_MAG_TH], p[P_ACC_TH], p[P_SKEW], p[P_ACC_GATE]
    dt = p[P_DT]
    km = 1.0 - math.exp(-dt / p[P_TAU_M])
    ka = 1.0 - math.exp(-dt / p[P_TAU_A])
    kg = 1.0 - math.exp(-dt / p[P_TAU_G])
    kh = 1.0 - math.exp(-dt / p[P_TAU_H])
    kb = 1.0 - math.exp(-dt / p[P_BIAS_TAU])
    kmean = 1.0 - math.exp(-dt / ACC_MEAN_TAU_S)
    c12 = dt * dt / 12.0
    use_err = errors.shape[0] > 0
    for t in range(acc.shape[0]):
        for i in range(acc.shape[1]):
            s = state[i]
            acc_ok = not (use_err and errors[t, i, 0])
            mag_ok = not (use_err and errors[t, i, 1])
            gyr_ok = not (use_err and errors[t, i, 2])
            if not gyr_ok:  # gyro failed: its last good sample (held, as the banks)
                gx, gy, gz = s[F_W0], s[F_W1], s[F_W2]
            else:
                gx, gy, gz = gyr[t, i, 0], gyr[t, i, 1], gyr[t, i, 2]
            if gx * gx + gy * gy + gz * gz > RATE_MAX * RATE_MAX:
                # no limb turns this fast: a pinned or broken gyro reading, which would turn
                # ĝ and ĥ anywhere. Hold, and align anew from the next sane sample.
                s[F_INIT] = 0.0
                _hold(s, t, i, acc_th, flags, values)
                continue
            snap = s[F_INIT] == 0.0  # (re-)aligned: ĝ from the accelerometer, ĥ from the field
            if snap:
                if not acc_ok:
                    _hold(s, t, i, acc_th, flags, values)
                    continue
                an = math.sqrt(acc[t, i, 0] ** 2 + acc[t, i, 1] ** 2 + acc[t, i, 2] ** 2)
                if an > 0.0:
                    s[F_G0], s[F_G1], s[F_G2] = (acc[t, i, 0] / an, acc[t, i, 1] / an,
                                                 acc[t, i, 2] / an)
                else:
                    s[F_G0], s[F_G1], s[F_G2] = 0.0, 0.0, 1.0
                s[F_H0], s[F_H1], s[F_H2] = 1.0, 0.0, 0.0
                s[F_W0], s[F_W1], s[F_W2] = gx, gy, gz
                s[F_INIT] = 1.0
            # 1. turn ĝ and ĥ (world-fixed, sensor axes) by −(rotation over the step):
            #    trapezoid of the bias-corrected rates plus the coning term
            ax, ay, az = s[F_W0], s[F_W1], s[F_W2]
            vx = (0.5 * (ax + gx) - s[F_B0]) * dt + c12 * (ay * gz - az * gy)
            vy = (0.5 * (ay + gy) - s[F_B1]) * dt + c12 * (az * gx - ax * gz)
            vz = (0.5 * (az + gz) - s[F_B2]) * dt + c12 * (ax * gy - ay * gx)
            s[F_W0], s[F_W1], s[F_W2] = gx, gy, gz
            g0, g1, g2 = _turn(-vx, -vy, -vz, s[F_G0], s[F_G1], s[F_G2])
            h0, h1, h2 = _turn(-vx, -vy, -vz, s[F_H0], s[F_H1], s[F_H2])
            rate = math.sqrt(gx * gx + gy * gy + gz * gz)
            # 2. acceleration: a (g) against ĝ
            if acc_ok:
                a0, a1, a2 = (acc[t, i, 0] / gravity[i], acc[t, i, 1] / gravity[i],
                              acc[t, i, 2] / gravity[i])
                an = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
                l0, l1, l2 = g0 - a0, g1 - a1, g2 - a2
                lin = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
                s[F_ACC_MS] += ka * (lin * lin - s[F_ACC_MS])
                s[F_ACC_MEAN] += kmean * (abs(an - 1.0) - s[F_ACC_MEAN])
                if an > 0.0 and lin < gate:  # ĝ towards the accelerometer, not while shaken
                    g0 += kg * (a0 / an - g0)
                    g1 += kg * (a1 / an - g1)
                    g2 += kg * (a2 / an - g2)
                    gn = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
                    g0, g1, g2 = g0 / gn, g1 / gn, g2 / gn
                still = rate < p[P_REST_GYR] and abs(an - 1.0) < p[P_REST_ACC]
            else:
                still = False
            s[F_G0], s[F_G1], s[F_G2] = g0, g1, g2
            lin_rms = math.sqrt(s[F_ACC_MS])
            aflag = lin_rms > acc_th
            s[F_ACC_UP] = s[F_ACC_UP] + dt if aflag else 0.0
            # ĥ stays horizontal (perpendicular to ĝ), unit
            hd = h0 * g0 + h1 * g1 + h2 * g2
            h0, h1, h2 = h0 - hd * g0, h1 - hd * g1, h2 - hd * g2
            hn = math.sqrt(h0 * h0 + h1 * h1 + h2 * h2)
            if hn > 1e-9:
                h0, h1, h2 = h0 / hn, h1 / hn, h2 / hn
            # 3. rest: the gyro bias; the first still period: the field's norm and dip
            s[F_REST_T] = s[F_REST_T] + dt if still else 0.0
            rested = still and s[F_REST_T] >= p[P_REST_TIME]
            if rested and math.sqrt(s[F_ACC_MS]) > gate and an > 0.0:
                # still for a second, yet ĝ far from the accelerometer (a sensor fault turned
                # it): what a still accelerometer reads is gravity; the field's direction anew
                g0, g1, g2 = a0 / an, a1 / an, a2 / an
                s[F_G0], s[F_G1], s[F_G2] = g0, g1, g2
                s[F_ACC_MS] = 0.0
                snap = True
            if rested and gyr_ok:
                s[F_B0] += kb * (gx - s[F_B0])
                s[F_B1] += kb * (gy - s[F_B1])
                s[F_B2] += kb * (gz - s[F_B2])
            mok = mag_ok
            m0, m1, m2 = mag[t, i, 0], mag[t, i, 1], mag[t, i, 2]
            mn = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
            mok = mok and mn > 0.0
            if mok:
                md = m0 * g0 + m1 * g1 + m2 * g2
                dip = math.asin(min(1.0, max(-1.0, md / mn)))
                x0, x1, x2 = m0 - md * g0, m1 - md * g1, m2 - md * g2
                xn = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
                if xn > 0.0:
                    x0, x1, x2 = x0 / xn, x1 / xn, x2 / xn
                if rested and s[F_LEARN_T] > 0.0 and s[F_LEARN_T] < p[P_LEARN_S]:
                    # still, so the field in sensor axes must stay put: a change is a magnet
                    # coming (or going) while learning, which ends the learning here
                    c0, c1, c2 = m0 - s[F_M0], m1 - s[F_M1], m2 - s[F_M2]
                    if (math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
                            > 0.5 * mag_th * s[F_REF_NORM]):
                        s[F_LEARN_T] = p[P_LEARN_S]
                if rested and s[F_LEARN_T] < p[P_LEARN_S]:
                    n_prev = s[F_LEARN_T] / dt
                    s[F_REF_NORM] = (s[F_REF_NORM] * n_prev + mn) / (n_prev + 1.0)
                    s[F_REF_DIP] = (s[F_REF_DIP] * n_prev + dip) / (n_prev + 1.0)
                    s[F_M0] = (s[F_M0] * n_prev + m0) / (n_prev + 1.0)
                    s[F_M1] = (s[F_M1] * n_prev + m1) / (n_prev + 1.0)
                    s[F_M2] = (s[F_M2] * n_prev + m2) / (n_prev + 1.0)
                    s[F_LEARN_T] += dt
                    if xn > 0.0:
                        h0, h1, h2 = x0, x1, x2
                    if s[F_READY] == 0.0:
                        s[F_NORM_LP], s[F_DIP_LP] = mn / s[F_REF_NORM], dip
                        s[F_DEV_LP], s[F_HEAD_LP] = 0.0, 0.0
                    s[F_READY] = 1.0
                elif not still and s[F_LEARN_T] > 0.0:
                    s[F_LEARN_T] = p[P_LEARN_S]  # the first still period is over: frozen
            if snap and mok and s[F_READY] > 0.0 and xn > 0.0:
                h0, h1, h2 = x0, x1, x2
                s[F_DEV_LP], s[F_HEAD_LP], s[F_OK_T] = 0.0, 0.0, 0.0
            if mok and s[F_READY] > 0.0:
                # 4. the field against the one expected
                rn, rd = s[F_REF_NORM], s[F_REF_DIP]
                ch, sd = math.cos(rd), math.sin(rd)
                e0 = m0 / rn - (ch * h0 + sd * g0)
                e1 = m1 / rn - (ch * h1 + sd * g1)
                e2 = m2 / rn - (ch * h2 + sd * g2)
                dev = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
                head = 0.0  # signed angle ĥ → measured horizontal field, about ĝ
                if xn > 0.0:
                    cr = ((h1 * x2 - h2 * x1) * g0 + (h2 * x0 - h0 * x2) * g1
                          + (h0 * x1 - h1 * x0) * g2)
                    head = math.atan2(cr, h0 * x0 + h1 * x1 + h2 * x2)
                s[F_DEV_LP] += km * (dev - s[F_DEV_LP])
                s[F_HEAD_LP] += km * (head - s[F_HEAD_LP])
                s[F_NORM_LP] += km * (mn / rn - s[F_NORM_LP])
                s[F_DIP_LP] += km * (dip - s[F_DIP_LP])
                # the horizontal field turned: by more than mag_turn_th of the earth's field
                turn_th = math.asin(min(1.0, p[P_HEAD_TH] / max(ch, 0.1)))
                mflag = (s[F_DEV_LP] > mag_th + skew * rate
                         or abs(s[F_HEAD_LP]) > turn_th + skew * rate)
                if mflag:
                    # norm and dip back for long: the gyro's ĥ is no longer to be trusted
                    back = (abs(s[F_NORM_LP] - 1.0) < 0.5 * mag_th
                            and abs(s[F_DIP_LP] - rd) < 0.5 * mag_th)
                    s[F_OK_T] = s[F_OK_T] + dt if back else 0.0
                    if s[F_OK_T] >= p[P_RECOVER_S] and xn > 0.0:
                        h0, h1, h2 = x0, x1, x2
                        s[F_OK_T] = 0.0
                elif xn > 0.0:
                    s[F_OK_T] = 0.0
                    h0 += kh * (x0 - h0)
                    h1 += kh * (x1 - h1)
                    h2 += kh * (x2 - h2)
                s[F_MAG_FLAG] = 1.0 if mflag else 0.0
                s[F_MAG_UP] = s[F_MAG_UP] + dt if mflag else 0.0
            s[F_H0], s[F_H1], s[F_H2] = h0, h1, h2
            _hold(s, t, i, acc_th, flags, values)
            flags[1, t, i] = aflag
        for i in range(acc.shape[1]):
            counts[i, 0] += flags[0, t, i]
            counts[i, 1] += flags[1, t, i]


@dataclass
class Disturbance:
    """The detector's flags and their strengths, N frames × n IMUs.

    mag ``[N, n]`` bool: the field deviates from the earth's by more than
    :attr:`DisturbanceSettings.mag_th`; acc ``[N, n]`` bool: linear acceleration above
    :attr:`DisturbanceSettings.acc_th_g`. Strengths: mag_dev ``[N, n]`` ``|m − m̂| / N_ref``
    (fraction of the earth's field, low-passed 0.1 s); mag_heading_deg ``[N, n]`` ° the angle
    from the expected to the measured horizontal field (the heading error a filter trusting
    this sample would take); acc_lin_g ``[N, n]`` g RMS linear acceleration (0.25 s).
    mag_up_s / acc_up_s ``[N, n]`` s since the flag went up (0 while down). Also, as the older
    indicators: mag_norm_ratio ``|m| / N_ref − 1``, mag_dip_dev_deg ° dip − learnt dip (both
    low-passed 0.1 s, the dip against the detector's own ĝ), acc_dev_g g mean ``||a| − 1 g|``
    over 1 s. NaN where the field reference is not learnt yet."""

    mag: np.ndarray
    acc: np.ndarray
    mag_dev: np.ndarray
    mag_heading_deg: np.ndarray
    acc_lin_g: np.ndarray
    mag_up_s: np.ndarray
    acc_up_s: np.ndarray
    mag_norm_ratio: np.ndarray
    mag_dip_dev_deg: np.ndarray
    acc_dev_g: np.ndarray

    @property
    def mag_count(self) -> np.ndarray:
        return self.mag.sum(axis=0)

    @property
    def acc_count(self) -> np.ndarray:
        return self.acc.sum(axis=0)


class DisturbanceTracker:
    """The detector for ``n`` IMUs, state kept between calls (a batch and frame by frame give
    the same flags). ``gravity[n]``: accelerometer units per g; ``dt``: sample period, s."""

    def __init__(self, gravity: np.ndarray, dt: float,
                 settings: DisturbanceSettings | None = None) -> None:
        self.gravity = checked_gravity(gravity)
        self.n = len(self.gravity)
        self.settings = settings or DisturbanceSettings()
        self.params = self.settings.params(dt)
        self.state = np.zeros((self.n, N_FLAG_STATE))
        self._counts = np.zeros((self.n, 2), np.int64)  # flagged frames: mag, acc
        self._no_errors = np.zeros((0, self.n, 3), np.bool_)

    @property
    def mag_count(self) -> np.ndarray:
        """``[n]`` frames with the magnetometer flag up since the last reset."""
        return self._counts[:, 0]

    @property
    def acc_count(self) -> np.ndarray:
        """``[n]`` frames with the acceleration flag up since the last reset."""
        return self._counts[:, 1]

    def reset(self) -> None:
        """Forget everything learnt (a new stream)."""
        self.state[:] = 0.0
        self._counts[:] = 0

    @property
    def ready(self) -> np.ndarray:
        """``[n]`` bool: the field's norm and dip have been learnt."""
        return self.state[:, F_READY] > 0.0

    @property
    def gyro_bias(self) -> np.ndarray:
        """``[n, 3]`` rad/s: the gyro bias learnt at rest (sensor axes)."""
        return self.state[:, F_B0:F_B2 + 1].copy()

    def update(self, acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray,
               errors: np.ndarray | None = None) -> Disturbance:
        """Flags of N frames: ``[N, n, 3]`` calibrated inputs (units: :func:`run_disturbance`),
        errors ``[N, n, 3]`` failed-sensor flags (accel, mag, gyro) or None."""
        acc = np.ascontiguousarray(acc, dtype=np.float64)
        mag = np.ascontiguousarray(mag, dtype=np.float64)
        gyr = np.ascontiguousarray(gyr, dtype=np.float64)
        N = acc.shape[0]
        errors = (self._no_errors if errors is None
                  else np.ascontiguousarray(errors, dtype=np.bool_))
        flags = np.empty((2, N, self.n), np.bool_)
        v = np.empty((N_VALUES, N, self.n))
        run_disturbance(acc, mag, gyr, self.gravity, errors, self.params, self.state,
                        self._counts, flags, v)
        return Disturbance(flags[0], flags[1], v[V_MAG_DEV], v[V_MAG_HEADING],
                           v[V_ACC_LIN], v[V_MAG_UP], v[V_ACC_UP], v[V_NORM_RATIO],
                           v[V_DIP_DEV], v[V_ACC_MEAN])


__all__ = ["Disturbance", "DisturbanceSettings", "DisturbanceTracker", "run_disturbance"]
