"""A plain scalar reference of ONE IMU's DCM Mahony filter, written straight from SPEC §5.

Lists and :mod:`math` only, one step per call, no vectorisation: slow and obviously correct.
The fast kernel in :mod:`bpms.filter.mahony` must match it to 1e-9 on every output.

Also: :func:`synthetic_motion`, consistent accel/mag/gyro for 18 IMUs rotating smoothly,
for tests and benches that must not depend on the simulated suit.
"""

from __future__ import annotations

import math

import numpy as np

X_AXIS = [1.0, 0.0, 0.0]


def cross(u: list[float], v: list[float]) -> list[float]:
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]


def dot(u: list[float], v: list[float]) -> float:
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def scale(k: float, u: list[float]) -> list[float]:
    return [k * u[0], k * u[1], k * u[2]]


def add(u: list[float], v: list[float]) -> list[float]:
    return [u[0] + v[0], u[1] + v[1], u[2] + v[2]]


def matmul(A: list[list[float]], B: list[list[float]]) -> list[list[float]]:
    return [[sum(A[r][k] * B[k][c] for k in range(3)) for c in range(3)] for r in range(3)]


class ReferenceMahony:
    """One IMU. Gains and dt are plain attributes (change them between steps at will)."""

    def __init__(self, gravity: float, kp_rp: float = 0.02, ki_rp: float = 0.00002,
                 kp_yaw: float = 1.2, ki_yaw: float = 0.00002, dt: float = 0.02) -> None:
        self.gravity = gravity
        self.kp_rp, self.ki_rp, self.kp_yaw, self.ki_yaw, self.dt = kp_rp, ki_rp, kp_yaw, ki_yaw, dt
        self.initialised = False
        self.R = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        self.w_i = [0.0, 0.0, 0.0]
        self.w_p = [0.0, 0.0, 0.0]
        self.roll = self.pitch = self.yaw = 0.0

    def reset(self) -> None:
        """The next frame only initialises."""
        self.initialised = False

    def heading(self, m: list[float]) -> float:
        """Step 1, with the previous roll and pitch."""
        cr, sr = math.cos(self.roll), math.sin(self.roll)
        cp, sp = math.cos(self.pitch), math.sin(self.pitch)
        mx = m[0] * cp + m[1] * sr * sp + m[2] * cr * sp
        my = m[1] * cr - m[2] * sr
        return math.atan2(-my, mx)

    def initialise(self, a: list[float], m: list[float]) -> None:
        """"Reset_Mahony"."""
        self.w_i = [0.0, 0.0, 0.0]
        self.w_p = [0.0, 0.0, 0.0]
        self.pitch = -math.atan2(a[0], math.sqrt(a[1] ** 2 + a[2] ** 2))
        t1 = cross(a, X_AXIS)
        t2 = cross(X_AXIS, t1)
        self.roll = math.atan2(t2[1], t2[2])
        self.yaw = self.heading(m)
        c1, s1 = math.cos(self.roll), math.sin(self.roll)
        c2, s2 = math.cos(self.pitch), math.sin(self.pitch)
        c3, s3 = math.cos(self.yaw), math.sin(self.yaw)
        self.R = [
            [c2 * c3, c3 * s1 * s2 - c1 * s3, s1 * s3 + c1 * c3 * s2],
            [c2 * s3, c1 * c3 + s1 * s2 * s3, c1 * s2 * s3 - c3 * s1],
            [-s2, c2 * s1, c1 * c2],
        ]
        self.initialised = True

    def update(self, a: list[float], m: list[float], g: list[float]) -> None:
        """One frame: initialise if needed, else one filter step."""
        a, m, g = [float(v) for v in a], [float(v) for v in m], [float(v) for v in g]
        if not self.initialised:
            self.initialise(a, m)
            return
        # 1. heading
        H = self.heading(m)
        # 2. matrix update
        w = add(add(g, self.w_i), self.w_p)
        u = scale(self.dt, w)
        skew = [[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]]
        RS = matmul(self.R, skew)
        R = [[self.R[r][c] + RS[r][c] for c in range(3)] for r in range(3)]
        # 3. renormalise
        X, Y = R[0], R[1]
        e = dot(X, Y)
        Xo = add(X, scale(-e / 2, Y))
        Yo = add(Y, scale(-e / 2, X))
        Zo = cross(Xo, Yo)
        self.R = [scale(0.5 * (3 - dot(r, r)), r) for r in (Xo, Yo, Zo)]
        # 4. drift correction
        weight = 1 - 2 * abs(1 - math.sqrt(dot(a, a)) / self.gravity)
        weight = min(max(weight, 0.0), 1.0)
        e_rp = cross(a, self.R[2])
        self.w_p = scale(self.kp_rp * weight, e_rp)
        self.w_i = add(self.w_i, scale(self.ki_rp * weight, e_rp))
        e_course = self.R[0][0] * math.sin(H) - self.R[1][0] * math.cos(H)
        e_yaw = scale(e_course, self.R[2])
        self.w_p = add(self.w_p, scale(self.kp_yaw, e_yaw))
        self.w_i = add(self.w_i, scale(self.ki_yaw, e_yaw))
        # 5. Euler (asin argument clamped: rounding can exceed 1 by an ulp)
        self.pitch = -math.asin(min(max(self.R[2][0], -1.0), 1.0))
        self.roll = math.atan2(self.R[2][1], self.R[2][2])
        self.yaw = math.atan2(self.R[1][0], self.R[0][0])


# -- synthetic data -----------------------------------------------------------------------------

def _expm_so3(w: np.ndarray) -> np.ndarray:
    """Rotation matrices ``[..., 3, 3]`` = exp(skew(w)) (Rodrigues)."""
    theta = np.linalg.norm(w, axis=-1)[..., None, None]
    K = np.zeros((*w.shape[:-1], 3, 3))
    K[..., 0, 1], K[..., 0, 2] = -w[..., 2], w[..., 1]
    K[..., 1, 0], K[..., 1, 2] = w[..., 2], -w[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -w[..., 1], w[..., 0]
    safe = np.where(theta > 1e-12, theta, 1.0)
    A = np.where(theta > 1e-12, np.sin(safe) / safe, 1.0)
    B = np.where(theta > 1e-12, (1 - np.cos(safe)) / safe**2, 0.5)
    return np.eye(3) + A * K + B * (K @ K)


def synthetic_motion(n_frames: int, seed: int = 0, n_imus: int = 18, gravity: float = 256.0,
                     dt: float = 0.02, noise: bool = True,
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(acc, mag, gyr, R_true), the first three ``[N, n_imus, 3]`` in filter units, ``R_true``
    ``[N, n_imus, 3, 3]``. Each IMU turns at a smoothly varying body rate (up to ~2 rad/s)
    from a random start; accel = gravity direction (no linear acceleration), mag = a field of
    magnitude 100 dipping 60° below north; gyro = the exact per-step body rate (+ noise)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames) * dt
    freqs = rng.uniform(0.05, 0.4, (n_imus, 3))
    phases = rng.uniform(0, 2 * np.pi, (n_imus, 3))
    amps = rng.uniform(0.3, 1.5, (n_imus, 3))
    rates = amps * np.sin(2 * np.pi * freqs * t[:, None, None] + phases)  # [N, n, 3] rad/s
    R = np.empty((n_frames, n_imus, 3, 3))
    start = _expm_so3(rng.normal(size=(n_imus, 3)))
    R[0] = start
    steps = _expm_so3(rates * dt)
    for k in range(1, n_frames):
        R[k] = R[k - 1] @ steps[k - 1]
    down = np.array([0.0, 0.0, gravity])
    dip = math.radians(60)
    field_w = 100 * np.array([math.cos(dip), 0.0, math.sin(dip)])
    Rt = np.swapaxes(R, -1, -2)
    acc = Rt @ down
    mag = Rt @ field_w
    gyr = np.concatenate([rates[:1], rates[:-1]], axis=0)  # the rate that led into frame k
    if noise:
        acc = acc + rng.normal(scale=2.0, size=acc.shape)
        mag = mag + rng.normal(scale=1.0, size=mag.shape)
        gyr = gyr + rng.normal(scale=0.005, size=gyr.shape)
    return acc, mag, gyr, R
