"""Per-IMU disturbance indicators, whichever attitude filter runs (one numba kernel: its state
recurs from frame to frame).

Two questions an investigator asks of every sensor and frame:

- **Is the magnetometer disturbed?** The field's norm and dip (angle below the horizontal)
  are compared with the values learnt while the sensor was still at the start (the calibration
  pause): ``|m| / ref − 1`` beyond ``mag_norm_th`` or ``|dip − ref|`` beyond
  ``mag_dip_th_deg``. Ferromagnetic material or a magnet nearby changes both; a clean room
  changes neither whatever the sensor's attitude. The dip needs the down direction: it comes
  from the running filter's attitude (``R[2, :]`` in body axes), and is only judged while the
  sensor turns slower than ``dip_max_rate`` (rad/s) — at fast rates the sensors' sampling skew
  and the filter's lag make it unreliable. Both quantities are low-passed over ``tau_s`` to
  average out the magnetometer noise (≈ 1.5 % of the norm per sample on real sensors).
  Limitation: a disturbance that only turns the field about the vertical (a weak field added
  at right angles in the horizontal plane) changes neither norm nor dip much and stays unseen;
  the filters' heading then follows it as far as their magnetic rejection lets it.
- **Is the acceleration far from gravity for long?** The mean of ``||a| − 1 g|`` over
  ``acc_tau_s`` (exponential) above ``acc_th_g``: the accelerometer is then no gravity
  reference, and a filter that trusts it (the original Mahony) tilts.

The reference is learnt during the first still period of each IMU (|ω| < ``rest_gyr`` rad/s
and ``||a| − 1 g|`` < ``rest_acc_g`` for ``rest_time_s``), averaged over up to
``rest_learn_s``; before that the magnetic indicator is False and ``ready`` False.
:meth:`DisturbanceTracker.reset` forgets it (a new stream or sensor).

Inputs: calibrated vectors as the filters get them — accelerometer in any unit with
``gravity[n]`` units per g (the suite: counts of 1 g pointing down; only the norm is used),
magnetometer in any unit, gyro rad/s, R ``[N, n, 3, 3]`` body → NED (NaN allowed: then the
accelerometer direction stands in for down).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from bpms.filter.bank import checked_gravity

#: per-IMU state columns
(S_REST_T, S_LEARN_T, S_REF_NORM, S_REF_DIP, S_READY, S_NORM_LP, S_DIP_LP, S_ACC_LP,
 S_MAG_FLAG) = range(9)
N_STATE = 9


@dataclass
class DisturbanceSettings:
    """Thresholds (physical units) of the indicators. The defaults stay quiet on all six
    BROAD trials without a magnet attached (largest low-passed deviations there: norm 6.8 %,
    dip 3.4°) and fire on the attached-magnet trial (norm 53 %, dip 26°)."""

    mag_norm_th: float = 0.08      # fraction of the learnt norm
    mag_dip_th_deg: float = 4.0    # degrees from the learnt dip
    dip_max_rate: float = 1.0      # rad/s: the dip is judged only below this rate
    tau_s: float = 0.5             # s, low-pass of norm and dip
    acc_th_g: float = 0.15         # g, mean |‖a‖ − 1 g| that counts as far from gravity
    acc_tau_s: float = 1.0         # s, averaging time of that mean
    rest_gyr: float = 0.1          # rad/s
    rest_acc_g: float = 0.05       # g
    rest_time_s: float = 1.0       # s still before learning starts
    rest_learn_s: float = 5.0      # s of stillness averaged into the reference

    def params(self, dt: float) -> np.ndarray:
        return np.array([self.mag_norm_th, math.radians(self.mag_dip_th_deg), self.dip_max_rate,
                         self.tau_s, self.acc_th_g, self.acc_tau_s, self.rest_gyr,
                         self.rest_acc_g, self.rest_time_s, self.rest_learn_s, dt])


@njit(cache=True)
def run_disturbance(acc, mag, gyr, R, gravity, valid, p, state, mag_dist, acc_dist, norm_ratio,
                    dip_dev, acc_mean):
    """N frames × n IMUs. acc/mag/gyr ``[N, n, 3]``, R ``[N, n, 3, 3]``, gravity ``[n]``,
    valid ``[N, n]`` (False: a failed sensor, state held), params, state ``[n, N_STATE]``.
    Writes mag_dist, acc_dist ``[N, n]`` bool, norm_ratio ``[N, n]`` (|m| / learnt − 1,
    low-passed, NaN before learnt), dip_dev ``[N, n]`` rad (dip − learnt dip, low-passed),
    acc_mean ``[N, n]`` g (mean ||a| − 1 g|)."""
    norm_th, dip_th, dip_rate, tau, acc_th, acc_tau = p[0], p[1], p[2], p[3], p[4], p[5]
    rest_gyr, rest_acc, rest_time, learn_s, dt = p[6], p[7], p[8], p[9], p[10]
    k = 1.0 - math.exp(-dt / tau) if tau > 0.0 else 1.0
    ka = 1.0 - math.exp(-dt / acc_tau) if acc_tau > 0.0 else 1.0
    for t in range(acc.shape[0]):
        for i in range(acc.shape[1]):
            s = state[i]
            if not valid[t, i]:
                mag_dist[t, i] = s[S_MAG_FLAG] > 0.0
                acc_dist[t, i] = s[S_ACC_LP] > acc_th
                acc_mean[t, i] = s[S_ACC_LP]
                norm_ratio[t, i] = s[S_NORM_LP] - 1.0 if s[S_READY] > 0.0 else np.nan
                dip_dev[t, i] = s[S_DIP_LP] - s[S_REF_DIP] if s[S_READY] > 0.0 else np.nan
                continue
            a0, a1, a2 = acc[t, i, 0], acc[t, i, 1], acc[t, i, 2]
            an = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2) / gravity[i]
            w = math.sqrt(gyr[t, i, 0] ** 2 + gyr[t, i, 1] ** 2 + gyr[t, i, 2] ** 2)
            # acceleration far from gravity (mean absolute deviation, g)
            s[S_ACC_LP] += ka * (abs(an - 1.0) - s[S_ACC_LP])
            acc_dist[t, i] = s[S_ACC_LP] > acc_th
            acc_mean[t, i] = s[S_ACC_LP]
            # field norm and dip
            m0, m1, m2 = mag[t, i, 0], mag[t, i, 1], mag[t, i, 2]
            mn = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
            d0, d1, d2 = R[t, i, 2, 0], R[t, i, 2, 1], R[t, i, 2, 2]
            if not (math.isfinite(d0) and math.isfinite(d1) and math.isfinite(d2)):
                dn = an * gravity[i]
                d0, d1, d2 = (a0 / dn, a1 / dn, a2 / dn) if dn > 0.0 else (0.0, 0.0, 1.0)
            dip = math.asin(min(1.0, max(-1.0, (m0 * d0 + m1 * d1 + m2 * d2) / mn))) \
                if mn > 0.0 else 0.0
            still = w < rest_gyr and abs(an - 1.0) < rest_acc
            s[S_REST_T] = s[S_REST_T] + dt if still else 0.0
            if still and s[S_REST_T] >= rest_time and s[S_LEARN_T] < learn_s and mn > 0.0:
                # learning: the running mean over the first still period (≤ learn_s)
                n_prev = s[S_LEARN_T] / dt
                s[S_REF_NORM] = (s[S_REF_NORM] * n_prev + mn) / (n_prev + 1.0)
                s[S_REF_DIP] = (s[S_REF_DIP] * n_prev + dip) / (n_prev + 1.0)
                s[S_LEARN_T] += dt
                if s[S_READY] == 0.0:
                    s[S_NORM_LP], s[S_DIP_LP] = 1.0, dip
                s[S_READY] = 1.0
            elif not still and s[S_LEARN_T] > 0.0:
                s[S_LEARN_T] = learn_s  # the first still period is over: reference frozen
            if s[S_READY] == 0.0:
                mag_dist[t, i] = False
                norm_ratio[t, i] = np.nan
                dip_dev[t, i] = np.nan
                continue
            s[S_NORM_LP] += k * (mn / s[S_REF_NORM] - s[S_NORM_LP])
            if w < dip_rate:
                s[S_DIP_LP] += k * (dip - s[S_DIP_LP])
            flag = abs(s[S_NORM_LP] - 1.0) > norm_th or abs(s[S_DIP_LP] - s[S_REF_DIP]) > dip_th
            s[S_MAG_FLAG] = 1.0 if flag else 0.0
            mag_dist[t, i] = flag
            norm_ratio[t, i] = s[S_NORM_LP] - 1.0
            dip_dev[t, i] = s[S_DIP_LP] - s[S_REF_DIP]


@dataclass
class Disturbance:
    """Indicators of N frames × n IMUs.

    mag: ``[N, n]`` bool magnetometer disturbed; acc: ``[N, n]`` bool acceleration far from
    gravity for long; mag_norm_ratio: ``[N, n]`` |m| / learnt − 1 (low-passed; NaN before the
    reference is learnt); mag_dip_dev_deg: ``[N, n]`` dip − learnt dip, degrees; acc_dev_g:
    ``[N, n]`` the mean ||a| − 1 g| in g. ``mag_count`` / ``acc_count``: ``[n]`` frames
    flagged in this batch (the processor's running totals are on the tracker)."""

    mag: np.ndarray
    acc: np.ndarray
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
    """Running indicators for ``n`` IMUs (state kept between calls; batch = live)."""

    def __init__(self, gravity: np.ndarray, dt: float,
                 settings: DisturbanceSettings | None = None) -> None:
        self.gravity = checked_gravity(gravity)
        self.n = len(self.gravity)
        self.settings = settings or DisturbanceSettings()
        self.params = self.settings.params(dt)
        self.state = np.zeros((self.n, N_STATE))
        #: ``[n]`` running totals of flagged frames since the last reset
        self.mag_count = np.zeros(self.n, np.int64)
        self.acc_count = np.zeros(self.n, np.int64)

    def reset(self) -> None:
        """Forget the learnt references and counts (a new stream)."""
        self.state[:] = 0.0
        self.mag_count[:] = 0
        self.acc_count[:] = 0

    @property
    def ready(self) -> np.ndarray:
        """``[n]`` bool: the magnetic reference has been learnt."""
        return self.state[:, S_READY] > 0.0

    def update(self, acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray,
               R: np.ndarray | None = None, errors: np.ndarray | None = None) -> Disturbance:
        """Indicators of N frames (``[N, n, 3]`` inputs, R ``[N, n, 3, 3]`` or None,
        errors ``[N, n, 3]`` failed-sensor flags: such frames hold the state)."""
        acc, mag, gyr = (np.ascontiguousarray(v, dtype=np.float64) for v in (acc, mag, gyr))
        N = acc.shape[0]
        Rm = (np.full((N, self.n, 3, 3), np.nan) if R is None
              else np.ascontiguousarray(R, dtype=np.float64))
        valid = (np.ones((N, self.n), np.bool_) if errors is None
                 else ~np.asarray(errors, dtype=np.bool_).any(axis=-1))
        out = Disturbance(np.zeros((N, self.n), np.bool_), np.zeros((N, self.n), np.bool_),
                          np.empty((N, self.n)), np.empty((N, self.n)), np.empty((N, self.n)))
        dip = np.empty((N, self.n))
        run_disturbance(acc, mag, gyr, Rm, self.gravity, np.ascontiguousarray(valid),
                        self.params, self.state, out.mag, out.acc, out.mag_norm_ratio, dip,
                        out.acc_dev_g)
        out.mag_dip_dev_deg = np.degrees(dip)
        self.mag_count += out.mag_count
        self.acc_count += out.acc_count
        return out


__all__ = ["Disturbance", "DisturbanceSettings", "DisturbanceTracker", "run_disturbance"]
