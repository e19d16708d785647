"""MahonyBank: 18 DCM Mahony filters (docs/filter.md) driven by the numba kernels of
:mod:`bpms.filter.mahony`, with run-time gains, resets and the failed-sensor hold.

Inputs are calibrated filter-frame vectors (``SensorCalibration.calibrate``): accel in Gravity
counts pointing down, mag ±100, gyro rad/s, ``[N, 18, 3]`` (a live frame is N = 1).
Outputs: DCM ``[N, 18, 3, 3]`` (filter frame → NED) and ωI, ωP ``[N, 18, 3]`` rad/s; NaN for
an IMU that is not initialised. The Euler angles are not a filter output: they are computed
once per batch from the final DCMs (:meth:`bpms.filter.processor.BodyPoseProcessor.process`),
or on read from :attr:`BankOutput.euler`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bpms.filter.kernel_state import KernelState
from bpms.filter.mahony import N_PARAMS, MahonyState, run_batch
from bpms.filter.rotations import dcm_to_euler
from bpms.io.frames import N_IMUS
from bpms.io.options import FilterOptions


@dataclass
class BankOutput:
    """Filter outputs of N frames (see the module docstring for units)."""

    R: np.ndarray
    w_i: np.ndarray | None = None
    w_p: np.ndarray | None = None
    #: gyro-bias estimate ``[.., n, 3]`` rad/s (body axes) of the filters that have one
    gyro_bias: np.ndarray | None = None
    #: body (linear) acceleration estimate ``[.., n, 3]`` m/s², NED, where estimated
    body_acc: np.ndarray | None = None

    @property
    def euler(self) -> np.ndarray:
        """Roll, pitch, yaw ``[.., n, 3]`` rad of :attr:`R`, computed on each read."""
        return dcm_to_euler(self.R)


def checked_gravity(gravity: np.ndarray) -> np.ndarray:
    """``gravity[n]`` (accelerometer counts per g) as a contiguous float array; ValueError
    unless every value is finite and > 0 (the kernels divide by it)."""
    g = np.ascontiguousarray(gravity, dtype=np.float64)
    if g.ndim != 1 or not (np.isfinite(g) & (g > 0)).all():
        raise ValueError(f"gravity must be finite counts/g > 0 for every IMU, got {g}")
    return g


#: The field a bank is handed in the 6D mode (``FilterOptions.heading = "relative"``): the
#: earth's norm along the sensor's forward axis, in units of the earth's field. It aligns the
#: heading of the sensor's forward axis at 0 and, with no heading correction, says nothing after.
HEADING_FREE_FIELD = np.array([1.0, 0.0, 0.0])


def params_from_options(options: FilterOptions) -> np.ndarray:
    """``[kp_rollpitch, ki_rollpitch, kp_yaw, ki_yaw, dt]`` as the kernels take them."""
    return np.array([options.kp_rollpitch, options.ki_rollpitch, options.kp_yaw,
                     options.ki_yaw, options.dt], dtype=np.float64)


class FilterBank:
    """What every bank of ``n`` attitude filters shares: ``gravity[n]`` (accelerometer counts
    per g, checked), the IMUs waiting to re-initialise (:meth:`reset`), and the count of steps
    that used a held sensor value (``state.held_count`` of the bank's state arrays)."""

    state: KernelState  # the bank's state arrays (each bank makes its own)

    def __init__(self, gravity: np.ndarray) -> None:
        self.gravity = checked_gravity(gravity)
        self.n = len(self.gravity)
        self._pending_reset = np.zeros(self.n, dtype=np.bool_)
        self._any_pending = False  # = self._pending_reset.any(), kept as a plain bool
        self._no_resets = np.zeros((0, self.n), np.bool_)

    def reset(self, imu: int | None = None) -> None:
        """Re-initialise IMU ``imu`` (all when None) at its next valid frame."""
        if imu is None:
            self._pending_reset[:] = True
        else:
            self._pending_reset[imu] = True
        self._any_pending = True

    def _resets(self, n: int, resets: np.ndarray | None) -> np.ndarray:
        """The kernels' ``resets`` of the next ``n`` frames: ``resets[N, n]`` with the pending
        resets taken at the first frame, or ``[0, n]`` when there are none."""
        if resets is None and not self._any_pending:
            return self._no_resets
        rs = (np.zeros((n, self.n), np.bool_) if resets is None
              else np.array(resets, dtype=np.bool_))
        if n:
            rs[0] |= self._pending_reset
            self._pending_reset[:] = False
            self._any_pending = False
        return rs

    @property
    def held_count(self) -> np.ndarray:
        """``[n, 3]`` filter steps that used a held (last good) accel, mag, gyro value."""
        return self.state.held_count.copy()

    def snapshot(self) -> tuple:
        """A copy of the filter state, for :meth:`restore` (the state guard rewinds a batch
        to re-run it up to a frame where a state stopped being a rotation)."""
        return [a.copy() for a in self.state.arrays()], self._pending_reset.copy()

    def restore(self, snap: tuple) -> None:
        """Back to the state :meth:`snapshot` copied."""
        arrays, pending = snap
        for target, saved in zip(self.state.arrays(), arrays, strict=True):
            target[...] = saved
        self._pending_reset[:] = pending
        self._any_pending = bool(pending.any())


class MahonyBank(FilterBank):
    """18 (or ``n``) Mahony filters sharing gains and dt.

    ``gravity``: ``[n]`` accelerometer counts per g (the calibration's Gravity). Gains are read
    from :attr:`params` at every call, so changing them (:meth:`set_gains`) takes effect at the
    next frame. :meth:`reset` re-initialises one IMU or all: the next valid frame of that IMU
    only initialises it (docs/filter.md).
    """

    def __init__(self, gravity: np.ndarray, options: FilterOptions | None = None) -> None:
        super().__init__(gravity)
        self.params = params_from_options(options or FilterOptions())
        #: the 6D mode: no yaw correction, the heading-free field (:data:`HEADING_FREE_FIELD`)
        self.relative = (options or FilterOptions()).heading == "relative"
        self.state = MahonyState(self.n)
        self._no_errors = np.zeros((0, self.n, 3), np.bool_)
        self._no_terms = np.empty((0, self.n, 3))  # ωI, ωP not stored

    # -- settings -----------------------------------------------------------------------
    def set_gains(self, kp_rollpitch: float | None = None, ki_rollpitch: float | None = None,
                  kp_yaw: float | None = None, ki_yaw: float | None = None,
                  dt: float | None = None) -> None:
        """Change gains (per accel count for roll/pitch) or dt (s) from the next frame on."""
        for k, v in enumerate((kp_rollpitch, ki_rollpitch, kp_yaw, ki_yaw, dt)):
            if v is not None:
                self.params[k] = float(v)

    def set_options(self, options: FilterOptions) -> None:
        self.params[:] = params_from_options(options)
        self.relative = options.heading == "relative"

    # -- running ------------------------------------------------------------------------
    def process(self, acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray,
                errors: np.ndarray | None = None, resets: np.ndarray | None = None,
                params: np.ndarray | None = None, store_terms: bool = False) -> BankOutput:
        """Filter N frames in one kernel call and keep the state for the next call.

        errors: bool ``[N, n, 3]`` failed-sensor flags; resets: bool ``[N, n]`` re-initialise
        at frame k; params: ``[N, 5]`` per-frame gains (default: :attr:`params` for all).
        """
        acc = np.ascontiguousarray(acc, dtype=np.float64)
        if self.relative:  # 6D: the magnetometer is not read (units: ±100 = the earth's)
            mag = np.ascontiguousarray(np.broadcast_to(100.0 * HEADING_FREE_FIELD,
                                                       np.shape(acc)))
        mag = np.ascontiguousarray(mag, dtype=np.float64)
        gyr = np.ascontiguousarray(gyr, dtype=np.float64)
        n = acc.shape[0]
        err = (self._no_errors if errors is None
               else np.ascontiguousarray(errors, dtype=np.bool_))
        rs = self._resets(n, resets)
        prm = (self.params[None] if params is None
               else np.ascontiguousarray(np.atleast_2d(params), dtype=np.float64))
        if prm.shape[1] != N_PARAMS or prm.shape[0] not in (1, n):
            raise ValueError(f"params must be [1, {N_PARAMS}] or [N, {N_PARAMS}]")
        if self.relative:  # 6D: no yaw correction (kp_yaw, ki_yaw)
            prm = prm.copy()
            prm[:, 2:4] = 0.0
        out_R = np.empty((n, self.n, 3, 3))
        out_wi = np.empty((n, self.n, 3)) if store_terms else self._no_terms
        out_wp = np.empty((n, self.n, 3)) if store_terms else self._no_terms
        run_batch(acc, mag, gyr, err, rs, prm, self.gravity, *self.state.arrays(),
                  out_R, out_wi, out_wp)
        return BankOutput(out_R, out_wi if store_terms else None,
                          out_wp if store_terms else None)


__all__ = ["HEADING_FREE_FIELD", "N_IMUS", "BankOutput", "FilterBank", "MahonyBank",
           "params_from_options"]
