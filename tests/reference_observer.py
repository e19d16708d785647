"""A plain scalar reference of the quaternion observer (bpms.filter.observer), one IMU and one
sample at a time with lists and :mod:`math`, written from the module's documented steps
(docs/filters.md) rather than from its code:

0. alignment from the first sample: TRIAD of the measured down vector ``−f`` and the field
   (rows of the body → NED matrix: north, east, down); the field's norm and dip become the
   magnetic reference;
1. prediction ``q ← q ⊗ exp(φ)``: ``φ = (ω − b)dt`` (observer) or the trapezoid of the
   bias-corrected rates plus the coning term ``(1/12)(ω_{k−1} × ω_k)dt²`` (adaptive);
2. the measured down vector in the earth frame ``d = R(q)(−f)``; the gravity low-pass
   ``ℓ ← ℓ + k(d − ℓ)``, ``k = 1 − exp(−dt/τ_acc)``; the body acceleration ``ℓ − d``;
3. inclination error: the rotation vector turning ``ℓ`` onto the vertical (horizontal axis);
   heading error ``−ψ``, ψ the heading of the field in the earth frame after that tilt;
   a field whose norm (ratio) or dip (rad) is off the reference is disturbed: no heading
   correction; a steady new field (a candidate within the thresholds for longer than
   mag_new_time) replaces the reference after as long a rejection; a clean field moves the
   reference slowly (τ = 60 s);
4. correction ``q ← exp(½[k_incl·dt·θ, k_head·dt·(−ψ·trust)]) ⊗ q``, ``ℓ`` turned with it;
5. bias: at rest (adaptive) the mean of 0.5 s blocks of still samples, each taken when the
   next block is complete too, weighed over at most rest_tau seconds; else the integral
   ``b ← b − k_bias·dt·R(q)ᵀ e`` while ``|e|`` < 0.2 rad; clipped to ±bias_clip.

Quaternions are scalar first, body → NED; a positive scalar part is kept after each
correction.
"""

from __future__ import annotations

import math

G = 9.81
REF_TAU = 60.0
MAX_ERR = 0.2
BLOCK = 0.5
BIAS_CLIP = math.radians(5.0)
REST_GYR = math.radians(2.0)


def _norm(v):
    return math.sqrt(sum(x * x for x in v))


def _cross(u, v):
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]


def _qmul(a, b):
    return [a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
            a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
            a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
            a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]]


def _qexp(v):
    """The unit quaternion of the rotation vector ``v`` (rad)."""
    ang = _norm(v)
    if ang < 1e-12:
        return [1.0] + [0.5 * x for x in v]
    s = math.sin(0.5 * ang) / ang
    return [math.cos(0.5 * ang)] + [x * s for x in v]


def _unit(q):
    n = _norm(q)
    return [x / n for x in q]


def dcm(q):
    """Body → NED rotation matrix (rows) of the quaternion ``q``."""
    w, x, y, z = q
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]


def _apply(R, v):
    return [sum(R[r][c] * v[c] for c in range(3)) for r in range(3)]


def _turn(v, x):
    """``x`` turned by the rotation vector ``v`` (through its quaternion: q x q*)."""
    if _norm(v) < 1e-15:
        return list(x)
    return _apply(dcm(_unit(_qexp(v))), x)


def _from_matrix(R):
    """Quaternion of a rotation matrix, scalar part ≥ 0 (any robust method)."""
    w = math.sqrt(max(0.0, 1 + R[0][0] + R[1][1] + R[2][2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + R[0][0] - R[1][1] - R[2][2])) / 2, R[2][1] - R[1][2])
    y = math.copysign(math.sqrt(max(0.0, 1 - R[0][0] + R[1][1] - R[2][2])) / 2, R[0][2] - R[2][0])
    z = math.copysign(math.sqrt(max(0.0, 1 - R[0][0] - R[1][1] + R[2][2])) / 2, R[1][0] - R[0][1])
    return _unit([w, x, y, z])


class ReferenceObserver:
    """One IMU; settings as :class:`bpms.filter.observer.ObserverGains` (dip threshold in
    degrees, times in s, rates in rad/s, accelerations in m/s²)."""

    def __init__(self, k_incl=0.5, k_head=0.2, k_bias=0.01, tau_acc=1.5, dt=0.02,
                 mag_norm_th=0.05, mag_dip_th_deg=5.0, mag_new_time_s=10.0,
                 bias_clip=BIAS_CLIP, rest_gyr=REST_GYR, rest_acc=0.3,
                 rest_time=1.0, rest_tau=0.0, trapezoid=False):
        self.k_incl, self.k_head, self.k_bias, self.tau, self.dt = (k_incl, k_head, k_bias,
                                                                     tau_acc, dt)
        self.norm_th, self.dip_th, self.new_time = (mag_norm_th, math.radians(mag_dip_th_deg),
                                                    mag_new_time_s)
        self.clip, self.rest_gyr, self.rest_acc = bias_clip, rest_gyr, rest_acc
        self.rest_time, self.rest_tau, self.trapezoid = rest_time, rest_tau, trapezoid
        self.initialised = False
        self.rest_regime_reached = self.new_field_accepted = False

    def _align(self, f, m):
        down = [-x for x in f]
        dn = _norm(down)
        if dn == 0.0:
            down, dn = [0.0, 0.0, 1.0], 1.0
        down = [x / dn for x in down]
        east = _cross(down, m)
        if _norm(east) < 1e-12:  # no usable field: any heading
            east = [down[1], -down[0], 0.0]
            if _norm(east) < 1e-12:
                east = [0.0, 1.0, 0.0]
        east = [x / _norm(east) for x in east]
        north = _cross(east, down)
        self.q = _from_matrix([north, east, down])
        self.b = [0.0, 0.0, 0.0]
        self.acc = [0.0, 0.0, 0.0]
        self.lp = [0.0, 0.0, dn]
        mn = _norm(m)
        dip = math.atan2(sum(a * b for a, b in zip(down, m, strict=True)),
                         abs(sum(a * b for a, b in zip(north, m, strict=True))))
        self.ref = [mn, dip]
        self.cand = [mn, dip, 0.0]
        self.reject_t = 0.0
        self.g_prev = None
        self.rest_t = 0.0
        self.filling, self.waiting = [0.0] * 4, [0.0] * 4  # sums x, y, z and sample count
        self.averaged = 0.0
        self.disturbed = False
        self.initialised = True

    def update(self, f, m, g, trust=1.0):
        """One sample: ``f`` specific force (m/s²), ``m`` field (any unit), ``g`` rad/s."""
        if not self.initialised:
            self._align(f, m)
            self.g_prev = list(g)
            return
        dt, b = self.dt, self.b
        # 1. prediction
        if self.trapezoid:
            p = self.g_prev
            mean = [0.5 * (p[k] + g[k]) - b[k] for k in range(3)]
            con = _cross(p, g)
            phi = [mean[k] * dt + con[k] * dt * dt / 12.0 for k in range(3)]
        else:
            phi = [(g[k] - b[k]) * dt for k in range(3)]
        self.g_prev = list(g)
        q = _unit(_qmul(self.q, _qexp(phi)))
        R = dcm(q)
        # 2. gravity low-pass in the earth frame, body acceleration
        d = _apply(R, [-x for x in f])
        k = 1.0 - math.exp(-dt / self.tau) if self.tau > 0.0 else 1.0
        ell = [self.lp[a] + k * (d[a] - self.lp[a]) for a in range(3)]
        self.acc = [ell[a] - d[a] for a in range(3)]
        # 3a. inclination: the rotation vector taking ℓ onto the vertical (0, 0, 1)
        theta = [0.0, 0.0, 0.0]
        ln = _norm(ell)
        if ln > 0.0:
            u = [x / ln for x in ell]
            axis = _cross(u, [0.0, 0.0, 1.0])  # horizontal, |axis| = sin(angle)
            if math.hypot(u[0], u[1]) > 1e-12:
                angle = math.atan2(math.hypot(u[0], u[1]), u[2])
                theta = [axis[0] / _norm(axis) * angle, axis[1] / _norm(axis) * angle, 0.0]
        # 3b. heading of the tilt-corrected field; the magnetic reference
        mt = _turn(theta, _apply(R, m))
        mh, mn = math.hypot(mt[0], mt[1]), _norm(mt)
        psi = math.atan2(mt[1], mt[0]) if mh > 0.0 else 0.0
        dip = math.atan2(mt[2], mh)

        def near(norm, ref_dip):
            return (mn > 0.0 and norm > 0.0 and abs(mn / norm - 1.0) < self.norm_th
                    and abs(dip - ref_dip) < self.dip_th)

        if near(self.cand[0], self.cand[1]):
            kc = min(1.0, dt)
            self.cand = [self.cand[0] + kc * (mn - self.cand[0]),
                         self.cand[1] + kc * (dip - self.cand[1]), self.cand[2] + dt]
        else:
            self.cand = [mn, dip, 0.0]
        disturbed = not near(*self.ref)
        if disturbed:
            self.reject_t += dt
            if self.reject_t > self.new_time and self.cand[2] > self.new_time:
                self.ref = self.cand[:2]
                self.reject_t = 0.0
                disturbed = False
                self.new_field_accepted = True
        else:
            self.reject_t = 0.0
            self.ref = [r + dt / REF_TAU * (v - r) for r, v in zip(self.ref, (mn, dip),
                                                                   strict=True)]
        self.disturbed = disturbed
        head = 0.0 if disturbed or mh == 0.0 else -psi * trust
        # 4. correction, ℓ carried along
        c = [self.k_incl * dt * theta[0], self.k_incl * dt * theta[1], self.k_head * dt * head]
        q = _unit(_qmul(_qexp(c), q))
        self.q = q if q[0] >= 0.0 else [-x for x in q]
        self.lp = _turn(c, ell)
        # 5. gyro bias
        r = [g[a] - b[a] for a in range(3)]
        still = (self.rest_tau > 0.0 and _norm(r) < self.rest_gyr
                 and abs(_norm(f) - G) < self.rest_acc)
        self.rest_t = self.rest_t + dt if still else 0.0
        if still and self.rest_t >= self.rest_time:
            self.rest_regime_reached = True
            self.filling = [self.filling[a] + g[a] for a in range(3)] + [self.filling[3] + 1]
            if self.filling[3] * dt >= BLOCK - 0.5 * dt:  # a block is complete
                nb = self.waiting[3]
                if nb > 0.0:  # the block before it is taken, weighed by its share
                    self.averaged = min(self.averaged + nb, self.rest_tau / dt)
                    w = nb / self.averaged
                    mean = [self.waiting[a] / nb for a in range(3)]
                    self.b = [self._clip(b[a] + w * (mean[a] - b[a])) for a in range(3)]
                self.waiting, self.filling = self.filling, [0.0] * 4
        else:
            if not still:
                self.filling, self.waiting = [0.0] * 4, [0.0] * 4
            kb = self.k_bias * dt
            e = [theta[0], theta[1], head]
            if kb > 0.0 and _norm(e) < MAX_ERR:
                # the error in body axes through the predicted attitude (before step 4)
                e_body = [sum(R[row][a] * e[row] for row in range(3)) for a in range(3)]
                self.b = [self._clip(b[a] - kb * e_body[a]) for a in range(3)]

    def _clip(self, v):
        return min(self.clip, max(-self.clip, v))

    @property
    def R(self):
        return dcm(self.q)
