"""Adapter over the ``vqf`` package (D. Laidig, T. Seel, "VQF", Information Fusion 2023):
``n`` independent 9D VQF filters through its batch API (``VQF.updateBatch``; a live frame is
a batch of one), returning the suite's conventions.

Inputs in physical units: specific force ``f`` m/s² (reads (0, 0, −9.81) level in a Z-down
body frame), magnetometer in any unit, gyro rad/s. VQF's earth frame is ENU (x east, y north,
z up); outputs here are rotated to NED: ``R_ned = M R_enu`` with ``M`` swapping x, y and
negating z. ``vqf`` is a run-time dependency of this choice only: :func:`require_vqf` raises
:class:`VqfMissingError` with a one-line message when it is not installed.
"""

from __future__ import annotations

import numpy as np

#: ENU → NED coordinates (a proper rotation: 180° about (1, 1, 0)/√2).
ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: The same as a quaternion (w, x, y, z).
Q_ENU_TO_NED = np.array([0.0, 1.0, 1.0, 0.0]) / np.sqrt(2.0)


class VqfMissingError(RuntimeError):
    """The ``vqf`` package is not installed."""


def require_vqf():
    """The ``vqf.VQF`` class, or :class:`VqfMissingError` with a clear message."""
    try:
        from vqf import VQF
    except ImportError as exc:
        raise VqfMissingError("the 'vqf' filter needs the vqf package (pip install vqf); "
                         "choose 'mahony' or 'observer' otherwise") from exc
    return VQF


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions ``[..., 4]`` (w, x, y, z)."""
    a0, a1, a2, a3 = np.moveaxis(a, -1, 0)
    b0, b1, b2, b3 = np.moveaxis(b, -1, 0)
    return np.stack([a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
                     a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                     a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
                     a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0], axis=-1)


def ned_dcm_of_enu(w: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray,
                   out: np.ndarray | None = None, work: np.ndarray | None = None
                   ) -> np.ndarray:
    """Unit body → ENU quaternions, as their components ``[...]`` each (NaN allowed) → body →
    NED DCMs ``[..., 3, 3]``: ``ENU_TO_NED @ R(q)``, i.e. the rows y, x, −z of ``R(q)``,
    each entry written once into the result (``out`` when given; VQF's quaternions are unit:
    no normalisation). ``work``: ``[10, ...]`` scratch for the products (allocated when not
    given; a caller converting block after block passes the same one, so that no block
    allocates)."""
    R = np.empty((*w.shape, 3, 3)) if out is None else out
    t = np.empty((10, *w.shape)) if work is None else work
    s, (xx, wx, xy, yy, wy, xz, yz, zz, wz) = t[0], t[1:]
    for c, pairs in ((x, ((x, xx), (w, wx))), (y, ((x, xy), (y, yy), (w, wy))),
                     (z, ((x, xz), (y, yz), (z, zz), (w, wz)))):
        np.multiply(c, 2.0, out=s)
        for a, product in pairs:
            np.multiply(a, s, out=product)
    # each entry written once (R may be strided), ``s`` holding a two-step entry's first step
    np.add(xy, wz, out=R[..., 0, 0])  # ENU y row
    np.subtract(np.subtract(1.0, xx, out=s), zz, out=R[..., 0, 1])
    np.subtract(yz, wx, out=R[..., 0, 2])
    np.subtract(np.subtract(1.0, yy, out=s), zz, out=R[..., 1, 0])  # ENU x row
    np.subtract(xy, wz, out=R[..., 1, 1])
    np.add(xz, wy, out=R[..., 1, 2])
    np.subtract(wy, xz, out=R[..., 2, 0])  # −ENU z row
    np.negative(np.add(yz, wx, out=s), out=R[..., 2, 1])
    np.subtract(np.add(xx, yy, out=s), 1.0, out=R[..., 2, 2])
    return R


class VqfFilters:
    """``n`` VQF filters sharing dt and time constants.

    dt: sample period, s; tau_acc, tau_mag: VQF's accelerometer and magnetometer time
    constants, s (package defaults 3 s and 9 s).
    """

    def __init__(self, n: int, dt: float, tau_acc: float = 3.0, tau_mag: float = 9.0) -> None:
        self._cls = require_vqf()
        self.n = n
        self.dt = float(dt)
        self.tau_acc = float(tau_acc)
        self.tau_mag = float(tau_mag)
        self.filters = [self._new() for _ in range(n)]

    def _new(self):
        return self._cls(self.dt, tauAcc=self.tau_acc, tauMag=self.tau_mag)

    def reset(self, imu: int) -> None:
        """Start IMU ``imu`` afresh (its next sample aligns it)."""
        self.filters[imu].resetState()

    def set_time_constants(self, tau_acc: float | None = None,
                           tau_mag: float | None = None) -> None:
        if tau_acc is not None:
            self.tau_acc = float(tau_acc)
            for f in self.filters:
                f.setTauAcc(self.tau_acc)
        if tau_mag is not None:
            self.tau_mag = float(tau_mag)
            for f in self.filters:
                f.setTauMag(self.tau_mag)

    def process_imu(self, imu: int, f: np.ndarray, m: np.ndarray, g: np.ndarray,
                    six_d: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Filter ``[N, 3]`` samples of one IMU (batch API): (body → **ENU** quaternions
        ``[N, 4]``, VQF's own frame — :func:`ned_dcm_of_enu` gives their NED DCMs; gyro-bias
        estimate ``[N, 3]`` rad/s in sensor axes, rate = gyro − bias). ``six_d``: VQF's
        magnetometer-free estimate (heading relative to the start) instead of the 9D one."""
        out = self.filters[imu].updateBatch(
            np.ascontiguousarray(g, dtype=np.float64), np.ascontiguousarray(f, dtype=np.float64),
            np.ascontiguousarray(m, dtype=np.float64))
        return out["quat6D" if six_d else "quat9D"], out["bias"]


__all__ = ["ENU_TO_NED", "Q_ENU_TO_NED", "VqfFilters", "VqfMissingError", "ned_dcm_of_enu",
           "quat_mul", "require_vqf"]
