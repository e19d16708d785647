"""The default filter (DCM Mahony, SPEC §5) against its scalar reference (tests/
reference_mahony.py) in every regime of its step (issue 46.3): accelerations below 0.5 g and
above 1.5 g (the drift correction's weight clamps to 0; heel strikes and jumps), between them
(the weight's two slopes), a missing magnetometer (a zero field: heading 0), a failed sensor
(its last good value held; an IMU with no good value yet stays uninitialised), saturated
gyroscopes (±32767 counts, about ±40 rad/s) and the 6D mode (no magnetometer read, no yaw
correction) — on the simulated suit's calibrated data.

The hold of a failed sensor's last good value is written here a second time, frame by frame,
in front of the scalar reference (SPEC §2: a flagged sensor's values are not to be trusted)."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.filter.bank import HEADING_FREE_FIELD, MahonyBank
from bpms.io.options import FilterOptions
from tests.reference_mahony import ReferenceMahony
from tests.reference_regimes import ACC_FACTORS, calibrated_suit, plant_regimes

TOL = 1e-9


@pytest.fixture(scope="module")
def regimes():
    """(acc, mag, gyr, errors, gravity): the simulated suit (calibrated, pre-rotated) with
    each regime planted in its own frames."""
    acc, mag, gyr, cal = calibrated_suit()
    errors = plant_regimes(acc, mag, gyr)
    return acc, mag, gyr, errors, cal.gravity


def _reference(acc, mag, gyr, errors, gravity, kp_yaw=1.2, ki_yaw=0.00002):
    """R [N, 18, 3, 3] (NaN until initialised), euler, ωI, ωP of the scalar reference, with
    a flagged sensor's last good value held in front of it."""
    n = len(acc)
    R = np.full((n, 18, 3, 3), np.nan)
    eul = np.full((n, 18, 3), np.nan)
    wi = np.full((n, 18, 3), np.nan)
    wp = np.full((n, 18, 3), np.nan)
    for i in range(18):
        f = ReferenceMahony(float(gravity[i]), kp_yaw=kp_yaw, ki_yaw=ki_yaw)
        held: list[list[float] | None] = [None, None, None]
        for k in range(n):
            for s, v in enumerate((acc, mag, gyr)):
                if not errors[k, i, s]:
                    held[s] = v[k, i].tolist()
            if not f.initialised and (errors[k, i].any() or None in held):
                continue  # an IMU initialises on a frame with every sensor good
            f.update(*held)
            R[k, i] = f.R
            eul[k, i] = (f.roll, f.pitch, f.yaw)
            wi[k, i] = f.w_i
            wp[k, i] = f.w_p
    return R, eul, wi, wp


def _close(out, ref) -> None:
    for name, got, want in zip(("R", "euler", "w_i", "w_p"),
                               (out.R, out.euler, out.w_i, out.w_p), ref, strict=True):
        assert np.array_equal(np.isnan(got), np.isnan(want)), f"{name}: NaN where not expected"
        err = np.nanmax(np.abs(got - want))
        assert err < TOL, f"{name} differs from the reference by {err:g}"


def test_every_regime_matches_the_scalar_reference(regimes):
    acc, mag, gyr, errors, gravity = regimes
    out = MahonyBank(gravity).process(acc, mag, gyr, errors=errors, store_terms=True)
    ref = _reference(acc, mag, gyr, errors, gravity)
    _close(out, ref)
    # the regimes were reached: the weight is 0 for the clamped IMUs (ωP's roll/pitch part
    # vanishes: only the yaw term R[2]·eCourse is left, parallel to the stored R[2])
    wp = out.w_p[230]
    for i, factor in enumerate(ACC_FACTORS):
        if factor <= 0.5 or factor >= 1.5:
            assert np.linalg.norm(np.cross(wp[i], out.R[230, i, 2])) < 1e-12, (i, factor)
        else:
            assert np.linalg.norm(np.cross(wp[i], out.R[230, i, 2])) > 1e-9, (i, factor)


def test_heel_strikes_change_nothing_the_reference_would_not(regimes):
    """Above 1.5 g the drift correction must stop (weight 0): the same filter with the spikes
    removed by hand (a weight-0 frame is a pure gyro step, whatever |a|) agrees, so a filter
    still trusting a 2.2 g accelerometer fails."""
    acc, mag, gyr, errors, gravity = regimes
    calm = acc.copy()
    calm[300:303] *= 5.0 / 2.2  # still far above 1.5 g: the same weight 0
    a = MahonyBank(gravity).process(acc[:320], mag[:320], gyr[:320], errors=errors[:320])
    b = MahonyBank(gravity).process(calm[:320], mag[:320], gyr[:320], errors=errors[:320])
    ok = np.isfinite(a.R).all(axis=(-1, -2))
    np.testing.assert_allclose(a.R[ok], b.R[ok], atol=1e-12)


def test_6d_mode_matches_the_reference_without_yaw_correction(regimes):
    """The 6D (relative heading) mode: the magnetometer is not read (the heading-free field
    stands in for it) and the yaw gains are 0."""
    acc, mag, gyr, errors, gravity = regimes
    options = FilterOptions()
    options.heading = "relative"
    out = MahonyBank(gravity, options).process(acc, mag, gyr, errors=errors, store_terms=True)
    free = np.broadcast_to(100.0 * HEADING_FREE_FIELD, mag.shape)
    ref = _reference(acc, free, gyr, errors, gravity,
                     kp_yaw=0.0, ki_yaw=0.0)
    _close(out, ref)
