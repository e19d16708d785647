"""The DCM Mahony complementary filter (docs/filter.md, Razor AHRS lineage) for 18 IMUs at once.

One numba kernel, :func:`run_batch`, filters N frames × 18 IMUs in one call, with no Python
per frame and no heap allocation per IMU update; a live frame is N = 1 (the same code). The
kernels here call only kernels of this module, so numba's on-disk cache (``cache=True``,
keyed by this file) never holds stale machine code.

Inputs are the calibrated, pre-rotated filter-frame vectors of
:meth:`bpms.filter.calibration.SensorCalibration.calibrate`: accelerometer in "Gravity counts"
pointing down (|a| ≈ Gravity ≈ 256–270 at rest), magnetometer ±100, gyroscope rad/s. The
DCM ``R`` maps the filter frame to world north-east-down; Euler angles (roll, pitch, yaw) in
radians as :mod:`bpms.filter.rotations`.

Per frame and IMU (all docs/filter.md):

- an IMU that is not initialised (first frame of a stream, or after a reset) is initialised
  from the frame ("Reset_Mahony": ωI = ωP = 0, roll/pitch from the accelerometer, yaw from the
  tilt-compensated magnetometer heading); no filter step runs on that frame;
- otherwise one step: heading with the previous roll/pitch, matrix update with the previous
  ωI + ωP, renormalisation, drift correction. The Euler angles are not part of the loop: they
  come from the final DCMs (:func:`bpms.filter.rotations.dcm_to_euler`, the one place every
  filter's Euler angles come from, called for a whole Result when they are first read).

Failed sensors (error bits of the frame, ``errors[..., imu, sensor]``, sensor 0 accel, 1 mag,
2 gyro): the filter *holds* that sensor's last good calibrated value and runs its step with it;
every step that used a held value is counted in ``held_count[imu, sensor]``. Initialisation
needs a frame in which all three sensors of the IMU are good (a "valid" frame), so an IMU that
never had a good value stays uninitialised. Outputs of an uninitialised IMU are NaN.

Gains and dt are ``params = [kp_rollpitch, ki_rollpitch, kp_yaw, ki_yaw, dt]``; the batch path
takes ``params[1, 5]`` (constant) or ``params[N, 5]`` (per frame) so they can change between
frames. ``R[2][0]`` is clamped to [-1, 1] for the next heading's pitch (rounding can push it
past 1 by 1e-16).

Speed: the step needs no ``atan2`` or ``asin`` at all. The sines and cosines of the previous
roll and pitch (step 1) are taken algebraically from the DCM (``cos φ = R22/√(R21²+R22²)``,
``sin θ = -R20``, ...) and ``sin H``, ``cos H`` from ``(-my, mx)/√(mx²+my²)`` instead of
``sin(atan2(..))``: the same numbers up to ~1e-16.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bpms.filter.kernel_state import KernelState

#: Indices into ``params``.
KP_RP, KI_RP, KP_YAW, KI_YAW, DT = range(5)
N_PARAMS = 5


@njit(cache=True)
def _heading(m0: float, m1: float, m2: float, roll: float, pitch: float) -> float:
    """docs/filter.md step 1: tilt-compensated magnetic heading H, rad."""
    cr = math.cos(roll)
    sr = math.sin(roll)
    cp = math.cos(pitch)
    sp = math.sin(pitch)
    mx = m0 * cp + m1 * sr * sp + m2 * cr * sp
    my = m1 * cr - m2 * sr
    return math.atan2(-my, mx)


@njit(cache=True)
def _init_imu(i, a, m, R, w_i, w_p, trig):
    """"Reset_Mahony" of IMU ``i`` from accel ``a[3]`` and mag ``m[3]``."""
    for k in range(3):
        w_i[i, k] = 0.0
        w_p[i, k] = 0.0
    a0, a1, a2 = a[0], a[1], a[2]
    pitch = -math.atan2(a0, math.sqrt(a1 * a1 + a2 * a2))
    # t1 = a × x̂ = (0, a2, -a1); t2 = x̂ × t1 = (0, a1, a2)
    roll = math.atan2(a1, a2)
    yaw = _heading(m[0], m[1], m[2], roll, pitch)
    c1, s1 = math.cos(roll), math.sin(roll)
    c2, s2 = math.cos(pitch), math.sin(pitch)
    c3, s3 = math.cos(yaw), math.sin(yaw)
    R[i, 0, 0] = c2 * c3
    R[i, 0, 1] = c3 * s1 * s2 - c1 * s3
    R[i, 0, 2] = s1 * s3 + c1 * c3 * s2
    R[i, 1, 0] = c2 * s3
    R[i, 1, 1] = c1 * c3 + s1 * s2 * s3
    R[i, 1, 2] = c1 * s2 * s3 - c3 * s1
    R[i, 2, 0] = -s2
    R[i, 2, 1] = c2 * s1
    R[i, 2, 2] = c1 * c2
    trig[i, 0], trig[i, 1], trig[i, 2], trig[i, 3] = c1, s1, c2, s2


@njit(cache=True)
def _step_imu(i, a, m, g, gravity, kp_rp, ki_rp, kp_y, ki_y, dt, R, w_i, w_p, trig):
    """One filter step (docs/filter.md steps 1–5) of IMU ``i``; scalars only, no allocation."""
    # 1. heading with the previous roll and pitch; their sines and cosines were cached by the
    # previous step (or the initialisation), and sin H, cos H come without atan2.
    cr, sr, cp, sp = trig[i, 0], trig[i, 1], trig[i, 2], trig[i, 3]
    mx = m[0] * cp + m[1] * sr * sp + m[2] * cr * sp
    my = m[1] * cr - m[2] * sr
    rm = math.sqrt(mx * mx + my * my)
    if rm > 0.0:
        sin_h, cos_h = -my / rm, mx / rm
    else:  # atan2(0, 0) = 0
        sin_h, cos_h = 0.0, 1.0
    # 2. R ← R + R·(dt·skew(ω)), ω = g + ωI + ωP
    ux = dt * ((g[0] + w_i[i, 0]) + w_p[i, 0])
    uy = dt * ((g[1] + w_i[i, 1]) + w_p[i, 1])
    uz = dt * ((g[2] + w_i[i, 2]) + w_p[i, 2])
    r00, r01, r02 = R[i, 0, 0], R[i, 0, 1], R[i, 0, 2]
    r10, r11, r12 = R[i, 1, 0], R[i, 1, 1], R[i, 1, 2]
    r20, r21, r22 = R[i, 2, 0], R[i, 2, 1], R[i, 2, 2]
    x0 = r00 + (r01 * uz - r02 * uy)
    x1 = r01 + (r02 * ux - r00 * uz)
    x2 = r02 + (r00 * uy - r01 * ux)
    y0 = r10 + (r11 * uz - r12 * uy)
    y1 = r11 + (r12 * ux - r10 * uz)
    y2 = r12 + (r10 * uy - r11 * ux)
    # (row 2 of the update is not needed: renormalisation rebuilds it as X × Y)
    # 3. renormalise
    e = x0 * y0 + x1 * y1 + x2 * y2
    h = e / 2.0
    xo0, xo1, xo2 = x0 - h * y0, x1 - h * y1, x2 - h * y2
    yo0, yo1, yo2 = y0 - h * x0, y1 - h * x1, y2 - h * x2
    zo0 = xo1 * yo2 - xo2 * yo1
    zo1 = xo2 * yo0 - xo0 * yo2
    zo2 = xo0 * yo1 - xo1 * yo0
    s = 0.5 * (3.0 - (xo0 * xo0 + xo1 * xo1 + xo2 * xo2))
    r00, r01, r02 = s * xo0, s * xo1, s * xo2
    s = 0.5 * (3.0 - (yo0 * yo0 + yo1 * yo1 + yo2 * yo2))
    r10, r11, r12 = s * yo0, s * yo1, s * yo2
    s = 0.5 * (3.0 - (zo0 * zo0 + zo1 * zo1 + zo2 * zo2))
    r20, r21, r22 = s * zo0, s * zo1, s * zo2
    R[i, 0, 0], R[i, 0, 1], R[i, 0, 2] = r00, r01, r02
    R[i, 1, 0], R[i, 1, 1], R[i, 1, 2] = r10, r11, r12
    R[i, 2, 0], R[i, 2, 1], R[i, 2, 2] = r20, r21, r22
    # 4. drift correction
    a0, a1, a2 = a[0], a[1], a[2]
    w = 1.0 - 2.0 * abs(1.0 - math.sqrt(a0 * a0 + a1 * a1 + a2 * a2) / gravity)
    w = min(max(w, 0.0), 1.0)
    e0 = a1 * r22 - a2 * r21  # eRP = a × R[2]
    e1 = a2 * r20 - a0 * r22
    e2 = a0 * r21 - a1 * r20
    kp = kp_rp * w
    ki = ki_rp * w
    c = r00 * sin_h - r10 * cos_h  # eCourse
    ey0, ey1, ey2 = r20 * c, r21 * c, r22 * c  # eYaw = R[2]·eCourse
    w_p[i, 0] = kp * e0 + kp_y * ey0
    w_p[i, 1] = kp * e1 + kp_y * ey1
    w_p[i, 2] = kp * e2 + kp_y * ey2
    w_i[i, 0] = (w_i[i, 0] + ki * e0) + ki_y * ey0
    w_i[i, 1] = (w_i[i, 1] + ki * e1) + ki_y * ey1
    w_i[i, 2] = (w_i[i, 2] + ki * e2) + ki_y * ey2
    # 5. the sines/cosines of roll and pitch for the next heading (the Euler angles
    # themselves come from the DCM outside the loop, bpms.filter.rotations.dcm_to_euler):
    # roll = atan2(r21, r22) → cos = r22/h, sin = r21/h; pitch = -asin(r20) → sin = -r20.
    s20 = min(max(r20, -1.0), 1.0)
    hr = math.sqrt(r21 * r21 + r22 * r22)
    if hr > 0.0:
        trig[i, 0], trig[i, 1] = r22 / hr, r21 / hr
    else:
        trig[i, 0], trig[i, 1] = 1.0, 0.0
    trig[i, 2], trig[i, 3] = math.sqrt(1.0 - s20 * s20), -s20


@njit(cache=True)
def _frame(acc, mag, gyr, err, use_err, reset, use_reset, params, gravity,
           R, w_i, w_p, trig, initialised, held, held_count):
    """One frame for all IMUs: reset flags, failed-sensor hold, initialise or step."""
    kp_rp, ki_rp = params[KP_RP], params[KI_RP]
    kp_y, ki_y, dt = params[KP_YAW], params[KI_YAW], params[DT]
    for i in range(acc.shape[0]):
        if use_reset and reset[i]:
            initialised[i] = False
        valid = True
        for s in range(3):
            if use_err and err[i, s]:
                valid = False
            else:
                src = acc if s == 0 else (mag if s == 1 else gyr)
                for k in range(3):
                    held[i, s, k] = src[i, k]
        if not initialised[i]:
            if valid:
                _init_imu(i, held[i, 0], held[i, 1], R, w_i, w_p, trig)
                initialised[i] = True
            continue
        if use_err:
            for s in range(3):
                if err[i, s]:
                    held_count[i, s] += 1
        _step_imu(i, held[i, 0], held[i, 1], held[i, 2], gravity[i], kp_rp, ki_rp, kp_y, ki_y,
                  dt, R, w_i, w_p, trig)


@njit(cache=True)
def _store(k, R, w_i, w_p, initialised, out_R, out_wi, out_wp, store_terms):
    nan = np.nan
    for i in range(R.shape[0]):
        ok = initialised[i]
        for r in range(3):
            for c in range(3):
                out_R[k, i, r, c] = R[i, r, c] if ok else nan
            if store_terms:
                out_wi[k, i, r] = w_i[i, r] if ok else nan
                out_wp[k, i, r] = w_p[i, r] if ok else nan


@njit(cache=True, nogil=True)
def run_batch(acc, mag, gyr, errors, resets, params, gravity,
              R, w_i, w_p, trig, initialised, held, held_count, out_R, out_wi, out_wp):
    """Filter N frames × 18 IMUs, updating the state arrays in place.

    acc, mag, gyr: float64 ``[N, 18, 3]`` filter inputs. errors: bool ``[N, 18, 3]`` or
    ``[0, 18, 3]`` (no error flags). resets: bool ``[N, 18]`` (re-initialise that IMU from
    frame k on) or ``[0, 18]``. params: ``[1, 5]`` or ``[N, 5]``. gravity: ``[18]`` counts/g.
    out_R ``[N, 18, 3, 3]`` (NaN while an IMU is not initialised); out_wi, out_wp ``[N, 18, 3]`` or
    ``[0, 18, 3]`` to skip storing ωI, ωP.
    """
    n = acc.shape[0]
    use_err = errors.shape[0] > 0
    use_reset = resets.shape[0] > 0
    store_terms = out_wi.shape[0] > 0
    per_frame = params.shape[0] > 1
    no_err = np.zeros((acc.shape[1], 3), dtype=np.bool_)
    no_reset = np.zeros(acc.shape[1], dtype=np.bool_)
    for k in range(n):
        p = params[k] if per_frame else params[0]
        e = errors[k] if use_err else no_err
        z = resets[k] if use_reset else no_reset
        _frame(acc[k], mag[k], gyr[k], e, use_err, z, use_reset, p, gravity,
               R, w_i, w_p, trig, initialised, held, held_count)
        _store(k, R, w_i, w_p, initialised, out_R, out_wi, out_wp, store_terms)


class MahonyState(KernelState):
    """The filter state of ``n`` IMUs (arrays updated in place by the kernels).

    R ``[n, 3, 3]`` DCM filter frame → NED; w_i, w_p ``[n, 3]`` rad/s; trig ``[n, 4]`` cos,
    sin of the roll and pitch of R;
    initialised ``[n]``; held ``[n, 3 sensors, 3]`` the last good
    calibrated value of each sensor; held_count ``[n, 3]`` steps that used a held value.
    """

    LAYOUT = (("R", (3, 3), np.float64, np.eye(3)), ("w_i", (3,), np.float64, 0.0),
              ("w_p", (3,), np.float64, 0.0), ("trig", (4,), np.float64, 0.0),
              ("initialised", (), np.bool_, False),
              ("held", (3, 3), np.float64, 0.0), ("held_count", (3,), np.int64, 0))
