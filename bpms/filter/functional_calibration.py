"""Functional pose calibration (docs/pose-calibration.md): sensor-to-segment rotations from
movements, no assumed posture.

From a still window and a short sequence of movements (knee and elbow flexions, an arm
swing, a few steps), per IMU the rotation ``M_i`` (segment axes → the IMU's filter frame) with
``C_i = R_i M_i``:

1. **Hinge axes** of the knees and elbows from the gyroscopes, with the hinge-joint kinematic
   constraint of Seel, Schauer and Raisch (2012) and Seel, Raisch and Schauer (2014): for a
   hinge of axis ``j1`` (proximal sensor's frame) and ``j2`` (distal), ``|ω1 × j1| = |ω2 × j2|``
   at every sample. Started from the principal direction of the relative angular rate
   ``ω2 − R2ᵀR1 ω1`` and refined on the constraint by Gauss-Newton (spherical coordinates).
   The axis is the segments' right axis (Y).
2. **Long axes** from the joint centre, with the same papers' acceleration constraint: the
   joint centre, at ``o1`` from the proximal sensor and ``o2`` from the distal one, has one
   acceleration, so ``|a1 − Γ1(o1)| = |a2 − Γ2(o2)|`` with ``Γ(o) = ω × (ω × o) + ω̇ × o``.
   ``o1`` (perpendicular to the axis) points down the proximal segment, ``−o2`` down the
   distal one (Z). Where the fit fails, the long axis falls back on gravity in the still
   window (which assumes the segment hung straight) and the report says so.
3. Axes' signs from anatomy: the knee bends the shank backward, the elbow the forearm forward.
4. **Vertical** of the pelvis, spine, neck, head and shoulder girdles from gravity in the still
   window; their **heading**, and the body's, from the hips' flexion axis (the knees' hinge
   axes, averaged); the feet: vertical from gravity, heading from the shank's axis; the hands
   follow the forearms.

The result is a Reset Zero (``R0' = Rz(ψ0) Mᵀ``, ψ0) so every door applies it unchanged, and
a :class:`FunctionalReport` with its quality.

References: T. Seel, T. Schauer, J. Raisch, "Joint axis and position estimation from
inertial measurement data by exploiting kinematic constraints", IEEE CCA 2012; T. Seel,
J. Raisch, T. Schauer, "IMU-based joint angle measurement for gait analysis", Sensors 14(4),
6891–6909, 2014.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bpms.filter.calibration import STANDARD_GRAVITY
from bpms.filter.pose import HIP_IMU, average_dcm
from bpms.filter.rotations import rot_z

G = STANDARD_GRAVITY  # m/s² per g
#: (name, proximal IMU, distal IMU, the distal segment's swing sense: +1 forward, -1 back)
HINGES = (("elbow_r", 4, 5, 1.0), ("elbow_l", 10, 11, 1.0),
          ("knee_r", 0, 2, -1.0), ("knee_l", 12, 14, -1.0))
UPRIGHT = (6, 8, 7, 17, 15, 16)  # pelvis, mid spine, neck, head, shoulder girdles
FEET = ((1, 2), (13, 14))  # (foot, shank)
HANDS = ((3, 5), (9, 11))  # (hand, forearm)
#: A hinge needs this many samples turning faster than :data:`MOVING_RAD_S` relative rate.
MIN_MOVING = 50
MOVING_RAD_S = 0.5


@dataclass
class HingeQuality:
    """One hinge: ``moving`` samples used, ``axis_residual_dps`` rms of the relative rate
    off the axis (°/s), ``constraint_residual_dps`` rms of the constraint's residual (°/s),
    ``planarity`` ratio of the second to the first singular value of the relative rate (0: a
    pure hinge), ``centre_residual`` rms of the joint-centre residual (m/s², NaN not fitted),
    ``long_axis`` ``"joint centre"`` or ``"gravity"``, ``centre_m`` |o1|, |o2| (m)."""

    moving: int
    axis_residual_dps: float = float("nan")
    constraint_residual_dps: float = float("nan")
    planarity: float = float("nan")
    centre_residual: float = float("nan")
    long_axis: str = "gravity"
    centre_m: tuple[float, float] = (float("nan"), float("nan"))


@dataclass
class FunctionalReport:
    """Quality of a functional calibration: per hinge, the movements missing, ψ0's source."""

    hinges: dict[str, HingeQuality] = field(default_factory=dict)
    missing: list[str] = field(default_factory=list)
    heading: str = "knee axes"

    def as_dict(self) -> dict:
        """What the ``reset_zero`` event stores (numbers rounded)."""
        def r(v: float) -> float | None:
            return round(float(v), 4) if np.isfinite(v) else None
        return {"heading": self.heading, "missing": list(self.missing),
                "hinges": {name: {"moving": q.moving, "axis_residual_dps": r(q.axis_residual_dps),
                                  "constraint_residual_dps": r(q.constraint_residual_dps),
                                  "planarity": r(q.planarity),
                                  "centre_residual": r(q.centre_residual),
                                  "long_axis": q.long_axis,
                                  "centre_m": [r(v) for v in q.centre_m]}
                           for name, q in self.hinges.items()}}

    def lines(self) -> list[str]:
        """One line per hinge and one for the missing movements, for a terminal."""
        out = [f"{name}: axis off-rate {q.axis_residual_dps:.2f} °/s, constraint residual "
               f"{q.constraint_residual_dps:.2f} °/s over {q.moving} moving samples; long axis "
               f"from {q.long_axis}" for name, q in self.hinges.items()]
        if self.missing:
            out.append("missing movements: " + ", ".join(self.missing))
        return out


def sensor_values(calibration, raw: np.ndarray, errors: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(accelerometer in g, gyroscope rad/s), each ``[N, 18, 3]`` in the filter frame, of raw
    counts ``[N, 18, 9]`` through the processor's ``calibration``
    (:class:`bpms.filter.calibration.SensorCalibration`); NaN where ``errors [N, 18, 3]``
    (accel, mag, gyro) flags a failed reading."""
    acc, _, gyr = calibration.calibrate(raw)
    acc = acc / calibration.gravity[None, :, None]
    if errors is not None:
        errors = np.asarray(errors, dtype=bool)
        acc[errors[..., 0]] = np.nan
        gyr[errors[..., 2]] = np.nan
    return acc, gyr


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _sphere(phi: float, theta: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vector of spherical coordinates and its two derivatives."""
    cp, sp, ct, st = np.cos(phi), np.sin(phi), np.cos(theta), np.sin(theta)
    return (np.array([cp * ct, cp * st, sp]), np.array([-sp * ct, -sp * st, cp]),
            np.array([-cp * st, cp * ct, 0.0]))


def _angles(j: np.ndarray) -> tuple[float, float]:
    return float(np.arcsin(np.clip(j[2], -1, 1))), float(np.arctan2(j[1], j[0]))


def hinge_axes(w1: np.ndarray, w2: np.ndarray, rel: np.ndarray, iterations: int = 20
               ) -> tuple[np.ndarray, np.ndarray, float, float, float]:
    """(j1, j2, axis residual °/s, constraint residual °/s, planarity) of one hinge from the
    two gyroscopes ``w1, w2 [K, 3]`` (rad/s, moving samples) and the relative rotations
    ``rel [K, 3, 3]`` (``R2ᵀ R1``, from the filter) used only to start."""
    wr = w2 - np.einsum("kij,kj->ki", rel, w1)
    _, s, vt = np.linalg.svd(wr, full_matrices=False)
    j2 = vt[0]
    j1 = _unit(np.einsum("kji,j->i", rel, j2))  # R1ᵀR2 j2, averaged
    planarity = float(s[1] / s[0]) if s[0] > 0 else float("nan")
    x = np.array([*_angles(j1), *_angles(j2)])
    for _ in range(iterations):  # Gauss-Newton on |w1 × j1| - |w2 × j2| = 0
        a1, d1p, d1t = _sphere(x[0], x[1])
        a2, d2p, d2t = _sphere(x[2], x[3])
        c1, c2 = np.cross(w1, a1), np.cross(w2, a2)
        n1 = np.maximum(np.linalg.norm(c1, axis=1), 1e-9)
        n2 = np.maximum(np.linalg.norm(c2, axis=1), 1e-9)
        e = n1 - n2
        J = np.stack([(c1 * np.cross(w1, d1p)).sum(1) / n1, (c1 * np.cross(w1, d1t)).sum(1) / n1,
                      -(c2 * np.cross(w2, d2p)).sum(1) / n2,
                      -(c2 * np.cross(w2, d2t)).sum(1) / n2], axis=1)
        step = np.linalg.lstsq(J.T @ J + 1e-6 * np.eye(4), J.T @ e, rcond=None)[0]
        x = x - step
        if np.abs(step).max() < 1e-9:
            break
    j1, j2 = _sphere(x[0], x[1])[0], _sphere(x[2], x[3])[0]
    if (np.einsum("kij,j->ki", rel, j1) @ j2).mean() < 0:  # one physical axis: same sense
        j1 = -j1
    e = np.linalg.norm(np.cross(w1, j1), axis=1) - np.linalg.norm(np.cross(w2, j2), axis=1)
    off = wr - np.outer(wr @ j2, j2)
    return (j1, j2, float(np.degrees(np.sqrt((off ** 2).sum(1).mean()))),
            float(np.degrees(np.sqrt((e ** 2).mean()))), planarity)


def _gamma(w: np.ndarray, dw: np.ndarray) -> np.ndarray:
    """``[K, 3, 3]``: Γ with ``Γ o = ω × (ω × o) + ω̇ × o``."""
    def skew(v: np.ndarray) -> np.ndarray:
        z = np.zeros(len(v))
        return np.stack([np.stack([z, -v[:, 2], v[:, 1]], -1),
                         np.stack([v[:, 2], z, -v[:, 0]], -1),
                         np.stack([-v[:, 1], v[:, 0], z], -1)], axis=1)
    W = skew(w)
    return W @ W + skew(dw)


def joint_centre(a1: np.ndarray, w1: np.ndarray, dw1: np.ndarray, a2: np.ndarray,
                 w2: np.ndarray, dw2: np.ndarray, o1: np.ndarray, o2: np.ndarray,
                 iterations: int = 30) -> tuple[np.ndarray, np.ndarray, float]:
    """(o1, o2, rms residual m/s²): the joint centre seen from both sensors, by Gauss-Newton
    on ``|a1 − Γ1 o1| − |a2 − Γ2 o2| = 0`` from ``o1, o2`` (m). ``a`` in m/s² (the gravity
    direction convention: what the accelerometer reads)."""
    G1, G2 = _gamma(w1, dw1), _gamma(w2, dw2)
    x = np.concatenate([o1, o2])
    for _ in range(iterations):
        v1 = a1 - np.einsum("kij,j->ki", G1, x[:3])
        v2 = a2 - np.einsum("kij,j->ki", G2, x[3:])
        n1 = np.maximum(np.linalg.norm(v1, axis=1), 1e-9)
        n2 = np.maximum(np.linalg.norm(v2, axis=1), 1e-9)
        e = n1 - n2
        J = np.concatenate([-np.einsum("ki,kij->kj", v1 / n1[:, None], G1),
                            np.einsum("ki,kij->kj", v2 / n2[:, None], G2)], axis=1)
        step = np.linalg.lstsq(J.T @ J + 1e-6 * np.eye(6), J.T @ e, rcond=None)[0]
        x = x - step
        if np.abs(step).max() < 1e-7:
            break
    v1 = a1 - np.einsum("kij,j->ki", G1, x[:3])
    v2 = a2 - np.einsum("kij,j->ki", G2, x[3:])
    e = np.linalg.norm(v1, axis=1) - np.linalg.norm(v2, axis=1)
    return x[:3], x[3:], float(np.sqrt((e ** 2).mean()))


def _frame(y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``[3, 3]`` columns X, Y, Z: Y = ``y``, Z = ``z`` made perpendicular, X = Y × Z."""
    y = _unit(y)
    z = _unit(z - (z @ y) * y)
    return np.stack([np.cross(y, z), y, z], axis=1)


def functional_calibration(R: np.ndarray, acc_g: np.ndarray, gyr: np.ndarray,
                           still: slice, moves: slice, dt: float
                           ) -> tuple[np.ndarray, float, FunctionalReport]:
    """(``R0'[18, 3, 3]``, ψ0 rad, report) from the filter's DCMs ``R[N, 18, 3, 3]``, the
    calibrated accelerometer in g (the gravity direction: +1 on the axis pointing down at
    rest) and gyroscope (rad/s), both ``[N, 18, 3]`` in the filter frame, the ``still``
    window's frames and the ``moves``' frames. ``C = R @ R0'ᵀ Rz(ψ0)`` (a Reset Zero)."""
    R, acc, gyr = (np.asarray(v, dtype=np.float64) for v in (R, acc_g, gyr))
    down = _unit(np.nanmean(acc[still], axis=0))  # [18, 3] gravity in each sensor frame
    R_still = average_dcm(R[still])
    # The suit's gyroscope reports the rate over the sample interval, the accelerometer the
    # value at the sample: the rate at sample k is the mean of intervals k and k + 1.
    w_at = gyr.copy()
    w_at[:-1] = 0.5 * (gyr[:-1] + gyr[1:])
    dw = np.zeros_like(gyr)
    dw[:-1] = (gyr[1:] - gyr[:-1]) / dt
    M = np.full((len(down), 3, 3), np.nan)
    report = FunctionalReport()
    right_world = []
    for name, p, d, sense in HINGES:
        w1, w2 = gyr[moves, p], gyr[moves, d]
        rel = np.swapaxes(R[moves, d], -1, -2) @ R[moves, p]
        ok = np.asarray(np.isfinite(w1).all(1) & np.isfinite(w2).all(1)
                        & np.isfinite(rel).all((1, 2)))
        w1, w2 = np.where(ok[:, None], w1, 0.0), np.where(ok[:, None], w2, 0.0)
        rel = np.where(ok[:, None, None], rel, np.eye(3))
        wr = w2 - np.einsum("kij,kj->ki", rel, w1)
        moving = ok & (np.linalg.norm(wr, axis=1) > MOVING_RAD_S)
        q = HingeQuality(int(moving.sum()))
        report.hinges[name] = q
        if q.moving < MIN_MOVING:
            report.missing.append(f"{name} flexion")
            continue
        j1, j2, q.axis_residual_dps, q.constraint_residual_dps, q.planarity = hinge_axes(
            w1[moving], w2[moving], rel[moving])
        # the joint centre's constraint holds whenever either segment turns (an arm swing
        # with a still elbow helps too)
        turning = ok & np.all([np.isfinite(v[moves, i]).all(1) for v in (acc, w_at, dw)
                               for i in (p, d)], axis=0)
        turning &= (np.linalg.norm(w1, axis=1) > MOVING_RAD_S) | (
            np.linalg.norm(w2, axis=1) > MOVING_RAD_S)
        o1, o2, q.centre_residual = joint_centre(
            acc[moves, p][turning] * G, w_at[moves, p][turning], dw[moves, p][turning],
            acc[moves, d][turning] * G, w_at[moves, d][turning], dw[moves, d][turning],
            0.2 * down[p], -0.2 * down[d])
        z1, z2 = o1 - (o1 @ j1) * j1, -(o2 - (o2 @ j2) * j2)
        q.centre_m = (float(np.linalg.norm(o1)), float(np.linalg.norm(o2)))
        if (min(np.linalg.norm(z1), np.linalg.norm(z2)) > 0.03 and max(q.centre_m) < 1.0
                and z1 @ down[p] > 0 and z2 @ down[d] > 0):
            q.long_axis = "joint centre"
        else:
            z1, z2 = down[p], down[d]
        M1, M2 = _frame(j1, z1), _frame(j2, z2)
        # anatomy fixes the axis' sign: at the largest bend the distal long axis leans to the
        # proximal segment's front (elbow) or back (knee)
        zd_in_p = np.einsum("kij,j->ki", np.swapaxes(rel[moving], -1, -2), M2[:, 2])
        k = int(np.argmin(zd_in_p @ M1[:, 2]))
        if sense * (zd_in_p[k] @ M1[:, 0]) < 0:
            M1, M2 = _frame(-j1, z1), _frame(-j2, z2)
        M[p], M[d] = M1, M2
        if name.startswith("knee"):
            right_world.append(R_still[p] @ M1[:, 1])
    if right_world:
        y = np.mean(right_world, axis=0)
    else:  # no knee flexions: the hip IMU's own heading, as Reset Zero
        report.heading = "hip IMU (knee flexions missing)"
        y = R_still[HIP_IMU] @ np.array([0.0, 1.0, 0.0])
    yaw0 = float(np.arctan2(-y[0], y[1]))
    y_world = np.array([-np.sin(yaw0), np.cos(yaw0), 0.0])
    for imu in UPRIGHT:
        M[imu] = _frame(R_still[imu].T @ y_world, down[imu])
    for foot, shank in FEET:
        y = R_still[shank] @ M[shank][:, 1] if np.isfinite(M[shank]).all() else y_world
        M[foot] = _frame(R_still[foot].T @ y, down[foot])
    for hand, forearm in HANDS:
        if np.isfinite(M[forearm]).all():
            M[hand] = R_still[hand].T @ R_still[forearm] @ M[forearm]
    for imu in np.flatnonzero(~np.isfinite(M).all(axis=(1, 2))).tolist():  # a hinge not moved
        M[imu] = _frame(R_still[imu].T @ y_world, down[imu])
    R0 = rot_z(yaw0) @ np.swapaxes(M, -1, -2)
    return R0, yaw0, report
