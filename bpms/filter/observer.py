"""The quaternion nonlinear observer of the second seed paper, for n IMUs at once (numba),
in two settings: ``observer`` (the paper's structure) and ``adaptive`` (two physical
additions). One state, one kernel; :class:`ObserverGains` chooses.

State per IMU: attitude quaternion ``q`` (body → NED, scalar first), gyro-bias estimate
``b`` (rad/s), the low-passed gravity vector ``ℓ`` in the estimated earth frame (m/s²) whose
difference from the measurement is the body-acceleration estimate, the magnetic reference
(field norm and dip) used to reject disturbed magnetometer samples, the previous gyro sample
and the time the sensor has been still.

Per sample (derivation and the equations the paper leaves out: docs/filters.md):

1. prediction ``q ← q ⊗ exp(½ φ)`` with the rotation vector ``φ`` of the step: the rectangle
   rule ``φ = (ω − b)dt`` (``trapezoid`` off, the observer), or the trapezoid with coning
   correction ``φ = (½(ω_{k−1} + ω_k) − b)dt + (1/12)(ω_{k−1} × ω_k)dt²`` (``trapezoid`` on,
   the adaptive setting): a gyro sample is the rate *at* the sample instant, and the
   rectangle rule lets the attitude lead by ``½·dt·Δω``;
2. body acceleration: ``d = R(q)(−f)`` is the measured "down" vector in the earth frame,
   ``ℓ ← ℓ + k(d − ℓ)`` with ``k = 1 − exp(−dt/τ_acc)`` (the explicit minimiser of the
   two-term cost of the paper: prediction of the gravity vs. measurement), and
   ``a = ℓ − d`` the estimated linear acceleration (earth frame, m/s²);
3. pseudo-measurement ``q_m = Rz(−ψ) ⊗ R_tilt ⊗ q``: ``R_tilt`` turns ``ℓ`` onto the vertical,
   ``ψ`` is the heading of the tilt-corrected magnetic field (TRIAD, closed form);
4. correction towards ``q_m``: the error ``q_m ⊗ q⁻¹`` is split into its inclination part
   (rotation vector ``θ``, horizontal axis) and heading part ``−ψ`` about the vertical, applied
   with gains ``k_incl``, ``k_head`` (1/s); ``ℓ`` is carried along with the correction;
   magnetically disturbed samples (norm or dip off the reference) get no heading correction;
5. bias ``b ← b − k_bias·dt·R(q)ᵀ e`` with ``e`` the error rotation vector (PI action),
   held while ``|e|`` > 0.2 rad (anti-windup); with ``rest_tau`` > 0 (adaptive), while
   ``|ω − b|`` < ``rest_gyr`` and ``||f| − g|`` < ``rest_acc`` for longer than ``rest_time``
   the sensor is still and what it reads *is* its bias: the bias becomes the mean of the
   still samples in blocks of :data:`REST_BLOCK_S`, each block taken only once the next one
   is still too (a motion starts slowly, under ``rest_gyr``: its first samples are not
   bias), over at most the last ``rest_tau`` seconds of stillness (the first block is taken
   whole, later ones weigh by their share).

A heading trust ``trust[N, n]`` (0–1, optional) scales the heading correction and the
heading's share of the bias update per sample: the processor lowers it while the disturbance
flags say the field is off (docs/filters.md); 0 switches heading corrections off (the 6D
mode).

Inputs (the adapters in :mod:`bpms.filter.algorithms` convert the suite's calibrated units):
specific force ``f`` in m/s² (reads (0, 0, −9.81) level in a Z-down body frame),
magnetometer in any unit (≈ 1 is convenient), gyro rad/s, all ``[N, n, 3]``.

The kernels here call only kernels of this module, so numba's cache (keyed by this file)
never holds stale machine code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from bpms.filter.kernel_state import KernelState
from bpms.filter.rotations import dcm_to_euler
from bpms.io.frames import N_IMUS

#: Indices into ``params``.
(K_INCL, K_HEAD, K_BIAS, TAU_ACC, DT, MAG_NORM_TH, MAG_DIP_TH, MAG_NEW_TIME, BIAS_CLIP,
 REST_GYR, REST_ACC, REST_TIME, REST_TAU, TRAPEZOID) = range(14)
N_PARAMS = 14
#: Indices into the per-IMU magnetic state.
M_REF_NORM, M_REF_DIP, M_CAND_NORM, M_CAND_DIP, M_CAND_TIME, M_REJECT_TIME = range(6)
#: Time constant (s) of the slow update of the accepted magnetic reference.
MAG_REF_TAU_S = 60.0
#: Error angle (rad) above which the bias integrator holds (anti-windup).
BIAS_MAX_ERR = 0.2
G_MS2 = 9.81
#: s, the block of still samples the bias at rest is averaged over.
REST_BLOCK_S = 0.5


@njit(cache=True)
def _dcm(q0, q1, q2, q3, R, i):
    R[i, 0, 0] = 1.0 - 2.0 * (q2 * q2 + q3 * q3)
    R[i, 0, 1] = 2.0 * (q1 * q2 - q0 * q3)
    R[i, 0, 2] = 2.0 * (q1 * q3 + q0 * q2)
    R[i, 1, 0] = 2.0 * (q1 * q2 + q0 * q3)
    R[i, 1, 1] = 1.0 - 2.0 * (q1 * q1 + q3 * q3)
    R[i, 1, 2] = 2.0 * (q2 * q3 - q0 * q1)
    R[i, 2, 0] = 2.0 * (q1 * q3 - q0 * q2)
    R[i, 2, 1] = 2.0 * (q2 * q3 + q0 * q1)
    R[i, 2, 2] = 1.0 - 2.0 * (q1 * q1 + q2 * q2)


@njit(cache=True)
def _exp(vx, vy, vz):
    """Quaternion of the rotation vector v (rad)."""
    ang = math.sqrt(vx * vx + vy * vy + vz * vz)
    if ang < 1e-12:
        return 1.0, 0.5 * vx, 0.5 * vy, 0.5 * vz
    s = math.sin(0.5 * ang) / ang
    return math.cos(0.5 * ang), vx * s, vy * s, vz * s


@njit(cache=True)
def _mul(a0, a1, a2, a3, b0, b1, b2, b3):
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@njit(cache=True)
def _rotate(vx, vy, vz, x, y, z):
    """Rotate (x, y, z) by the rotation vector v (Rodrigues)."""
    ang = math.sqrt(vx * vx + vy * vy + vz * vz)
    if ang < 1e-15:
        return x, y, z
    kx, ky, kz = vx / ang, vy / ang, vz / ang
    c, s = math.cos(ang), math.sin(ang)
    cx = ky * z - kz * y
    cy = kz * x - kx * z
    cz = kx * y - ky * x
    d = (kx * x + ky * y + kz * z) * (1.0 - c)
    return x * c + cx * s + kx * d, y * c + cy * s + ky * d, z * c + cz * s + kz * d


@njit(cache=True)
def _init_imu(i, f, m, q, bias, lp, acc_est, mag_state):
    """Alignment from one sample: TRIAD of the measured down vector and magnetic field."""
    dx, dy, dz = -f[0], -f[1], -f[2]
    dn = math.sqrt(dx * dx + dy * dy + dz * dz)
    if dn == 0.0:
        dx, dy, dz, dn = 0.0, 0.0, 1.0, 1.0
    dx, dy, dz = dx / dn, dy / dn, dz / dn
    # east = down × m, north = east × down (body coordinates); rows of R = N, E, D
    ex = dy * m[2] - dz * m[1]
    ey = dz * m[0] - dx * m[2]
    ez = dx * m[1] - dy * m[0]
    en = math.sqrt(ex * ex + ey * ey + ez * ez)
    if en < 1e-12:  # no usable field: any heading
        ex, ey, ez = dy, -dx, 0.0
        en = math.sqrt(ex * ex + ey * ey)
        if en < 1e-12:
            ex, ey, ez, en = 0.0, 1.0, 0.0, 1.0
    ex, ey, ez = ex / en, ey / en, ez / en
    nx = ey * dz - ez * dy
    ny = ez * dx - ex * dz
    nz = ex * dy - ey * dx
    # rotation matrix rows (N, E, D) → quaternion (Shepperd)
    r00, r01, r02 = nx, ny, nz
    r10, r11, r12 = ex, ey, ez
    r20, r21, r22 = dx, dy, dz
    tr = r00 + r11 + r22
    if tr > 0.0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q0, q1, q2, q3 = 0.25 * s, (r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s
    elif r00 > r11 and r00 > r22:
        s = 2.0 * math.sqrt(1.0 + r00 - r11 - r22)
        q0, q1, q2, q3 = (r21 - r12) / s, 0.25 * s, (r01 + r10) / s, (r02 + r20) / s
    elif r11 > r22:
        s = 2.0 * math.sqrt(1.0 + r11 - r00 - r22)
        q0, q1, q2, q3 = (r02 - r20) / s, (r01 + r10) / s, 0.25 * s, (r12 + r21) / s
    else:
        s = 2.0 * math.sqrt(1.0 + r22 - r00 - r11)
        q0, q1, q2, q3 = (r10 - r01) / s, (r02 + r20) / s, (r12 + r21) / s, 0.25 * s
    qn = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    if q0 < 0.0:
        qn = -qn
    q[i, 0], q[i, 1], q[i, 2], q[i, 3] = q0 / qn, q1 / qn, q2 / qn, q3 / qn
    for k in range(3):
        bias[i, k] = 0.0
        acc_est[i, k] = 0.0
    lp[i, 0], lp[i, 1], lp[i, 2] = 0.0, 0.0, dn
    mn = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
    mh = (nx * m[0] + ny * m[1] + nz * m[2])
    mdown = dx * m[0] + dy * m[1] + dz * m[2]
    dip = math.atan2(mdown, abs(mh))
    mag_state[i, M_REF_NORM] = mn
    mag_state[i, M_REF_DIP] = dip
    mag_state[i, M_CAND_NORM] = mn
    mag_state[i, M_CAND_DIP] = dip
    mag_state[i, M_CAND_TIME] = 0.0
    mag_state[i, M_REJECT_TIME] = 0.0


@njit(cache=True)
def _step_imu(i, f, m, g, p, q, bias, lp, acc_est, mag_state, mag_dist, gprev, rest, rest_b,
              trust, R):
    dt = p[DT]
    # 1. prediction: trapezoid + coning correction (or the observer's rectangle rule)
    if p[TRAPEZOID] > 0.0:
        ax, ay, az = gprev[i, 0], gprev[i, 1], gprev[i, 2]
        wx = 0.5 * (ax + g[0]) - bias[i, 0]
        wy = 0.5 * (ay + g[1]) - bias[i, 1]
        wz = 0.5 * (az + g[2]) - bias[i, 2]
        c = dt * dt / 12.0
        vx = wx * dt + c * (ay * g[2] - az * g[1])
        vy = wy * dt + c * (az * g[0] - ax * g[2])
        vz = wz * dt + c * (ax * g[1] - ay * g[0])
    else:
        vx, vy, vz = ((g[0] - bias[i, 0]) * dt, (g[1] - bias[i, 1]) * dt,
                      (g[2] - bias[i, 2]) * dt)
    gprev[i, 0], gprev[i, 1], gprev[i, 2] = g[0], g[1], g[2]
    d0, d1, d2, d3 = _exp(vx, vy, vz)
    q0, q1, q2, q3 = _mul(q[i, 0], q[i, 1], q[i, 2], q[i, 3], d0, d1, d2, d3)
    n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    q0, q1, q2, q3 = q0 / n, q1 / n, q2 / n, q3 / n
    _dcm(q0, q1, q2, q3, R, i)
    # 2. gravity low-pass in the estimated earth frame; body acceleration
    bx, by, bz = -f[0], -f[1], -f[2]
    dnx = R[i, 0, 0] * bx + R[i, 0, 1] * by + R[i, 0, 2] * bz
    dny = R[i, 1, 0] * bx + R[i, 1, 1] * by + R[i, 1, 2] * bz
    dnz = R[i, 2, 0] * bx + R[i, 2, 1] * by + R[i, 2, 2] * bz
    k = 1.0 - math.exp(-dt / p[TAU_ACC]) if p[TAU_ACC] > 0.0 else 1.0
    lx = lp[i, 0] + k * (dnx - lp[i, 0])
    ly = lp[i, 1] + k * (dny - lp[i, 1])
    lz = lp[i, 2] + k * (dnz - lp[i, 2])
    acc_est[i, 0], acc_est[i, 1], acc_est[i, 2] = lx - dnx, ly - dny, lz - dnz
    # 3a. inclination pseudo-measurement
    ln = math.sqrt(lx * lx + ly * ly + lz * lz)
    tx, ty = 0.0, 0.0
    if ln > 0.0:
        ux, uy, uz = lx / ln, ly / ln, lz / ln
        sh = math.sqrt(ux * ux + uy * uy)
        if sh > 1e-12:
            theta = math.atan2(sh, uz)
            tx, ty = uy / sh * theta, -ux / sh * theta
    # 3b. heading pseudo-measurement and magnetic reference (as the observer)
    mx = R[i, 0, 0] * m[0] + R[i, 0, 1] * m[1] + R[i, 0, 2] * m[2]
    my = R[i, 1, 0] * m[0] + R[i, 1, 1] * m[1] + R[i, 1, 2] * m[2]
    mz = R[i, 2, 0] * m[0] + R[i, 2, 1] * m[1] + R[i, 2, 2] * m[2]
    mx, my, mz = _rotate(tx, ty, 0.0, mx, my, mz)
    mh = math.sqrt(mx * mx + my * my)
    mn = math.sqrt(mx * mx + my * my + mz * mz)
    psi = math.atan2(my, mx) if mh > 0.0 else 0.0
    dip = math.atan2(mz, mh)
    ms = mag_state
    if mn > 0.0 and ms[i, M_CAND_NORM] > 0.0 \
            and abs(mn / ms[i, M_CAND_NORM] - 1.0) < p[MAG_NORM_TH] \
            and abs(dip - ms[i, M_CAND_DIP]) < p[MAG_DIP_TH]:
        ms[i, M_CAND_TIME] += dt
        kc = min(1.0, dt)
        ms[i, M_CAND_NORM] += kc * (mn - ms[i, M_CAND_NORM])
        ms[i, M_CAND_DIP] += kc * (dip - ms[i, M_CAND_DIP])
    else:
        ms[i, M_CAND_NORM], ms[i, M_CAND_DIP], ms[i, M_CAND_TIME] = mn, dip, 0.0
    disturbed = not (mn > 0.0 and ms[i, M_REF_NORM] > 0.0
                     and abs(mn / ms[i, M_REF_NORM] - 1.0) < p[MAG_NORM_TH]
                     and abs(dip - ms[i, M_REF_DIP]) < p[MAG_DIP_TH])
    if disturbed:
        ms[i, M_REJECT_TIME] += dt
        if ms[i, M_REJECT_TIME] > p[MAG_NEW_TIME] and ms[i, M_CAND_TIME] > p[MAG_NEW_TIME]:
            ms[i, M_REF_NORM], ms[i, M_REF_DIP] = ms[i, M_CAND_NORM], ms[i, M_CAND_DIP]
            ms[i, M_REJECT_TIME] = 0.0
            disturbed = False
    else:
        ms[i, M_REJECT_TIME] = 0.0
        kr = dt / MAG_REF_TAU_S
        ms[i, M_REF_NORM] += kr * (mn - ms[i, M_REF_NORM])
        ms[i, M_REF_DIP] += kr * (dip - ms[i, M_REF_DIP])
    mag_dist[i] = disturbed
    hz = 0.0 if disturbed or mh == 0.0 else -psi * trust
    # 4. correction towards the pseudo-measurement, ℓ carried along
    ci, ch = p[K_INCL] * dt, p[K_HEAD] * dt
    cx, cy, cz = ci * tx, ci * ty, ch * hz
    c0, c1, c2, c3 = _exp(cx, cy, cz)
    q0, q1, q2, q3 = _mul(c0, c1, c2, c3, q0, q1, q2, q3)
    n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    if q0 < 0.0:
        n = -n
    q[i, 0], q[i, 1], q[i, 2], q[i, 3] = q0 / n, q1 / n, q2 / n, q3 / n
    lp[i, 0], lp[i, 1], lp[i, 2] = _rotate(cx, cy, cz, lx, ly, lz)
    # 5. gyro bias: at rest it is what the gyro reads; in motion the observer's integral
    clip = p[BIAS_CLIP]
    rx, ry, rz = g[0] - bias[i, 0], g[1] - bias[i, 1], g[2] - bias[i, 2]
    fn = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
    still = (p[REST_TAU] > 0.0 and math.sqrt(rx * rx + ry * ry + rz * rz) < p[REST_GYR]
             and abs(fn - G_MS2) < p[REST_ACC])
    rest[i] = rest[i] + dt if still else 0.0
    if still and rest[i] >= p[REST_TIME]:
        # at rest the gyro reads its bias: the mean of REST_BLOCK_S blocks of still samples,
        # each taken only once the next block is still too (a motion's first samples are
        # slow, and under the rate threshold), over at most the last rest_tau seconds
        for j in range(3):
            rest_b[i, j] += g[j]
        rest_b[i, 3] += 1.0
        if rest_b[i, 3] * dt >= REST_BLOCK_S - 0.5 * dt:
            nb = rest_b[i, 7]
            if nb > 0.0:
                rest_b[i, 8] = min(rest_b[i, 8] + nb, p[REST_TAU] / dt)
                kr = nb / rest_b[i, 8]
                for j in range(3):
                    v = bias[i, j] + kr * (rest_b[i, 4 + j] / nb - bias[i, j])
                    bias[i, j] = min(clip, max(-clip, v))
            for j in range(4):
                rest_b[i, 4 + j] = rest_b[i, j]
                rest_b[i, j] = 0.0
    else:
        if not still:
            for j in range(8):
                rest_b[i, j] = 0.0
        kb = p[K_BIAS] * dt
        if kb > 0.0 and tx * tx + ty * ty + hz * hz < BIAS_MAX_ERR * BIAS_MAX_ERR:
            for j in range(3):
                e_b = R[i, 0, j] * tx + R[i, 1, j] * ty + R[i, 2, j] * hz
                v = bias[i, j] - kb * e_b
                bias[i, j] = min(clip, max(-clip, v))
    _dcm(q[i, 0], q[i, 1], q[i, 2], q[i, 3], R, i)


@njit(cache=True)
def _frame(f, m, g, err, use_err, reset, use_reset, p, q, bias, lp, acc_est, mag_state,
           mag_dist, gprev, rest, rest_b, trust, use_trust, initialised, held, held_count, R):
    for i in range(f.shape[0]):
        if use_reset and reset[i]:
            initialised[i] = False
        valid = True
        for s in range(3):
            if use_err and err[i, s]:
                valid = False
            else:
                src = f if s == 0 else (m if s == 1 else g)
                for k in range(3):
                    held[i, s, k] = src[i, k]
        if not initialised[i]:
            if valid:
                _init_imu(i, held[i, 0], held[i, 1], q, bias, lp, acc_est, mag_state)
                _dcm(q[i, 0], q[i, 1], q[i, 2], q[i, 3], R, i)
                for k in range(3):
                    gprev[i, k] = held[i, 2, k]
                rest[i] = 0.0
                for k in range(9):
                    rest_b[i, k] = 0.0
                mag_dist[i] = False
                initialised[i] = True
            continue
        if use_err:
            for s in range(3):
                if err[i, s]:
                    held_count[i, s] += 1
        _step_imu(i, held[i, 0], held[i, 1], held[i, 2], p, q, bias, lp, acc_est, mag_state,
                  mag_dist, gprev, rest, rest_b, trust[i] if use_trust else 1.0, R)


@njit(cache=True, nogil=True)
def run_batch(f, m, g, errors, resets, trust, params, q, bias, lp, acc_est, mag_state,
              mag_dist, gprev, rest, rest_b, initialised, held, held_count, R, out_R,
              out_q, out_bias, out_acc, out_mag_dist):
    """Filter N samples × n IMUs, updating the state arrays in place.

    f (m/s²), m (any unit), g (rad/s): float64 ``[N, n, 3]``; errors bool ``[N, n, 3]`` or
    ``[0, n, 3]``; resets bool ``[N, n]`` or ``[0, n]``; trust float ``[N, n]`` (heading trust
    0–1) or ``[0, n]`` (1 everywhere); params ``[N_PARAMS]``. Outputs
    (NaN while an IMU is not initialised): out_R ``[N, n, 3, 3]`` body → NED (its Euler
    angles: :func:`bpms.filter.rotations.dcm_to_euler`); optional (``[0, …]`` to skip, each
    on its own): out_q ``[N, n, 4]``, out_bias ``[N, n, 3]`` rad/s, out_acc ``[N, n, 3]``
    body acceleration m/s² (NED), out_mag_dist ``[N, n]`` bool (heading correction skipped
    on that sample).
    """
    use_err = errors.shape[0] > 0
    use_reset = resets.shape[0] > 0
    use_trust = trust.shape[0] > 0
    no_err = np.zeros((f.shape[1], 3), dtype=np.bool_)
    no_reset = np.zeros(f.shape[1], dtype=np.bool_)
    no_trust = np.ones(f.shape[1])
    nan = np.nan
    for k in range(f.shape[0]):
        e = errors[k] if use_err else no_err
        z = resets[k] if use_reset else no_reset
        w = trust[k] if use_trust else no_trust
        _frame(f[k], m[k], g[k], e, use_err, z, use_reset, params, q, bias, lp, acc_est,
               mag_state, mag_dist, gprev, rest, rest_b, w, use_trust, initialised, held,
               held_count, R)
        for i in range(f.shape[1]):
            ok = initialised[i]
            for r in range(3):
                for c in range(3):
                    out_R[k, i, r, c] = R[i, r, c] if ok else nan
            if out_q.shape[0] > 0:
                for r in range(4):
                    out_q[k, i, r] = q[i, r] if ok else nan
            if out_bias.shape[0] > 0:
                for r in range(3):
                    out_bias[k, i, r] = bias[i, r] if ok else nan
            if out_acc.shape[0] > 0:
                for r in range(3):
                    out_acc[k, i, r] = acc_est[i, r] if ok else nan
            if out_mag_dist.shape[0] > 0:
                out_mag_dist[k, i] = ok and mag_dist[i]


@dataclass
class ObserverGains:
    """Observer settings (units as :class:`bpms.io.options.FilterOptions`). The defaults are
    the ``observer``; :data:`ADAPTIVE` gives the ``adaptive`` setting's defaults (the
    parameters chosen on the 7 BROAD trials, docs/filters.md)."""

    k_incl: float = 0.5          # 1/s, inclination correction
    k_head: float = 0.2          # 1/s, heading correction
    k_bias: float = 0.01         # 1/s², bias integral in motion
    tau_acc: float = 1.5         # s, gravity low-pass
    dt: float = 0.02             # s
    mag_norm_th: float = 0.05    # fraction of the reference field norm
    mag_dip_th_deg: float = 5.0  # degrees of dip change
    mag_new_time_s: float = 10.0  # s before a steady new field is accepted
    bias_clip: float = math.radians(5.0)  # rad/s
    rest_gyr: float = math.radians(2.0)  # rad/s
    rest_acc: float = 0.3        # m/s²
    rest_time: float = 1.0       # s
    rest_tau: float = 0.0        # s, longest memory of the bias at rest (0 = off, the observer)
    trapezoid: bool = False      # trapezoidal rate integration with coning correction

    def params(self) -> np.ndarray:
        return np.array([self.k_incl, self.k_head, self.k_bias, self.tau_acc, self.dt,
                         self.mag_norm_th, math.radians(self.mag_dip_th_deg),
                         self.mag_new_time_s, self.bias_clip, self.rest_gyr,
                         self.rest_acc, self.rest_time, self.rest_tau,
                         1.0 if self.trapezoid else 0.0], dtype=np.float64)


#: The ``adaptive`` setting's defaults (what differs from the observer's).
ADAPTIVE = {"mag_norm_th": 0.03, "mag_dip_th_deg": 3.0, "rest_tau": 10.0, "trapezoid": True}


class ObserverState(KernelState):
    """The state of ``n`` IMUs (arrays updated in place by the kernel).

    q ``[n, 4]`` body → NED (w, x, y, z); bias ``[n, 3]`` rad/s; lp ``[n, 3]`` low-passed
    gravity in the earth frame, m/s²; acc_est ``[n, 3]`` estimated linear acceleration (earth
    frame, NED, m/s²); mag_state ``[n, 6]`` reference / candidate field norm and dip (rad),
    candidate and rejection times (s); mag_dist ``[n]`` the last sample was rejected;
    gprev ``[n, 3]`` the previous gyro sample (rad/s); rest ``[n]`` time (s) the sensor has
    been still; rest_b ``[n, 9]`` the bias at rest: sums of the block being filled (x, y, z,
    samples), of the block waiting for the next one, the samples averaged so far;
    initialised ``[n]``; held ``[n, 3 sensors, 3]`` last good inputs;
    held_count ``[n, 3]``; R ``[n, 3, 3]`` the DCM of q.
    """

    LAYOUT = (("q", (4,), np.float64, (1.0, 0.0, 0.0, 0.0)), ("bias", (3,), np.float64, 0.0),
              ("lp", (3,), np.float64, 0.0), ("acc_est", (3,), np.float64, 0.0),
              ("mag_state", (6,), np.float64, 0.0), ("mag_dist", (), np.bool_, False),
              ("gprev", (3,), np.float64, 0.0), ("rest", (), np.float64, 0.0),
              ("rest_b", (9,), np.float64, 0.0), ("initialised", (), np.bool_, False),
              ("held", (3, 3), np.float64, 0.0), ("held_count", (3,), np.int64, 0),
              ("R", (3, 3), np.float64, np.eye(3)))

    def set_attitude(self, imu: int, q: np.ndarray) -> None:
        """Force IMU ``imu``'s attitude (body → NED quaternion); it must be initialised.
        Used to start from an arbitrary attitude (tests)."""
        q = np.asarray(q, dtype=np.float64)
        self.q[imu] = q / np.linalg.norm(q)
        self.lp[imu] = 0.0
        self.lp[imu, 2] = G_MS2


@dataclass
class ObserverOutput:
    """R ``[N, n, 3, 3]`` body → NED; when asked for: q ``[N, n, 4]``, bias ``[N, n, 3]``
    rad/s, acc ``[N, n, 3]`` body acceleration (NED, m/s²)."""

    R: np.ndarray
    q: np.ndarray | None = None
    bias: np.ndarray | None = None
    acc: np.ndarray | None = None

    @property
    def euler(self) -> np.ndarray:
        """Roll, pitch, yaw ``[N, n, 3]`` rad of :attr:`R`, computed on each read."""
        return dcm_to_euler(self.R)


class Observer:
    """``n`` observers on physical units (the BROAD bench and tests use it directly; the suit
    goes through :class:`bpms.filter.algorithms.ObserverBank`)."""

    def __init__(self, n: int = N_IMUS, gains: ObserverGains | None = None) -> None:
        self.n = n
        self.gains = gains or ObserverGains()
        self.state = ObserverState(n)

    def process(self, f: np.ndarray, m: np.ndarray, g: np.ndarray,
                errors: np.ndarray | None = None, resets: np.ndarray | None = None,
                keep: tuple[str, ...] = (), trust: np.ndarray | None = None) -> ObserverOutput:
        """Filter ``[N, n, 3]`` inputs (units: module docstring), continuing the state;
        ``keep`` names the optional outputs to fill (any of ``"q"``, ``"bias"``, ``"acc"``;
        the others stay None and cost nothing); ``trust`` ``[N, n]`` the heading trust
        (module docstring; None: 1)."""
        f, m, g = (np.ascontiguousarray(v, dtype=np.float64) for v in (f, m, g))
        N = f.shape[0]
        err = (np.zeros((0, self.n, 3), np.bool_) if errors is None
               else np.ascontiguousarray(errors, dtype=np.bool_))
        rs = (np.zeros((0, self.n), np.bool_) if resets is None
              else np.ascontiguousarray(resets, dtype=np.bool_))
        unknown = set(keep) - {"q", "bias", "acc"}
        if unknown:
            raise ValueError(f"Observer.process cannot keep {sorted(unknown)}")
        out = ObserverOutput(np.empty((N, self.n, 3, 3)),
                             *(np.empty((N if name in keep else 0, self.n, width))
                               for name, width in (("q", 4), ("bias", 3), ("acc", 3))))
        tr = (np.ones((0, self.n)) if trust is None
              else np.ascontiguousarray(trust, dtype=np.float64))
        run_batch(f, m, g, err, rs, tr, self.gains.params(), *self.state.arrays(), out.R,
                  out.q, out.bias, out.acc, np.empty((0, self.n), np.bool_))
        for name in {"q", "bias", "acc"} - set(keep):
            setattr(out, name, None)
        return out


__all__ = ["ADAPTIVE", "N_PARAMS", "REST_BLOCK_S", "Observer", "ObserverGains", "ObserverOutput",
           "ObserverState", "run_batch"]
