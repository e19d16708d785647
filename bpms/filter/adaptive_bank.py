"""``adaptive``: :mod:`bpms.filter.adaptive_observer` for the suit's IMUs behind the common
bank interface of :mod:`bpms.filter.algorithms` (units, hold and reset rules there)."""

from __future__ import annotations

import math

import numpy as np

from bpms.filter.adaptive_observer import AdaptiveGains, AdaptiveState, run_batch
from bpms.filter.algorithms import ObserverBank, _PhysicalBank
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


class AdaptiveBank(ObserverBank):
    """The adaptive observer for ``n`` IMUs: the observer bank's interface and outputs (the
    gyro-bias estimate ``gyro_bias`` ``[N, n, 3]`` rad/s, body axes, and the body-acceleration
    estimate ``body_acc`` ``[N, n, 3]`` m/s², NED), its own state, settings and kernel."""

    def __init__(self, gravity: np.ndarray, options: FilterOptions | None = None) -> None:
        _PhysicalBank.__init__(self, gravity, options)
        self.state = AdaptiveState(self.n)
        self._apply_options()

    def _apply_options(self) -> None:
        self.params = adaptive_gains(self.options).params()

    def _run_kernel(self, f, m, g, err, rs, out_R, out_e, bias, body_acc) -> None:
        run_batch(f, m, g, err, rs, self.params, *self.state.arrays(), out_R, out_e,
                  np.empty((0, self.n, 4)), bias, body_acc, np.empty((0, self.n), np.bool_))


__all__ = ["AdaptiveBank", "adaptive_gains"]
