"""Selectable attitude filters behind one interface (``FilterOptions.algorithm``).

Every bank filters ``n`` IMUs from the calibrated filter-frame vectors of
:meth:`bpms.filter.calibration.SensorCalibration.calibrate` (accel in Gravity counts pointing
down, mag ±100, gyro rad/s, ``[N, n, 3]``; a live frame is N = 1) and returns
:class:`bpms.filter.bank.BankOutput` (DCM filter frame → NED ``[N, n, 3, 3]``, Euler
``[N, n, 3]`` rad, NaN while an IMU is not initialised). All banks share the suite's rules:
the first valid frame of a stream (or after :meth:`reset`) aligns the filter, a failed sensor
holds its last good value (counted in ``held_count``), gains change from the next frame on.

- ``mahony``: :class:`bpms.filter.bank.MahonyBank`, the original (docs/filter.md), unchanged;
- ``observer``: :class:`ObserverBank` over :mod:`bpms.filter.observer`;
- ``vqf``: :class:`VqfBank` over :mod:`bpms.filter.vqf_filter` (needs the ``vqf`` package);
- ``adaptive``: :class:`AdaptiveBank`, the same observer in its adaptive setting
  (trapezoidal rates + bias at rest, :data:`bpms.filter.observer.ADAPTIVE`).

Unit conversion (inside the adapters): specific force ``f = −a · 9.81 / Gravity`` m/s² (the
suite's accel is the gravity direction, counts of 1 g), magnetometer ``m / 100`` (≈ unit
norm; only directions and relative norms are used), gyro unchanged.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from itertools import pairwise
from typing import Any, Protocol

import numpy as np

from bpms.filter.bank import HEADING_FREE_FIELD, BankOutput, FilterBank, MahonyBank
from bpms.filter.kernel_state import KernelState
from bpms.filter.observer import ADAPTIVE, Observer, ObserverGains
from bpms.filter.vqf_filter import VqfFilters, ned_dcm_of_enu
from bpms.io.options import ALGORITHMS, FilterOptions

G_MS2 = 9.81
MAG_UNIT = 100.0


class AttitudeBank(Protocol):
    """What the processor needs from a filter bank."""

    n: int

    def process(self, acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray,
                errors: np.ndarray | None = None,
                resets: np.ndarray | None = None) -> BankOutput: ...

    def reset(self, imu: int | None = None) -> None: ...

    def snapshot(self) -> Any: ...

    def restore(self, snap: Any) -> None: ...

    def set_gains(self, **gains: float) -> None: ...

    def set_options(self, options: FilterOptions) -> None:
        """Run with ``options`` (every filter's settings) from the next frame on; the
        processor's single way to change settings (it keeps ``options`` itself)."""
        ...

    @property
    def held_count(self) -> np.ndarray: ...


def make_bank(gravity: np.ndarray, options: FilterOptions) -> AttitudeBank:
    """The bank of ``options.algorithm`` for IMUs with accelerometer ``gravity[n]`` counts/g.
    Raises ValueError for an unknown name and
    :class:`bpms.filter.vqf_filter.VqfMissingError` when ``vqf`` is chosen but not installed."""
    banks: dict[str, Callable[..., AttitudeBank]] = {
        # (MahonyBank.set_gains names its keywords, the protocol takes any)
        "mahony": MahonyBank,  # type: ignore[dict-item]
        "observer": ObserverBank, "vqf": VqfBank,
        "adaptive": AdaptiveBank}
    name = options.algorithm
    if name not in banks:
        raise ValueError(f"unknown attitude filter '{name}' (choose {', '.join(ALGORITHMS)})")
    return banks[name](gravity, options)


def observer_gains(options: FilterOptions) -> ObserverGains:
    """The ``observer`` setting of :mod:`bpms.filter.observer` from the options."""
    return ObserverGains(k_incl=options.observer_k_incl, k_head=options.observer_k_head,
                         k_bias=options.observer_k_bias, tau_acc=options.observer_tau_acc_s,
                         dt=options.dt, mag_norm_th=options.observer_mag_norm_th,
                         mag_dip_th_deg=options.observer_mag_dip_th_deg,
                         mag_new_time_s=options.observer_mag_new_time_s)


def adaptive_gains(options: FilterOptions) -> ObserverGains:
    """The ``adaptive`` setting from the options (``adaptive_*`` plus the observer's bias
    gain, gravity low-pass and new-field time, which it shares)."""
    return dataclasses.replace(
        observer_gains(options), k_incl=options.adaptive_k_incl,
        k_head=options.adaptive_k_head, mag_norm_th=options.adaptive_mag_norm_th,
        mag_dip_th_deg=options.adaptive_mag_dip_th_deg,
        rest_gyr=math.radians(options.adaptive_rest_gyr_dps),
        rest_time=options.adaptive_rest_time_s, rest_tau=options.adaptive_rest_tau_s,
        trapezoid=bool(ADAPTIVE["trapezoid"]))


class _PhysicalBank(FilterBank):
    """Common parts of the non-Mahony banks: their options and the unit conversion."""

    def __init__(self, gravity: np.ndarray, options: FilterOptions | None) -> None:
        super().__init__(gravity)
        self.options = dataclasses.replace(options or FilterOptions())
        self._acc_factor = (-G_MS2 / self.gravity)[:, None]

    @property
    def relative(self) -> bool:
        """The 6D mode (``FilterOptions.heading = "relative"``): heading relative to the
        start, the magnetometer not read."""
        return self.options.heading == "relative"

    def physical(self, acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray,
                 out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Suite units ``[N, n, 3]`` → (specific force m/s², mag ≈ unit, gyro rad/s), float64
        ``[N, n, 3]``; or, into ``out``, three ``[n, N, 3]`` arrays (one block of rows per
        IMU, each IMU's rows contiguous). The conversion reads the inputs in their own order
        either way."""
        if out is None:
            to = (np.empty(np.shape(acc)), np.empty(np.shape(acc)), np.empty(np.shape(acc)))
            out = to
        else:
            to = (out[0].transpose(1, 0, 2), out[1].transpose(1, 0, 2),
                  out[2].transpose(1, 0, 2))
        np.multiply(acc, self._acc_factor, out=to[0])
        if self.relative:  # 6D: the magnetometer is not read
            to[1][...] = HEADING_FREE_FIELD
        else:
            np.divide(mag, MAG_UNIT, out=to[1])
        to[2][...] = gyr  # exact: a float64 copy in the asked layout
        return out

    def set_gains(self, **gains: float) -> None:
        """Change settings by their :class:`FilterOptions` names (e.g. ``observer_k_incl``,
        ``vqf_tau_acc_s``, ``dt``) from the next frame on; other filters' gains are kept for
        when they are selected."""
        self.options = dataclasses.replace(self.options, **gains)  # type: ignore[arg-type]
        self._apply_options()

    def set_options(self, options: FilterOptions) -> None:
        self.options = dataclasses.replace(options)
        self._apply_options()

    def _apply_options(self) -> None:  # pragma: no cover - overridden
        pass


class ObserverBank(_PhysicalBank):
    """The quaternion observer (:mod:`bpms.filter.observer`) for ``n`` IMUs, with the
    gyro-bias estimate ``gyro_bias`` ``[N, n, 3]`` rad/s (body axes) and the
    body-acceleration estimate ``body_acc`` ``[N, n, 3]`` m/s² (NED) beside its outputs."""

    #: the settings of this bank's kind from the options
    gains_from = staticmethod(observer_gains)

    def __init__(self, gravity: np.ndarray, options: FilterOptions | None = None) -> None:
        super().__init__(gravity, options)
        self.observer = Observer(self.n)
        self.state = self.observer.state
        self._apply_options()

    def _apply_options(self) -> None:
        self.observer.gains = self.gains_from(self.options)

    def process(self, acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray,
                errors: np.ndarray | None = None, resets: np.ndarray | None = None,
                mag_trust: np.ndarray | None = None) -> BankOutput:
        """Filter N frames in one kernel call (errors ``[N, n, 3]``, resets ``[N, n]``,
        mag_trust ``[N, n]`` the heading trust 0–1, :mod:`bpms.filter.observer`)."""
        f, m, g = self.physical(acc, mag, gyr)
        n = f.shape[0]
        # 6D: no heading correction at all
        trust = np.zeros((n, self.n)) if self.relative else mag_trust
        out = self.observer.process(f, m, g, errors, self._resets(n, resets),
                                    keep=("bias", "acc"), trust=trust)
        return BankOutput(out.R, gyro_bias=out.bias, body_acc=out.acc)


class AdaptiveBank(ObserverBank):
    """The observer in its ``adaptive`` setting (trapezoidal rates with coning correction,
    gyro bias learnt at rest) for ``n`` IMUs."""

    gains_from = staticmethod(adaptive_gains)


#: Frames that :class:`VqfBank` filters at a time: a block's inputs, quaternions and DCMs of
#: all IMUs (≈ 1.3 MB of DCMs) stay in the processor's cache.
VQF_BLOCK = 1024


class _VqfHold(KernelState):
    """The suite's hold/reset bookkeeping beside ``n`` VQF filters: initialised ``[n]``, held
    ``[n, 3 sensors, 3]`` the last good inputs (NaN before one), held_count ``[n, 3]``."""

    LAYOUT = (("initialised", (), np.bool_, False), ("held", (3, 3), np.float64, np.nan),
              ("held_count", (3,), np.int64, 0))


class VqfBank(_PhysicalBank):
    """``n`` VQF filters (:mod:`bpms.filter.vqf_filter`) with the suite's hold/reset rules."""

    def __init__(self, gravity: np.ndarray, options: FilterOptions | None = None) -> None:
        super().__init__(gravity, options)
        o = self.options
        self.vqf = VqfFilters(self.n, o.dt, o.vqf_tau_acc_s, o.vqf_tau_mag_s)
        self.state = _VqfHold(self.n)

    def _apply_options(self) -> None:
        o = self.options
        if o.dt != self.vqf.dt:  # a new sample period needs new filters
            self.vqf = VqfFilters(self.n, o.dt, o.vqf_tau_acc_s, o.vqf_tau_mag_s)
            self.state.initialised[:] = False
        else:
            self.vqf.set_time_constants(o.vqf_tau_acc_s, o.vqf_tau_mag_s)

    def snapshot(self) -> tuple:
        """A copy of every VQF filter's state and the hold bookkeeping."""
        return ([{k: np.copy(v) for k, v in f.state.items()} for f in self.vqf.filters],
                super().snapshot())

    def restore(self, snap: tuple) -> None:
        states, hold = snap
        for flt, state in zip(self.vqf.filters, states, strict=True):
            flt.state = state
        super().restore(hold)

    def _fill(self, inputs: tuple[np.ndarray, ...], err: np.ndarray | None
              ) -> np.ndarray | None:
        """A block's inputs (f, m, g ``[n, k, 3]``, IMU by IMU) with each failed sample
        replaced, in place, by the last good one of its IMU and sensor (before the block: the
        held one); the valid mask ``[n, k]`` (None: every sample is)."""
        valid: np.ndarray | None = None
        if err is not None:
            good = ~err.transpose(1, 0, 2)  # [n, k, sensor]
            valid = np.asarray(good.all(axis=-1))
            last_good = np.maximum.accumulate(
                np.where(good, np.arange(good.shape[1])[:, None], -1), axis=1)
            for s, x in enumerate(inputs):
                if not good[..., s].all():
                    at = last_good[..., s, None]
                    x[...] = np.where(at >= 0, np.take_along_axis(x, np.maximum(at, 0), axis=1),
                                      self.state.held[:, None, s])
        for s, x in enumerate(inputs):
            self.state.held[:, s] = x[:, -1]
        return valid

    def process(self, acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray,
                errors: np.ndarray | None = None,
                resets: np.ndarray | None = None) -> BankOutput:
        """Filter N frames through VQF's batch API, :data:`VQF_BLOCK` frames at a time: the
        block's inputs converted for all IMUs at once, each IMU's run handed to VQF (cut at
        its resets), and the block's DCMs computed at once from the quaternions gathered. A
        block's arrays stay in the processor's cache from conversion to output; VQF's state
        carries from block to block, so the numbers are those of one call."""
        n = len(acc)
        # one pass over the flags spares the per-IMU checks of an error-free batch
        err = None if errors is None or not np.any(errors) else np.asarray(errors, np.bool_)
        rs = self._resets(n, resets)
        R = np.empty((n, self.n, 3, 3))
        bias = np.empty((n, self.n, 3))
        # one block's arrays, reused by every block (no block allocates anything of its size)
        size = min(n, VQF_BLOCK)
        inputs = tuple(np.empty((self.n, size, 3)) for _ in range(3))
        quat = np.empty((self.n, size, 4))  # body → ENU, IMU by IMU
        block_bias = np.empty((self.n, size, 3))
        work = np.empty((10, self.n, size))
        for a in range(0, n, VQF_BLOCK):
            b = min(n, a + VQF_BLOCK)
            k = b - a
            by_imu = self.physical(acc[a:b], mag[a:b], gyr[a:b],
                                   out=(inputs[0][:, :k], inputs[1][:, :k], inputs[2][:, :k]))
            block_err = None if err is None else err[a:b]
            valid = self._fill(by_imu, block_err)
            for i in range(self.n):
                resets_at = np.flatnonzero(rs[a:b, i]).tolist() if len(rs) else []
                for lo, hi in pairwise([0, *resets_at, k]):
                    if hi > lo:
                        self._run(i, lo, hi, lo in resets_at, by_imu, valid, block_err,
                                  quat[i], block_bias[i])
            w, x, y, z = np.moveaxis(quat[:, :k], -1, 0)
            ned_dcm_of_enu(w, x, y, z, out=R[a:b].transpose(1, 0, 2, 3), work=work[:, :, :k])
            bias[a:b] = block_bias[:, :k].transpose(1, 0, 2)
        return BankOutput(R, gyro_bias=bias)

    def _run(self, i: int, lo: int, hi: int, reset: bool, inputs: tuple[np.ndarray, ...],
             valid: np.ndarray | None, err: np.ndarray | None, quat: np.ndarray,
             bias: np.ndarray) -> None:
        """IMU ``i``'s rows ``lo .. hi-1`` of a block (``reset``: a reset at ``lo``, none
        after it), from the block's inputs and valid mask (:meth:`_fill`) and error flags:
        its body → ENU quaternions ``[block, 4]`` into ``quat``, its bias estimate
        ``[block, 3]`` rad/s into ``bias`` (NaN in the rows before the aligning frame)."""
        if reset:
            self.state.initialised[i] = False
        start = first = lo
        if not self.state.initialised[i]:
            ok = [0] if valid is None else np.flatnonzero(valid[i, lo:hi])
            start = hi if len(ok) == 0 else lo + int(ok[0])
            quat[lo:start] = bias[lo:start] = np.nan  # no attitude yet
            if start == hi:
                return
            self.vqf.reset(i)
            self.state.initialised[i] = True
            first = start + 1  # the aligning frame is not a step
        if err is not None:
            self.state.held_count[i] += err[first:hi, i].sum(axis=0)
        f, m, g = (x[i, start:hi] for x in inputs)
        quat[start:hi], bias[start:hi] = self.vqf.process_imu(i, f, m, g,
                                                              six_d=self.relative)


__all__ = ["ALGORITHMS", "AdaptiveBank", "AttitudeBank", "ObserverBank", "VqfBank",
           "adaptive_gains", "make_bank", "observer_gains"]
