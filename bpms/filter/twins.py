"""numpy twins of the filter kernels: the same numbers, bit for bit, without numba.

Each function here takes exactly the arguments of the kernel it twins and writes the same
outputs in place (:mod:`bpms.filter.kernels` says when a twin runs). A twin repeats its
kernel's arithmetic operation for operation and in the same order, vectorised over IMUs (the
recursive filters, one frame at a time) or over frames (the stateless kernels). IEEE
arithmetic and ``sqrt`` are correctly rounded either way; the transcendental functions
(``atan2``, ``asin``, ``cos``, ``sin``, ``exp``) go through :mod:`math`, the C library that
numba's kernels call as well, never numpy's own vectorised versions, which may differ in the
last bit. tests/test_kernels.py compares every twin with its kernel bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bpms.filter.disturbance import (
    S_ACC_LP,
    S_DIP_LP,
    S_LEARN_T,
    S_MAG_FLAG,
    S_NORM_LP,
    S_READY,
    S_REF_DIP,
    S_REF_NORM,
    S_REST_T,
)
from bpms.filter.mahony import DT, KI_RP, KI_YAW, KP_RP, KP_YAW


def _each(fn: Callable[..., float], *arrays: np.ndarray) -> np.ndarray:
    """``fn`` of :mod:`math` elementwise (the kernels' C library, not numpy's SIMD code)."""
    return np.array(list(map(fn, *(a.tolist() for a in arrays))), dtype=np.float64)


# -- calibration and Reset Zero (stateless: vectorised over frames) ---------------------------
def calibrate_batch(raw, acc_off, acc_gain, mag_off, mag_gain, gyr_off, gyr_gain, rot,
                    out_acc, out_mag, out_gyr) -> None:
    """Twin of :func:`bpms.filter.mahony.calibrate_batch`."""
    for s, (off, gain, out) in enumerate(((acc_off, acc_gain, out_acc),
                                          (mag_off, mag_gain, out_mag),
                                          (gyr_off, gyr_gain, out_gyr))):
        v = [(raw[..., 3 * s + j] - off[:, j]) * gain[:, j] for j in range(3)]
        for r in range(3):
            out[..., r] = (rot[:, r, 0] * v[0] + rot[:, r, 1] * v[1]) + rot[:, r, 2] * v[2]


def right_multiply(R, M, out) -> None:
    """Twin of :func:`bpms.filter.mahony.right_multiply`."""
    for r in range(3):
        a0, a1, a2 = R[..., r, 0], R[..., r, 1], R[..., r, 2]
        for c in range(3):
            out[..., r, c] = (a0 * M[:, 0, c] + a1 * M[:, 1, c]) + a2 * M[:, 2, c]


# -- the Mahony filter (recursive: one frame at a time, vectorised over IMUs) -----------------
def _heading(m0, m1, m2, roll, pitch) -> np.ndarray:
    cr = _each(math.cos, roll)
    sr = _each(math.sin, roll)
    cp = _each(math.cos, pitch)
    sp = _each(math.sin, pitch)
    mx = m0 * cp + m1 * sr * sp + m2 * cr * sp
    my = m1 * cr - m2 * sr
    return _each(math.atan2, -my, mx)


def _init_imus(idx, R, w_i, w_p, euler, trig, held) -> None:
    """"Reset_Mahony" of the IMUs ``idx`` from their held accel and mag."""
    w_i[idx] = 0.0
    w_p[idx] = 0.0
    a = held[idx, 0]
    m = held[idx, 1]
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    pitch = -_each(math.atan2, a0, np.sqrt(a1 * a1 + a2 * a2))
    roll = _each(math.atan2, a1, a2)
    yaw = _heading(m[:, 0], m[:, 1], m[:, 2], roll, pitch)
    c1, s1 = _each(math.cos, roll), _each(math.sin, roll)
    c2, s2 = _each(math.cos, pitch), _each(math.sin, pitch)
    c3, s3 = _each(math.cos, yaw), _each(math.sin, yaw)
    Ri = np.empty((len(a), 3, 3))
    Ri[:, 0, 0] = c2 * c3
    Ri[:, 0, 1] = c3 * s1 * s2 - c1 * s3
    Ri[:, 0, 2] = s1 * s3 + c1 * c3 * s2
    Ri[:, 1, 0] = c2 * s3
    Ri[:, 1, 1] = c1 * c3 + s1 * s2 * s3
    Ri[:, 1, 2] = c1 * s2 * s3 - c3 * s1
    Ri[:, 2, 0] = -s2
    Ri[:, 2, 1] = c2 * s1
    Ri[:, 2, 2] = c1 * c2
    R[idx] = Ri
    euler[idx] = np.stack([roll, pitch, yaw], axis=-1)
    trig[idx] = np.stack([c1, s1, c2, s2], axis=-1)


#: Index orders of a cross product ``p × q = p[_P1]·q[_P2] − p[_P2]·q[_P1]`` (componentwise
#: the kernels' ``p1·q2 − p2·q1``, ``p2·q0 − p0·q2``, ``p0·q1 − p1·q0``).
_P1 = np.array([1, 2, 0])
_P2 = np.array([2, 0, 1])


def _sum3(v: np.ndarray) -> np.ndarray:
    """``v0 + v1 + v2`` over the last axis, left to right as the kernels add."""
    return (v[..., 0] + v[..., 1]) + v[..., 2]


def _step_imus(sel, p, gravity, R, w_i, w_p, euler, trig, held) -> None:
    """One filter step of the IMUs ``sel`` (docs/filter.md steps 1–5), the kernel's
    operations with its three axes (and the DCM's first two rows) side by side."""
    kp_rp, ki_rp, kp_y, ki_y, dt = p[KP_RP], p[KI_RP], p[KP_YAW], p[KI_YAW], p[DT]
    a, m, g = held[sel, 0], held[sel, 1], held[sel, 2]
    wi = w_i[sel]
    t = trig[sel]
    cr, sr, cp, sp = t[:, 0], t[:, 1], t[:, 2], t[:, 3]
    # 1. heading
    mx = m[:, 0] * cp + m[:, 1] * sr * sp + m[:, 2] * cr * sp
    my = m[:, 1] * cr - m[:, 2] * sr
    rm = np.sqrt(mx * mx + my * my)
    some = rm > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        sin_h = np.where(some, -my / rm, 0.0)
        cos_h = np.where(some, mx / rm, 1.0)
    # 2. R ← R + R·(dt·skew(ω)): rows 0 and 1 (row 2 is rebuilt by the renormalisation)
    u = (dt * ((g + wi) + w_p[sel]))[:, None, :]
    rows = R[sel][:, :2, :]
    xy = rows + (rows[..., _P1] * u[..., _P2] - rows[..., _P2] * u[..., _P1])
    x, y = xy[:, 0], xy[:, 1]
    # 3. renormalise
    h = (_sum3(x * y) / 2.0)[:, None]
    xo = x - h * y
    yo = y - h * x
    zo = xo[:, _P1] * yo[:, _P2] - xo[:, _P2] * yo[:, _P1]
    o = np.stack([xo, yo, zo], axis=1)
    Rn = (0.5 * (3.0 - _sum3(o * o)))[..., None] * o
    R[sel] = Rn
    # 4. drift correction
    w = 1.0 - 2.0 * np.abs(1.0 - np.sqrt(_sum3(a * a)) / gravity[sel])
    w = np.minimum(np.maximum(w, 0.0), 1.0)
    r2 = Rn[:, 2]
    e = a[:, _P1] * r2[:, _P2] - a[:, _P2] * r2[:, _P1]  # a × R[2]
    c = Rn[:, 0, 0] * sin_h - Rn[:, 1, 0] * cos_h  # eCourse
    ey = r2 * c[:, None]
    w_p[sel] = (kp_rp * w)[:, None] * e + kp_y * ey
    w_i[sel] = (wi + (ki_rp * w)[:, None] * e) + ki_y * ey
    # 5. Euler angles, and the sines/cosines of roll and pitch for the next heading
    r20, r21, r22 = r2[:, 0], r2[:, 1], r2[:, 2]
    s20 = np.minimum(np.maximum(r20, -1.0), 1.0)
    euler[sel] = np.stack([_each(math.atan2, r21, r22), -_each(math.asin, s20),
                           _each(math.atan2, Rn[:, 1, 0], Rn[:, 0, 0])], axis=-1)
    hr = np.sqrt(r21 * r21 + r22 * r22)
    some = hr > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        c_roll = np.where(some, r22 / hr, 1.0)
        s_roll = np.where(some, r21 / hr, 0.0)
    trig[sel] = np.stack([c_roll, s_roll, np.sqrt(1.0 - s20 * s20), -s20], axis=-1)


def _frame(acc, mag, gyr, err, reset, p, gravity, R, w_i, w_p, euler, trig, initialised,
           held, seen, held_count) -> None:
    """Twin of ``mahony._frame``; ``err`` / ``reset`` None when the batch has none."""
    if reset is not None:
        initialised[reset] = False
    if err is None:
        held[:, 0] = acc
        held[:, 1] = mag
        held[:, 2] = gyr
        valid = np.ones(len(acc), dtype=np.bool_)
        seen[:] = True
    else:
        good = ~err
        for s, value in enumerate((acc, mag, gyr)):
            np.copyto(held[:, s], value, where=good[:, s, None])
        valid = good.all(axis=1)
        seen |= good
    start = ~initialised & valid
    step = initialised.copy()
    if err is not None:
        held_count += err & step[:, None]
    if start.any():
        _init_imus(np.flatnonzero(start), R, w_i, w_p, euler, trig, held)
    if step.all():
        _step_imus(slice(None), p, gravity, R, w_i, w_p, euler, trig, held)
    elif step.any():
        _step_imus(np.flatnonzero(step), p, gravity, R, w_i, w_p, euler, trig, held)
    initialised |= start


def mahony_run_batch(acc, mag, gyr, errors, resets, params, gravity, R, w_i, w_p, euler,
                     trig, initialised, held, seen, held_count, out_R, out_euler, out_wi,
                     out_wp) -> None:
    """Twin of :func:`bpms.filter.mahony.run_batch`."""
    use_err = errors.shape[0] > 0
    use_reset = resets.shape[0] > 0
    store_terms = out_wi.shape[0] > 0
    per_frame = params.shape[0] > 1
    for k in range(acc.shape[0]):
        _frame(acc[k], mag[k], gyr[k], errors[k] if use_err else None,
               resets[k] if use_reset else None, params[k] if per_frame else params[0],
               gravity, R, w_i, w_p, euler, trig, initialised, held, seen, held_count)
        out_R[k] = R
        out_euler[k] = euler
        if store_terms:
            out_wi[k] = w_i
            out_wp[k] = w_p
        if not initialised.all():
            off = ~initialised
            out_R[k, off] = np.nan
            out_euler[k, off] = np.nan
            if store_terms:
                out_wi[k, off] = np.nan
                out_wp[k, off] = np.nan


def mahony_step_frame(acc, mag, gyr, errors, resets, params, gravity, R, w_i, w_p, euler,
                      trig, initialised, held, seen, held_count, out_R, out_euler, out_wi,
                      out_wp) -> None:
    """Twin of :func:`bpms.filter.mahony.step_frame`."""
    _frame(acc, mag, gyr, errors, resets, params, gravity, R, w_i, w_p, euler, trig,
           initialised, held, seen, held_count)
    off = ~initialised
    for out, value in ((out_R, R), (out_euler, euler), (out_wi, w_i), (out_wp, w_p)):
        out[...] = value
        out[off] = np.nan


# -- the state guard (stateless but for ``seen``: vectorised over frames) ---------------------
def guard_check(R, gyr, c4, expected, tol, bad, seen) -> None:
    """Twin of ``bpms.filter.guard._check``."""
    finite = np.isfinite(R).all(axis=(-1, -2))
    with np.errstate(over="ignore", invalid="ignore"):
        err2 = np.zeros(R.shape[:2])
        for a in range(3):
            for b in range(3):
                g = R[:, :, 0, a] * R[:, :, 0, b] + R[:, :, 1, a] * R[:, :, 1, b] \
                    + R[:, :, 2, a] * R[:, :, 2, b]
                if a == b:
                    g = g - 1.0
                err2 = err2 + g * g
        limit = np.full(R.shape[:2], tol)
        if c4 > 0.0:
            w2 = gyr[..., 0] ** 2 + gyr[..., 1] ** 2 + gyr[..., 2] ** 2
            limit = np.where(np.isfinite(w2), limit + c4 * w2 * w2, limit)
        bad_rotation = ~(err2 <= limit * limit)
    # an IMU is expected from its first finite frame on (or before the batch)
    finite_before = np.zeros_like(finite)
    if len(finite) > 1:
        finite_before[1:] = np.logical_or.accumulate(finite[:-1], axis=0)
    seen_before = expected[None, :] | finite_before
    bad[...] = np.where(finite, bad_rotation, seen_before)
    seen[...] = expected | finite.any(axis=0)


# -- the disturbance indicators (recursive: one frame at a time, vectorised over IMUs) --------
def run_disturbance(acc, mag, gyr, R, gravity, valid, p, state, mag_dist, acc_dist,
                    norm_ratio, dip_dev, acc_mean) -> None:
    """Twin of :func:`bpms.filter.disturbance.run_disturbance`."""
    norm_th, dip_th, dip_rate, tau, acc_th, acc_tau = p[0], p[1], p[2], p[3], p[4], p[5]
    rest_gyr, rest_acc, rest_time, learn_s, dt = p[6], p[7], p[8], p[9], p[10]
    k = 1.0 - math.exp(-dt / tau) if tau > 0.0 else 1.0
    ka = 1.0 - math.exp(-dt / acc_tau) if acc_tau > 0.0 else 1.0
    nan = np.nan
    for t in range(acc.shape[0]):
        v = valid[t]
        held = ~v
        if held.any():
            s = state[held]
            ready = s[:, S_READY] > 0.0
            mag_dist[t, held] = s[:, S_MAG_FLAG] > 0.0
            acc_dist[t, held] = s[:, S_ACC_LP] > acc_th
            acc_mean[t, held] = s[:, S_ACC_LP]
            norm_ratio[t, held] = np.where(ready, s[:, S_NORM_LP] - 1.0, nan)
            dip_dev[t, held] = np.where(ready, s[:, S_DIP_LP] - s[:, S_REF_DIP], nan)
        if not v.any():
            continue
        sel = slice(None) if v.all() else np.flatnonzero(v)
        s = state[sel].copy()
        a = acc[t, sel]
        a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
        grav = gravity[sel]
        an = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2) / grav
        g = gyr[t, sel]
        w = np.sqrt(g[:, 0] ** 2 + g[:, 1] ** 2 + g[:, 2] ** 2)
        s[:, S_ACC_LP] += ka * (np.abs(an - 1.0) - s[:, S_ACC_LP])
        acc_dist[t, sel] = s[:, S_ACC_LP] > acc_th
        acc_mean[t, sel] = s[:, S_ACC_LP]
        m = mag[t, sel]
        m0, m1, m2 = m[:, 0], m[:, 1], m[:, 2]
        mn = np.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
        d = R[t, sel, 2]
        d0, d1, d2 = d[:, 0], d[:, 1], d[:, 2]
        finite = np.isfinite(d0) & np.isfinite(d1) & np.isfinite(d2)
        with np.errstate(divide="ignore", invalid="ignore"):
            if not finite.all():
                dn = an * grav
                some = dn > 0.0
                d0 = np.where(finite, d0, np.where(some, a0 / dn, 0.0))
                d1 = np.where(finite, d1, np.where(some, a1 / dn, 0.0))
                d2 = np.where(finite, d2, np.where(some, a2 / dn, 1.0))
            some = mn > 0.0
            x = np.where(some, (m0 * d0 + m1 * d1 + m2 * d2) / mn, 0.0)
        # ``min(1.0, max(-1.0, x))`` as the kernel evaluates it (a NaN x gives -1.0)
        lo = np.where(x > -1.0, x, -1.0)
        dip = np.where(some, _each(math.asin, np.where(lo < 1.0, lo, 1.0)), 0.0)
        still = (w < rest_gyr) & (np.abs(an - 1.0) < rest_acc)
        s[:, S_REST_T] = np.where(still, s[:, S_REST_T] + dt, 0.0)
        learn = still & (s[:, S_REST_T] >= rest_time) & (s[:, S_LEARN_T] < learn_s) & some
        frozen = ~still & (s[:, S_LEARN_T] > 0.0)
        if learn.any():
            n_prev = s[learn, S_LEARN_T] / dt
            s[learn, S_REF_NORM] = (s[learn, S_REF_NORM] * n_prev + mn[learn]) / (n_prev + 1.0)
            s[learn, S_REF_DIP] = (s[learn, S_REF_DIP] * n_prev + dip[learn]) / (n_prev + 1.0)
            s[learn, S_LEARN_T] += dt
            first = learn & (s[:, S_READY] == 0.0)
            s[first, S_NORM_LP] = 1.0
            s[first, S_DIP_LP] = dip[first]
            s[learn, S_READY] = 1.0
        s[frozen, S_LEARN_T] = learn_s
        ready = s[:, S_READY] != 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            norm_lp = s[:, S_NORM_LP] + k * (mn / s[:, S_REF_NORM] - s[:, S_NORM_LP])
        s[:, S_NORM_LP] = np.where(ready, norm_lp, s[:, S_NORM_LP])
        turn_ok = ready & (w < dip_rate)
        s[:, S_DIP_LP] = np.where(turn_ok, s[:, S_DIP_LP] + k * (dip - s[:, S_DIP_LP]),
                                  s[:, S_DIP_LP])
        flag = ((np.abs(s[:, S_NORM_LP] - 1.0) > norm_th)
                | (np.abs(s[:, S_DIP_LP] - s[:, S_REF_DIP]) > dip_th))
        s[:, S_MAG_FLAG] = np.where(ready, np.where(flag, 1.0, 0.0), s[:, S_MAG_FLAG])
        mag_dist[t, sel] = ready & flag
        norm_ratio[t, sel] = np.where(ready, s[:, S_NORM_LP] - 1.0, nan)
        dip_dev[t, sel] = np.where(ready, s[:, S_DIP_LP] - s[:, S_REF_DIP], nan)
        state[sel] = s


# -- the body's numbers (stateless: vectorised over frames) -----------------------------------
def _quiet(twin: Callable[..., None]) -> Callable[..., None]:
    """Run ``twin`` without numpy's floating-point warnings: a non-finite orientation gives
    NaN silently, as in the compiled kernel."""

    def run(*args: object) -> None:
        with np.errstate(all="ignore"):
            twin(*args)

    run.__doc__ = twin.__doc__
    return run


def _clipped(x: np.ndarray) -> np.ndarray:
    """x clipped to [−1, 1], NaN kept (the kernels' two comparisons)."""
    return np.where(x > 1.0, 1.0, np.where(x < -1.0, -1.0, x))


@_quiet
def segment_euler(C, out) -> None:
    """Twin of :func:`bpms.filter.body_kernels.segment_euler`."""
    shape = C.shape[:-2]
    C = C.reshape(-1, 3, 3)
    out[..., 0] = _each(math.atan2, C[:, 2, 1], C[:, 2, 2]).reshape(shape)
    out[..., 1] = -_each(math.asin, _clipped(C[:, 2, 0])).reshape(shape)
    out[..., 2] = _each(math.atan2, C[:, 1, 0], C[:, 0, 0]).reshape(shape)


@_quiet
def joint_angle_frames(C, hinge, hinge_axes, ball, signs, out) -> None:
    """Twin of :func:`bpms.filter.body_kernels.joint_angle_frames`."""
    n_hinge = len(hinge)
    for j in range(n_hinge):
        P, D = C[:, hinge[j, 0]], C[:, hinge[j, 1]]
        ap, ad = hinge_axes[j, 0], hinge_axes[j, 1]
        u = [(P[:, a, 0] * ap[0] + P[:, a, 1] * ap[1]) + P[:, a, 2] * ap[2] for a in range(3)]
        v = [(D[:, a, 0] * ad[0] + D[:, a, 1] * ad[1]) + D[:, a, 2] * ad[2] for a in range(3)]
        c = ((u[0] * v[0] + u[1] * v[1]) + u[2] * v[2]) / np.sqrt(
            ((u[0] * u[0] + u[1] * u[1]) + u[2] * u[2]) * ((v[0] * v[0] + v[1] * v[1])
                                                           + v[2] * v[2]))
        out[:, j] = _each(math.acos, _clipped(c)) * signs[j]
    for b in range(len(ball)):
        S, D = C[:, ball[b, 0]], C[:, ball[b, 1]]

        def rel(a: int, c: int, S=S, D=D) -> np.ndarray:
            return (S[:, 0, a] * D[:, 0, c] + S[:, 1, a] * D[:, 1, c]) + S[:, 2, a] * D[:, 2, c]

        col = n_hinge + 3 * b
        out[:, col] = _each(math.atan2, rel(2, 1), rel(2, 2)) * signs[col]
        out[:, col + 1] = -_each(math.asin, _clipped(rel(2, 0))) * signs[col + 1]
        out[:, col + 2] = _each(math.atan2, rel(1, 0), rel(0, 0)) * signs[col + 2]


@_quiet
def joint_position_frames(C, imus, parents, vectors, feet, on_ground, out) -> None:
    """Twin of :func:`bpms.filter.body_kernels.joint_position_frames`."""
    out[:, 0] = 0.0
    for p in range(len(imus)):
        R, w = C[:, imus[p]], vectors[p]
        for a in range(3):
            out[:, p + 1, a] = out[:, parents[p], a] + ((R[:, a, 0] * w[0] + R[:, a, 1] * w[1])
                                                        + R[:, a, 2] * w[2])
    if on_ground:
        lowest = out[:, feet, 2].max(axis=1)  # NaN when one foot point is NaN
        out[:, :, 2] = out[:, :, 2] - lowest[:, None]
