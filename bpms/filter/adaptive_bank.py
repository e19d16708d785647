"""``adaptive``: :mod:`bpms.filter.adaptive_observer` for the suit's IMUs behind the common
bank interface of :mod:`bpms.filter.algorithms` (units, hold and reset rules there)."""

from __future__ import annotations

import math

import numpy as np

from bpms.filter.adaptive_observer import AdaptiveGains, AdaptiveState, run_batch
from bpms.filter.algorithms import _PhysicalBank
from bpms.filter.bank import BankOutput
from bpms.io.options import FilterOptions


def adaptive_gains(options: FilterOptions) -> AdaptiveGains:
    """The adaptive observer's settings from the options (``adaptive_*`` plus the observer's
    bias gain, gravity low-pass and new-field time, which it shares)."""
    return AdaptiveGains(
        k_incl=options.adaptive_k_incl, k_head=options.adaptive_k_head,
        k_bias=options.observer_k_bias, tau_acc=options.observer_tau_acc_s, dt=options.dt,
        mag_norm_th=options.adaptive_mag_norm_th,
        mag_dip_th_deg=options.adaptive_mag_dip_th_deg,
        mag_new_time_s=options.observer_mag_new_time_s,
        rest_gyr=math.radians(options.adaptive_rest_gyr_dps),
        rest_time=options.adaptive_rest_time_s, rest_tau=options.adaptive_rest_tau_s)


class AdaptiveBank(_PhysicalBank):
    """The adaptive observer for ``n`` IMUs. Its outputs carry the gyro-bias estimate
    (``gyro_bias`` ``[N, n, 3]`` rad/s, body axes) and the body-acceleration estimate
    (``body_acc`` ``[N, n, 3]`` m/s², NED) besides R and Euler."""

    def __init__(self, gravity: np.ndarray, options: FilterOptions | None = None) -> None:
        super().__init__(gravity, options)
        self.state = AdaptiveState(self.n)
        self._apply_options()

    def _apply_options(self) -> None:
        self.params = adaptive_gains(self.options).params()

    @property
    def initialised(self) -> np.ndarray:
        return self.state.initialised.copy()

    @property
    def held_count(self) -> np.ndarray:
        return self.state.held_count.copy()

    def process(self, acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray,
                errors: np.ndarray | None = None,
                resets: np.ndarray | None = None) -> BankOutput:
        """Filter N frames in one kernel call (errors ``[N, n, 3]``, resets ``[N, n]``)."""
        f, m, g = self.physical(acc, mag, gyr)
        n = f.shape[0]
        err = (np.zeros((0, self.n, 3), np.bool_) if errors is None
               else np.ascontiguousarray(errors, dtype=np.bool_))
        rs = self._resets(n, resets)
        out_R = np.empty((n, self.n, 3, 3))
        out_e = np.empty((n, self.n, 3))
        bias = np.empty((n, self.n, 3))
        body_acc = np.empty((n, self.n, 3))
        run_batch(f, m, g, err, rs, self.params, *self.state.arrays(), out_R, out_e,
                  np.empty((0, self.n, 4)), bias, body_acc, np.empty((0, self.n), np.bool_))
        return BankOutput(out_R, out_e, gyro_bias=bias, body_acc=body_acc)

    def step(self, acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray,
             errors: np.ndarray | None = None) -> BankOutput:
        """One live frame (``[n, 3]`` each)."""
        out = self.process(np.asarray(acc)[None], np.asarray(mag)[None], np.asarray(gyr)[None],
                           None if errors is None else np.asarray(errors)[None])
        return BankOutput(out.R[0], out.euler[0], gyro_bias=out.gyro_bias[0],
                          body_acc=out.body_acc[0])


__all__ = ["AdaptiveBank", "adaptive_gains"]
