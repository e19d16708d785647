"""``bpms export c3d``: the file read back by two independent readers (ezc3d and the pure-Python
``c3d`` package) holds the API's joint positions within 0.1 mm, the API's joint angles as
Vicon-style angle points, the rate, units and labels; and ``-o`` names every export alike."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from bpms.filter.body_model import POINT_NAMES
from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.firmware.sim.session import simulate

ezc3d = pytest.importorskip("ezc3d")
c3d = pytest.importorskip("c3d")

ROOT = Path(__file__).resolve().parents[1]
SECONDS = 6.0
#: NED (x north, y east, z down) → a Z-up lab frame (x north, y west, z up), as docs/analysis.md
#: states it: written here from the docs, not imported from the exporter.
P = np.diag([1.0, -1.0, -1.0])


def bpms(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bpms", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    folder = tmp_path_factory.mktemp("c3d")
    raw = simulate(SECONDS, seed=4).save_raw(folder / "Raw_c3d_001.bpmsraw")
    done = bpms("export", "c3d", str(raw), "-o", str(folder / "trial"))
    assert done.returncode == 0, done.stderr
    from bpms.filter.door import process_file

    return raw, folder / "trial.c3d", process_file(raw)


def test_ezc3d_reads_the_joint_centres_within_a_tenth_of_a_millimetre(exported):
    _, path, result = exported
    f = ezc3d.c3d(str(path))
    point = f["parameters"]["POINT"]
    labels = [s.strip() for s in point["LABELS"]["value"]]
    assert labels[:21] == list(POINT_NAMES)
    assert point["RATE"]["value"][0] == 50.0 and point["UNITS"]["value"] == ["mm"]
    xyz = f["data"]["points"][:3]  # [3, points, frames]
    assert xyz.shape == (3, 34, round(SECONDS * 50))  # the last: the centre of mass
    truth = np.einsum("ij,npj->ipn", P, result.joint_positions) * 1000.0  # mm
    ok = np.isfinite(truth).all(axis=0)
    assert ok[:, -1].all() and ok.mean() > 0.9
    assert np.abs(xyz[:, :21][:, ok] - truth[:, ok]).max() < 0.1
    assert np.isnan(xyz[:, :21][:, ~ok]).all()  # before Reset Zero: invalid points
    k = labels.index("head_top")
    assert xyz[2, k, -1] > 1400 and abs(xyz[2, labels.index("ankle_r"), -1]) < 200  # Z up
    residuals = f["data"]["meta_points"]["residuals"][0, :21]
    assert (residuals[ok] >= 0).all() and (residuals[~ok] < 0).all()


def test_joint_angles_are_angle_points_as_vicon_writes_them(exported):
    _, path, result = exported
    f = ezc3d.c3d(str(path))
    point = f["parameters"]["POINT"]
    labels = [s.strip() for s in point["LABELS"]["value"]]
    angles = [s.strip() for s in point["ANGLES"]["value"]]
    assert point["ANGLE_UNITS"]["value"] == ["deg"] and len(angles) == 12
    assert set(angles) <= set(labels) and "knee_r_angles" in angles
    xyz = f["data"]["points"][:3]
    deg = np.degrees(result.joint_angles)
    names = list(JOINT_ANGLE_NAMES)
    ok = np.isfinite(deg).all(axis=1)
    knee = xyz[:, labels.index("knee_r_angles")]
    np.testing.assert_allclose(knee[0, ok], deg[ok, names.index("knee_r.flexion")], atol=1e-3)
    assert (knee[1:, ok] == 0).all()  # a hinge
    hip = xyz[:, labels.index("hip_l_angles")]
    for axis, component in enumerate(("flexion", "abduction", "rotation")):
        np.testing.assert_allclose(hip[axis, ok], deg[ok, names.index(f"hip_l.{component}")],
                                   atol=1e-3)
    group = f["parameters"]["BPMS"]
    assert group["JOINT_ANGLE_CONVENTION"]["value"][0].startswith("isb")
    assert group["UTC_START"]["value"][0].endswith("Z")


def test_the_c3d_package_reads_the_same_points(exported):
    _, path, result = exported
    with open(path, "rb") as handle, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "No analog data found": there is none
        reader = c3d.Reader(handle)
        labels = [s.strip() for s in reader.point_labels]
        rate = reader.point_rate
        frames = np.array([p for _, p, _ in reader.read_frames()])  # [N, points, 5]
    assert rate == 50.0 and labels[:21] == list(POINT_NAMES)
    truth = np.einsum("ij,npj->npi", P, result.joint_positions) * 1000.0
    ok = np.isfinite(truth).all(axis=-1)
    assert np.abs(frames[:, :21, :3][ok] - truth[ok]).max() < 0.1
    assert (frames[:, :21, 3][~ok] == -1).all()  # the residual marks invalid points


@pytest.mark.parametrize(("fmt", "given", "expected"), [
    ("bvh", "out/b", ["out/b.bvh"]), ("bvh", "out/b.bvh", ["out/b.bvh"]),
    ("matlab", "out/e", ["out/e.csv"]), ("matlab", "out/e.csv", ["out/e.csv"]),
    ("c3d", "out/c", ["out/c.c3d"]),
    ("opensim", "out/s", ["out/s_orientations.sto", "out/s_calibration.sto",
                          "out/s_joint_angles.mot"]),
    ("opensim", "out/s.sto", ["out/s_orientations.sto", "out/s_calibration.sto",
                              "out/s_joint_angles.mot"]),
    ("matlab", None, ["rec/Raw_1.csv"]), ("c3d", None, ["rec/Raw_1.c3d"]),
])
def test_o_is_a_stem_for_every_export_format(fmt, given, expected):
    from bpms.commands.export import output_paths

    assert output_paths(fmt, "rec/Raw_1.bpmsraw", given) == [Path(e) for e in expected]


def test_every_format_writes_exactly_the_named_files(tmp_path):
    from bpms.cli import main

    raw = simulate(2.0, seed=1).save_raw(tmp_path / "Raw_x.bpmsraw")
    (tmp_path / "out").mkdir()
    for fmt in ("opensim", "bvh", "matlab", "c3d"):
        assert main(["export", fmt, str(raw), "-o", str(tmp_path / "out" / fmt)]) == 0
    written = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert written == ["bvh.bvh", "c3d.c3d", "matlab.csv", "opensim_calibration.sto",
                       "opensim_joint_angles.mot", "opensim_orientations.sto"]
