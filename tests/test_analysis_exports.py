"""Exports: OpenSim orientations .sto, BVH (read back with bvhio), MATLAB CSV."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from bpms.analysis.bvh import NED_TO_BVH, joint_name
from bpms.analysis.matlab import matlab_columns
from bpms.analysis.opensim import OPENSIM_IMUS, SENSOR_TO_OPENSIM_ROTATIONS
from bpms.cli import main
from bpms.filter.body_model import BODY_POINTS, POINT_INDEX
from bpms.filter.processor import BodyPoseProcessor
from bpms.filter.rotations import euler_to_dcm
from bpms.firmware.sim.session import simulate
from bpms.io.rawfile import new_header, write_raw

with warnings.catch_warnings():  # bvhio imports PyGLM the old way
    warnings.simplefilter("ignore", PendingDeprecationWarning)
    import bvhio


@pytest.fixture(scope="module")
def trial(tmp_path_factory):
    rec = simulate(duration_s=25.0, seed=3)
    folder = tmp_path_factory.mktemp("export")
    path = folder / "Raw_trial_001.bpmsraw"
    options = {"body": {"thigh": 0.47, "arm": 0.31}}  # per-subject lengths
    write_raw(path, 1.7e9 + rec.t, rec.frames,
              new_header(calibration=rec.calibration.values, options=options))
    proc = BodyPoseProcessor(rec.calibration)
    proc.options.body.thigh, proc.options.body.arm = 0.47, 0.31
    return rec, path, proc.process(rec.raw, rec.errors)


def read_sto(path: Path) -> tuple[dict[str, str], list[str], list[list[str]]]:
    """A plain reader: key=value lines up to endheader, a tab-separated label row, rows."""
    lines = path.read_text().splitlines()
    end = lines.index("endheader")
    header = dict(ln.split("=", 1) for ln in lines[:end])
    labels = lines[end + 1].split("\t")
    return header, labels, [ln.split("\t") for ln in lines[end + 2:]]


def test_opensim_orientations_parse_with_a_plain_reader(trial):
    rec, path, res = trial
    assert main(["export", "opensim", str(path)]) == 0
    header, labels, rows = read_sto(path.with_name("Raw_trial_001_orientations.sto"))
    assert header["DataType"] == "Quaternion" and float(header["DataRate"]) == 50.0
    assert {"version", "OpenSimVersion"} <= set(header)
    assert labels == ["time", *OPENSIM_IMUS.values()]
    assert labels[1:4] == ["pelvis_imu", "torso_imu", "humerus_r_imu"]
    assert len(rows) == len(rec) and all(len(r) == len(labels) for r in rows)
    q = np.array([[[float(v) for v in cell.split(",")] for cell in r[1:]] for r in rows])
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-7)
    # the cells are the segment orientations, w first
    ids = list(OPENSIM_IMUS)
    np.testing.assert_allclose(np.abs((q * res.segment_quaternions[:, ids]).sum(-1)), 1.0,
                               atol=1e-7)
    _, _, calib = read_sto(path.with_name("Raw_trial_001_calibration.sto"))
    t = [float(r[0]) for r in calib]
    assert len(calib) == 25 and t[0] > 0.45 and t[-1] < 1.05  # the Reset Zero window
    # the placer's rotation maps NED down to OpenSim's -y (y up)
    rot = euler_to_dcm(*SENSOR_TO_OPENSIM_ROTATIONS)
    np.testing.assert_allclose(rot @ [0, 0, 1], [0, -1, 0], atol=1e-12)


def test_bvh_reproduces_the_stick_figure_within_1mm(trial):
    rec, path, res = trial
    out = path.with_name("figure.bvh")
    assert main(["export", "bvh", str(path), "-o", str(out)]) == 0
    root = bvhio.readAsHierarchy(str(out))
    joints = {j.Name: j for j, _, _ in root.layout()}
    assert len(joints) == 1 + len(BODY_POINTS)
    expected = res.joint_positions @ NED_TO_BVH.T * 100.0  # cm, y up
    for frame in (40, 260, 700, 1000, len(rec) - 1):
        root.loadPose(frame)
        for k, p in enumerate(BODY_POINTS):
            got = np.array(joints[joint_name(k)].PositionWorld)
            np.testing.assert_allclose(got, expected[frame, POINT_INDEX[p.parent]], atol=0.1)
    # per-subject lengths: the thigh is 47 cm
    thigh = next(k for k, p in enumerate(BODY_POINTS) if p.name == "knee_r")
    child = joints[joint_name(thigh + 1)]
    assert np.linalg.norm(np.array(child.RestPose.Position)) == pytest.approx(47.0)


def test_exports_from_a_filtered_file_redo_reset_zero_like_the_api(trial):
    _, path, res = trial
    filtered = path.with_name("Filtered_trial_001.csv")
    assert main(["filter", str(path), "-o", str(filtered)]) == 0
    out = path.with_name("from_filtered.csv")
    assert main(["export", "matlab", str(filtered), "-o", str(out), "--radians"]) == 0
    lines = [ln for ln in out.read_text().splitlines() if not ln.startswith("%")]
    cols = lines[0].split(",")
    data = np.array([[float(c) for c in ln.split(",")] for ln in lines[1:]])
    joints = data[:, cols.index("joint_elbow_r_flexion_rad"):]
    # the filtered file keeps 10 significant digits
    np.testing.assert_allclose(joints, res.joint_angles, atol=1e-5, equal_nan=True)


def test_matlab_csv_has_a_header_and_the_api_values(trial):
    rec, path, res = trial
    out = path.with_name("m.csv")
    assert main(["export", "matlab", str(path), "-o", str(out)]) == 0
    lines = [ln for ln in out.read_text().splitlines() if not ln.startswith("%")]
    cols = lines[0].split(",")
    assert cols == matlab_columns() and len(cols) == 1 + 18 * 7 + 28
    assert cols[1:5] == ["imu0_right_leg_sensor_qw", "imu0_right_leg_sensor_qx",
                         "imu0_right_leg_sensor_qy", "imu0_right_leg_sensor_qz"]
    assert "joint_knee_r_flexion_deg" in cols
    data = np.array([[float(c) for c in ln.split(",")] for ln in lines[1:]])
    assert data.shape == (len(rec), len(cols))
    k = cols.index("joint_knee_r_flexion_deg")
    np.testing.assert_allclose(data[:, k], np.degrees(res.joint_angles[:, 2]), rtol=1e-6,
                               equal_nan=True)
    r = cols.index("imu6_hip_sensor_yaw_deg")
    np.testing.assert_allclose(data[:, r], np.degrees(res.euler[:, 6, 2]), rtol=1e-6)


def test_long_tables_show_progress_on_stderr(tmp_path, capsys):
    import io

    from bpms.analysis.textout import write_rows

    buffer = io.StringIO()
    write_rows(buffer, np.arange(30_001 * 2, dtype=float).reshape(-1, 2), "%.1f", ",",
               "writing long.csv")
    err = capsys.readouterr().err
    assert "writing long.csv: 100% (30001/30001 frames)" in err and " 33% " in err
    assert buffer.getvalue().count("\n") == 30_001
    write_rows(io.StringIO(), np.zeros((100, 2)), "%.1f")
    assert capsys.readouterr().err == ""
