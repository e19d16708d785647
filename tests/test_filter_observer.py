"""The quaternion observer (bpms/filter/observer.py): bias estimation, body accelerations,
convergence from any attitude. Synthetic signals from a known attitude trajectory."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.filter.algorithms import ObserverBank
from bpms.filter.bank import MahonyBank
from bpms.filter.observer import Observer, ObserverGains
from bpms.filter.rotations import dcm_to_quaternion, inclination_error, quaternion_to_dcm
from bpms.io.options import FilterOptions

DT = 0.02
G = 9.81
#: Earth field (NED, unit-ish): north and 60° dip down.
M_NED = np.array([np.cos(np.radians(60)), 0.0, np.sin(np.radians(60))])


def _exp_q(v: np.ndarray) -> np.ndarray:
    ang = np.linalg.norm(v)
    if ang < 1e-15:
        return np.array([1.0, *(0.5 * v)])
    return np.array([np.cos(ang / 2), *(np.sin(ang / 2) * v / ang)])


def _mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.array([a[0] * b[0] - a[1:] @ b[1:],
                     *(a[0] * b[1:] + b[0] * a[1:] + np.cross(a[1:], b[1:]))])


def motion(seconds: float, amplitude: float = 0.8, seed: int = 0,
           acc_body: np.ndarray | None = None):
    """A smooth tumbling motion: truth DCMs [N, 3, 3] (body → NED) and the ideal sensor
    signals f (m/s², specific force), m, ω (rad/s), ``[N, 3]`` each; ``acc_body`` is added to
    the accelerometer (a constant body-frame acceleration, m/s²)."""
    rng = np.random.default_rng(seed)
    n = round(seconds / DT)
    t = np.arange(n) * DT
    freqs = rng.uniform(0.1, 0.4, 3)
    phases = rng.uniform(0, 2 * np.pi, 3)
    w = amplitude * np.sin(2 * np.pi * freqs * t[:, None] + phases)
    q = np.array([1.0, 0.0, 0.0, 0.0])
    Rs = np.empty((n, 3, 3))
    for k in range(n):  # sample k's rate turns the body from k - 1 to k
        q = _mul(q, _exp_q(w[k] * DT))
        q /= np.linalg.norm(q)
        Rs[k] = quaternion_to_dcm(q)
    f = np.einsum("nji,j->ni", Rs, np.array([0.0, 0.0, -G]))
    if acc_body is not None:
        f = f + acc_body
    m = np.einsum("nji,j->ni", Rs, M_NED)
    return Rs, f, m, w


def _suite_units(f, m, g, gravity=256.0):
    """Physical signals → the suite's calibrated filter inputs for one IMU ``[N, 1, 3]``."""
    return (-f * gravity / G)[:, None], (m * 100.0)[:, None], g[:, None]


def test_bias_converges_to_an_injected_constant_gyro_bias():
    bias = np.array([0.02, -0.015, 0.01])  # rad/s (1.1, -0.9, 0.6 °/s)
    Rs, f, m, w = motion(300.0, amplitude=0.5)
    out = Observer(1).process(f[:, None], m[:, None], (w + bias)[:, None], keep=("bias",))
    est = out.bias[-500:, 0].mean(axis=0)  # last 10 s
    np.testing.assert_allclose(est, bias, atol=0.0015)
    assert np.abs(out.bias[100, 0] - bias).max() > 0.01  # it did start from zero
    incl = np.degrees(inclination_error(out.R[-500:, 0], Rs[-500:]))
    assert np.sqrt(np.mean(incl**2)) < 0.5


def test_constant_body_acceleration_inclination_error_below_the_original():
    """The paper's trial: a constant signal added to the accelerometer channels while the
    sensor turns in all directions. The original filter follows the accelerometer (its error
    is the angle between gravity and the specific force); the observer does not."""
    acc = np.array([2.0, -1.5, 0.0])  # m/s², constant in the sensor frame
    Rs, f, m, w = motion(60.0, amplitude=2.0, seed=3, acc_body=acc)
    a, mm, g = _suite_units(f, m, w)
    gravity = np.array([256.0])
    obs = ObserverBank(gravity, FilterOptions()).process(a, mm, g)
    mah = MahonyBank(gravity, FilterOptions()).process(a, mm, g)
    k = slice(round(10 / DT), None)  # after 10 s
    err_obs = np.degrees(inclination_error(obs.R[k, 0], Rs[k]))
    err_mah = np.degrees(inclination_error(mah.R[k, 0], Rs[k]))
    rms_obs, rms_mah = (float(np.sqrt(np.mean(e**2))) for e in (err_obs, err_mah))
    assert rms_mah > 8.0  # ≈ atan(2.5 / 9.81): the original tilts towards the specific force
    assert rms_obs < 0.5 * rms_mah
    assert err_obs.max() < err_mah.max()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rest_orientation_correct_from_any_initial_attitude(seed):
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    truth = quaternion_to_dcm(_exp_q(rng.uniform(-np.pi, np.pi) * axis / np.linalg.norm(axis)))
    n = round(90.0 / DT)
    f = np.tile(truth.T @ np.array([0.0, 0.0, -G]), (n, 1))
    m = np.tile(truth.T @ M_NED, (n, 1))
    g = np.zeros((n, 3))
    obs = Observer(1, ObserverGains())
    first = obs.process(f[:1, None], m[:1, None], g[:1, None])  # aligns on the first sample
    assert np.degrees(np.arccos(np.clip((np.trace(first.R[0, 0] @ truth.T) - 1) / 2, -1,
                                        1))) < 1e-4
    # then force a wrong attitude: 150°–179° away about a random axis
    off = rng.normal(size=3)
    off = rng.uniform(np.radians(150), np.radians(179)) * off / np.linalg.norm(off)
    start = quaternion_to_dcm(_exp_q(off)) @ truth
    obs.state.set_attitude(0, dcm_to_quaternion(start))
    out = obs.process(f[1:, None], m[1:, None], g[1:, None])
    err = np.degrees(np.arccos(np.clip((np.trace(out.R[-1, 0] @ truth.T) - 1) / 2, -1, 1)))
    assert err < 0.5
