"""The joint angles every export writes, in the unit its columns name, against the simulated
subject's own degrees of freedom (bpms.firmware.sim.motion's truth, the script's DOFs: not a
computation of bpms.filter), converted here by hand (× 180/π): the MATLAB CSV's ``_deg``
columns and the C3D angle points (ANGLE_UNITS deg, read with ezc3d). A column in radians under
a degree name, or a flipped sign, is off by far more than the filter's error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bpms.cli import main
from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.firmware.sim.sensors import SensorModel
from bpms.firmware.sim.session import simulate

DEG = 180.0 / math.pi
#: the joints that move by more than 20° in the first 24 s of the script
SECONDS = 24.0


@pytest.fixture(scope="module")
def trial(tmp_path_factory):
    rec = simulate(SECONDS, seed=5, model=SensorModel(mounting_error_deg=0.0))
    folder = tmp_path_factory.mktemp("units")
    path = rec.save_raw(folder / "Raw_units_001.bpmsraw")
    truth_deg = np.asarray(rec.truth.joint_angles) * DEG
    return rec, path, truth_deg


def _followed(got_deg: np.ndarray, truth_deg: np.ndarray, t: np.ndarray) -> None:
    """After the automatic Reset Zero (1.5 s), every joint that moves by more than 20° follows
    the truth to 10 % of its span, every joint to 3° RMS."""
    k = t >= 1.5
    err = (got_deg[k] - truth_deg[k] + 180.0) % 360.0 - 180.0
    rms = np.sqrt(np.nanmean(err**2, axis=0))
    span = np.ptp(truth_deg, axis=0)
    moving = span > 20.0
    table = dict(zip(JOINT_ANGLE_NAMES, rms.round(2), strict=True))
    assert moving.sum() >= 6, span
    assert rms.max() < 3.0, table
    assert (rms[moving] < 0.1 * span[moving]).all(), table


def test_matlab_csv_joint_angles_in_degrees(trial, tmp_path):
    rec, path, truth_deg = trial
    out = tmp_path / "m.csv"
    assert main(["export", "matlab", str(path), "-o", str(out)]) == 0
    lines = [ln for ln in out.read_text().splitlines() if not ln.startswith("%")]
    cols = lines[0].split(",")
    data = np.array([[float(c) for c in ln.split(",")] for ln in lines[1:]])
    names = [f"joint_{n.replace('.', '_')}_deg" for n in JOINT_ANGLE_NAMES]
    assert all(n in cols for n in names), [n for n in names if n not in cols]
    got = data[:, [cols.index(n) for n in names]]
    _followed(got, truth_deg, rec.t)


def test_c3d_angle_points_in_degrees(trial, tmp_path):
    ezc3d = pytest.importorskip("ezc3d")
    rec, path, truth_deg = trial
    stem = tmp_path / "walk"
    assert main(["export", "c3d", str(path), "-o", str(stem)]) == 0
    f = ezc3d.c3d(str(stem) + ".c3d")
    point = f["parameters"]["POINT"]
    assert point["ANGLE_UNITS"]["value"] == ["deg"]
    labels = [s.strip() for s in point["LABELS"]["value"]]
    xyz = f["data"]["points"][:3]
    names = list(JOINT_ANGLE_NAMES)
    got = np.full_like(truth_deg, np.nan)
    for label in (x.strip() for x in point["ANGLES"]["value"]):
        joint = label.removesuffix("_angles")
        if f"{joint}.flexion" in names and f"{joint}.abduction" not in names:  # a hinge
            got[:, names.index(f"{joint}.flexion")] = xyz[0, labels.index(label)]
            continue
        for axis, part in enumerate(("flexion", "abduction", "rotation")):
            got[:, names.index(f"{joint}.{part}")] = xyz[axis, labels.index(label)]
    written = ~np.isnan(got).all(axis=0)
    assert written.sum() >= 20
    _followed(got[:, written], truth_deg[:, written], rec.t)
