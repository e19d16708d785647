"""The quaternion observer's numba kernel (bpms/filter/observer.py) against its slow, readable
scalar reference (tests/reference_observer.py), in both settings (``observer`` and
``adaptive``), in every regime of its step (issue 46.3), on the simulated suit's calibrated
data: accelerations below 0.5 g and above 1.5 g (free fall, heel strikes, a 3 g landing), a
missing magnetometer (a zero field), a failed sensor (its last good value held; an IMU with no
good value yet stays uninitialised), saturated gyroscopes (±32767 counts), a disturbed field
replaced by a steady new one after ``mag_new_time``, a still sensor (the adaptive setting's
bias at rest), a heading trust below 1 and a reset.

Tolerance 1e-9: both compute the same formulas in double precision; they differ only in the
order of rounding (the reference turns vectors through quaternions, aligns with another
matrix → quaternion formula), a few 1e-16 a sample, which the correction keeps from growing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bpms.filter.algorithms import ObserverBank
from bpms.filter.observer import ADAPTIVE, Observer, ObserverGains
from tests.reference_observer import ReferenceObserver
from tests.reference_regimes import N, calibrated_suit, plant_regimes

TOL = 1e-9
STILL_IMU, NEW_FIELD_IMU, RESET_IMU = 17, 9, 2


@pytest.fixture(scope="module")
def inputs():
    """(f m/s², m, ω rad/s, errors, resets, trust) with each regime planted in its frames."""
    acc, mag, gyr, cal = calibrated_suit()
    # a sensor lying still for 8 s on a table: a constant reading, gyro bias 0.01 rad/s
    acc[:400, STILL_IMU] = acc[0, STILL_IMU]
    mag[:400, STILL_IMU] = mag[0, STILL_IMU]
    gyr[:400, STILL_IMU] = [0.01, -0.02, 0.015]
    mag[100:, NEW_FIELD_IMU] *= 1.2  # a field 20 % stronger for good: rejected, then accepted
    errors = plant_regimes(acc, mag, gyr)
    resets = np.zeros((N, 18), bool)
    resets[450, RESET_IMU] = True
    trust = np.ones((N, 18))
    trust[:, 10] = 0.0  # heading corrections off (the 6D mode)
    trust[100:500, 11] = np.linspace(1.0, 0.0, 400)
    f, m, g = ObserverBank(cal.gravity).physical(acc, mag, gyr)  # units only
    return f, m, g, errors, resets, trust


def _reference(f, m, g, errors, resets, trust, gains: ObserverGains):
    """q, R, bias, acc ``[N, 18, …]`` (NaN until initialised) and the 18 references; a
    flagged sensor's last good value is held in front of the reference (SPEC §2)."""
    n = len(f)
    out = {"q": np.full((n, 18, 4), np.nan), "R": np.full((n, 18, 3, 3), np.nan),
           "bias": np.full((n, 18, 3), np.nan), "acc": np.full((n, 18, 3), np.nan)}
    refs = []
    settings = {k: v for k, v in vars(gains).items()}
    for i in range(18):
        ref = ReferenceObserver(**settings)
        held: list[list[float] | None] = [None, None, None]
        for k in range(n):
            if resets[k, i]:
                ref.initialised = False
            for s, v in enumerate((f, m, g)):
                if not errors[k, i, s]:
                    held[s] = v[k, i].tolist()
            if not ref.initialised and errors[k, i].any():
                continue  # an IMU aligns on a sample with every sensor good
            ref.update(*held, trust=float(trust[k, i]))
            out["q"][k, i] = ref.q
            out["R"][k, i] = ref.R
            out["bias"][k, i] = ref.b
            out["acc"][k, i] = ref.acc
        refs.append(ref)
    return out, refs


@pytest.mark.parametrize("setting", ["observer", "adaptive"])
def test_every_regime_matches_the_scalar_reference(inputs, setting):
    f, m, g, errors, resets, trust = inputs
    gains = ObserverGains(**(ADAPTIVE if setting == "adaptive" else {}))
    got = Observer(18, gains).process(f, m, g, errors, resets, keep=("q", "bias", "acc"),
                                      trust=trust)
    want, refs = _reference(f, m, g, errors, resets, trust, gains)
    for name in ("q", "R", "bias", "acc"):
        a, b = getattr(got, name), want[name]
        assert np.array_equal(np.isnan(a), np.isnan(b)), f"{name}: NaN where not expected"
        err = np.nanmax(np.abs(a - b))
        assert err < TOL, f"{name} differs from the reference by {err:g}"
    # the regimes were reached
    fn = np.linalg.norm(f[230], axis=-1) / 9.81
    assert (fn < 0.5).sum() >= 4 and (fn > 1.5).sum() >= 6
    assert np.isnan(got.q[:15, 3]).all() and np.isfinite(got.q[15:, 3]).all()
    assert np.abs(g[460:466, 7]).max() > 30.0
    assert refs[NEW_FIELD_IMU].new_field_accepted
    assert refs[STILL_IMU].rest_regime_reached == (setting == "adaptive")
    if setting == "adaptive":  # the bias at rest is what the still gyro reads
        np.testing.assert_allclose(got.bias[399, STILL_IMU], [0.01, -0.02, 0.015], atol=1e-3)


def test_a_missing_field_and_a_disturbed_one_get_no_heading_correction(inputs):
    """The zero field (IMUs 0–5, frames 380–440) is flagged disturbed in both; the attitude
    then turns about the vertical by the gyro alone."""
    f, m, g = inputs[:3]
    ref = ReferenceObserver()
    kernel = Observer(1)
    for k in range(440):
        ref.update(f[k, 0].tolist(), m[k, 0].tolist(), g[k, 0].tolist())
    kernel.process(f[:440, :1], m[:440, :1], g[:440, :1])
    assert ref.disturbed and bool(kernel.state.mag_dist[0])
    np.testing.assert_allclose(kernel.state.q[0], ref.q, atol=TOL)
    assert math.isclose(np.linalg.norm(ref.q), 1.0, abs_tol=1e-12)
