"""A plain scalar reference of the disturbance detector (bpms.filter.disturbance), one IMU and
one frame at a time with lists and :mod:`math`, following the module's documented rules:

- two world-fixed directions in sensor axes, turned by the gyro each sample (trapezoid of the
  bias-corrected rates plus the coning term): gravity ``ĝ`` (pulled towards the accelerometer
  with τ_g while not accelerating) and the horizontal field direction ``ĥ`` (pulled towards the
  measured one with τ_h while the field is clean, kept perpendicular to ĝ);
- acc flag: the RMS (τ_a) of the linear acceleration |ĝ − a| (g) above acc_th;
- rest (rate < rest_gyr, ||a| − 1| < rest_acc) for rest_time: the gyro bias follows the gyro
  (τ_b); the first still period (up to rest_learn_s) learns the field's norm N_ref and dip
  δ_ref (a change of the field while learning ends it); a still sensor whose ĝ is far from its
  accelerometer takes ĝ from it anew;
- mag flag: the deviation |m/N_ref − (cos δ_ref ĥ + sin δ_ref ĝ)| (low-passed τ_m) above mag_th,
  or the heading between ĥ and the measured horizontal field above asin(turn_th / cos δ_ref),
  each plus skew × |ω|; flagged with norm and dip back for recover_s: ĥ from the field;
- a failed sensor's frame uses the gyro's last good sample, skips the accelerometer or the
  field; a gyro beyond 30 rad/s holds every output and aligns anew from the next sample.
"""

from __future__ import annotations

import math

DEG = 180.0 / math.pi
RATE_MAX = 30.0


def _norm(v):
    return math.sqrt(sum(x * x for x in v))


def _dot(u, v):
    return sum(a * b for a, b in zip(u, v, strict=True))


def _cross(u, v):
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]


def _rotate(v, x):
    """``x`` turned by the rotation vector ``v`` (Rodrigues)."""
    ang = _norm(v)
    if ang < 1e-15:
        return list(x)
    k = [c / ang for c in v]
    c, s = math.cos(ang), math.sin(ang)
    d = _dot(k, x) * (1.0 - c)
    kx = _cross(k, x)
    return [x[a] * c + kx[a] * s + k[a] * d for a in range(3)]


class ReferenceDetector:
    """One IMU; settings as :class:`bpms.filter.disturbance.DisturbanceSettings`."""

    def __init__(self, gravity: float, dt: float, mag_th=0.10, mag_turn_th=0.05, acc_th_g=0.20,
                 tau_mag_s=0.1, tau_acc_s=0.25, tau_gravity_s=2.0, tau_heading_s=10.0,
                 skew_s=0.015, acc_gate_g=0.2, rest_gyr=0.1, rest_acc_g=0.05, rest_time_s=1.0,
                 rest_learn_s=5.0, bias_tau_s=2.0, recover_s=20.0):
        self.G, self.dt = gravity, dt
        self.mag_th, self.turn_th, self.acc_th = mag_th, mag_turn_th, acc_th_g
        self.skew, self.gate = skew_s, acc_gate_g
        self.rest_gyr, self.rest_acc, self.rest_time = rest_gyr, rest_acc_g, rest_time_s
        self.learn_s, self.recover = rest_learn_s, recover_s

        def k(tau: float) -> float:  # the gain of a first-order low-pass of time constant tau
            return 1.0 - math.exp(-dt / tau)

        self.km, self.ka, self.kg = k(tau_mag_s), k(tau_acc_s), k(tau_gravity_s)
        self.kh, self.kb, self.kmean = k(tau_heading_s), k(bias_tau_s), k(1.0)
        self.aligned = False
        self.g, self.h = [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]
        self.bias, self.w = [0.0] * 3, [0.0] * 3
        self.rest_t = self.learn_t = 0.0
        self.ref_norm = self.ref_dip = 0.0
        self.m_learnt = [0.0] * 3
        self.ready = False
        self.norm_lp = self.dip_lp = self.dev_lp = self.head_lp = 0.0
        self.acc_ms = self.acc_mean = 0.0
        self.mag_up = self.acc_up = self.ok_t = 0.0
        self.mag_flag = False
        self.recoveries = 0  # times ĥ was taken from the field after recover_s (a branch count)

    def outputs(self, acc_flag=None):
        r = self.ready
        nan = float("nan")
        return {"mag": self.mag_flag,
                "acc": math.sqrt(self.acc_ms) > self.acc_th if acc_flag is None else acc_flag,
                "mag_dev": self.dev_lp if r else nan,
                "mag_heading_deg": self.head_lp * DEG if r else nan,
                "acc_lin_g": math.sqrt(self.acc_ms), "mag_up_s": self.mag_up,
                "acc_up_s": self.acc_up, "norm_ratio": self.norm_lp - 1.0 if r else nan,
                "dip_dev_deg": (self.dip_lp - self.ref_dip) * DEG if r else nan,
                "acc_dev_g": self.acc_mean}

    def step(self, a_raw, m, gyro, failed=(False, False, False)):
        dt = self.dt
        acc_ok, mag_ok, gyr_ok = (not f for f in failed)
        gyro = list(gyro) if gyr_ok else list(self.w)
        if _dot(gyro, gyro) > RATE_MAX * RATE_MAX:
            self.aligned = False
            return self.outputs()
        snap = not self.aligned
        if snap:
            if not acc_ok:
                return self.outputs()
            an = _norm(a_raw)
            self.g = [c / an for c in a_raw] if an > 0.0 else [0.0, 0.0, 1.0]
            self.h = [1.0, 0.0, 0.0]
            self.w = list(gyro)
            self.aligned = True
        # 1. turn ĝ and ĥ by minus the step's rotation
        prev = self.w
        cone = _cross(prev, gyro)
        v = [(0.5 * (prev[a] + gyro[a]) - self.bias[a]) * dt + dt * dt / 12.0 * cone[a]
             for a in range(3)]
        self.w = list(gyro)
        g = _rotate([-c for c in v], self.g)
        h = _rotate([-c for c in v], self.h)
        rate = _norm(gyro)
        # 2. acceleration against ĝ
        still = False
        if acc_ok:
            a = [c / self.G for c in a_raw]
            an = _norm(a)
            lin = _norm([g[k] - a[k] for k in range(3)])
            self.acc_ms += self.ka * (lin * lin - self.acc_ms)
            self.acc_mean += self.kmean * (abs(an - 1.0) - self.acc_mean)
            if an > 0.0 and lin < self.gate:
                g = [g[k] + self.kg * (a[k] / an - g[k]) for k in range(3)]
                gn = _norm(g)
                g = [c / gn for c in g]
            still = rate < self.rest_gyr and abs(an - 1.0) < self.rest_acc
        self.g = g
        acc_flag = math.sqrt(self.acc_ms) > self.acc_th
        self.acc_up = self.acc_up + dt if acc_flag else 0.0
        hd = _dot(h, g)
        h = [h[k] - hd * g[k] for k in range(3)]
        hn = _norm(h)
        if hn > 1e-9:
            h = [c / hn for c in h]
        # 3. rest
        self.rest_t = self.rest_t + dt if still else 0.0
        rested = still and self.rest_t >= self.rest_time
        if rested and math.sqrt(self.acc_ms) > self.gate and an > 0.0:
            g = [c / an for c in a]
            self.g = g
            self.acc_ms = 0.0
            snap = True
        if rested and gyr_ok:
            self.bias = [self.bias[k] + self.kb * (gyro[k] - self.bias[k]) for k in range(3)]
        mn = _norm(m)
        mok = mag_ok and mn > 0.0
        x, xn, dip = [0.0] * 3, 0.0, 0.0
        if mok:
            md = _dot(m, g)
            dip = math.asin(min(1.0, max(-1.0, md / mn)))
            x = [m[k] - md * g[k] for k in range(3)]
            xn = _norm(x)
            if xn > 0.0:
                x = [c / xn for c in x]
            if rested and 0.0 < self.learn_t < self.learn_s:
                change = _norm([m[k] - self.m_learnt[k] for k in range(3)])
                if change > 0.5 * self.mag_th * self.ref_norm:
                    self.learn_t = self.learn_s  # a magnet came while learning
            if rested and self.learn_t < self.learn_s:
                n = self.learn_t / dt
                self.ref_norm = (self.ref_norm * n + mn) / (n + 1.0)
                self.ref_dip = (self.ref_dip * n + dip) / (n + 1.0)
                self.m_learnt = [(self.m_learnt[k] * n + m[k]) / (n + 1.0) for k in range(3)]
                self.learn_t += dt
                if xn > 0.0:
                    h = list(x)
                if not self.ready:
                    self.norm_lp, self.dip_lp = mn / self.ref_norm, dip
                    self.dev_lp = self.head_lp = 0.0
                self.ready = True
            elif not still and self.learn_t > 0.0:
                self.learn_t = self.learn_s  # the first still period is over
        if snap and mok and self.ready and xn > 0.0:
            h = list(x)
            self.dev_lp = self.head_lp = self.ok_t = 0.0
        if mok and self.ready:
            # 4. the field against the expected one
            rn, rd = self.ref_norm, self.ref_dip
            expected = [math.cos(rd) * h[k] + math.sin(rd) * g[k] for k in range(3)]
            dev = _norm([m[k] / rn - expected[k] for k in range(3)])
            head = math.atan2(_dot(_cross(h, x), g), _dot(h, x)) if xn > 0.0 else 0.0
            self.dev_lp += self.km * (dev - self.dev_lp)
            self.head_lp += self.km * (head - self.head_lp)
            self.norm_lp += self.km * (mn / rn - self.norm_lp)
            self.dip_lp += self.km * (dip - self.dip_lp)
            turn_th = math.asin(min(1.0, self.turn_th / max(math.cos(rd), 0.1)))
            flag = (self.dev_lp > self.mag_th + self.skew * rate
                    or abs(self.head_lp) > turn_th + self.skew * rate)
            if flag:
                back = (abs(self.norm_lp - 1.0) < 0.5 * self.mag_th
                        and abs(self.dip_lp - rd) < 0.5 * self.mag_th)
                self.ok_t = self.ok_t + dt if back else 0.0
                if self.ok_t >= self.recover and xn > 0.0:
                    h = list(x)
                    self.ok_t = 0.0
                    self.recoveries += 1
            elif xn > 0.0:
                self.ok_t = 0.0
                h = [h[k] + self.kh * (x[k] - h[k]) for k in range(3)]
            self.mag_flag = flag
            self.mag_up = self.mag_up + dt if flag else 0.0
        self.h = h
        return self.outputs(acc_flag)
