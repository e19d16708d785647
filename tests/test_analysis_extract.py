"""Translators: ``bpms extract raw|filtered|vicon|qualisys`` on real files."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bpms.analysis.mocap_import import MocapFormatError, read_qualisys, read_vicon
from bpms.cli import main
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from bpms.io.filtered_file.writer import FilteredWriter
from bpms.io.rawfile import new_header, write_raw

DATA = Path(__file__).parent / "data"


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    lines = path.read_text().splitlines()
    return lines[0].split(","), np.array([[float(c) for c in ln.split(",")] for ln in lines[1:]])


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    rec = simulate(duration_s=4.0, seed=2, error_rate=0.001)
    path = tmp_path_factory.mktemp("raw") / "Raw_x_001.bpmsraw"
    rec.save_raw(path)
    return rec, path


def test_extract_raw_counts_and_calibrated_equal_the_api(recording, tmp_path):
    rec, path = recording
    out = tmp_path / "raw.csv"
    assert main(["extract", "raw", str(path), "--imu", "0", "5", "-o", str(out)]) == 0
    cols, data = read_csv(out)
    assert cols[:3] == ["time_s", "host_time_s", "imu0_right_leg_ax_counts"]
    assert cols[-1] == "imu5_right_forearm_gz_counts" and len(cols) == 2 + 18
    np.testing.assert_array_equal(data[:, 2:11], rec.raw[:, 0])
    np.testing.assert_array_equal(data[:, 11:20], rec.raw[:, 5])
    np.testing.assert_allclose(data[:, 0], rec.t, atol=1e-9)

    cal_out = tmp_path / "cal.csv"
    assert main(["extract", "raw", str(path), "--imu", "all", "--calibrated",
                 "-o", str(cal_out)]) == 0
    cols, data = read_csv(cal_out)
    assert cols[2] == "imu0_right_leg_ax_m_s2" and cols[5] == "imu0_right_leg_mx_gauss"
    assert len(cols) == 2 + 18 * 9
    api = BodyPoseProcessor(rec.calibration)
    acc, mag, gyr = api.sensor_calibration.physical_units(rec.raw)
    expected = np.concatenate([acc, mag, gyr], axis=-1).reshape(len(rec), -1)
    np.testing.assert_allclose(data[:, 2:], expected, rtol=1e-8, atol=1e-9)


def test_extract_filtered_equals_the_api(recording, tmp_path):
    rec, _ = recording
    res = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors)
    filtered = tmp_path / "Filtered.csv"
    with FilteredWriter(filtered) as w:
        w.write_block(res.t, res.euler)
    out = tmp_path / "euler.csv"
    assert main(["extract", "filtered", str(filtered), "--imu", "6,17", "--degrees",
                 "-o", str(out)]) == 0
    cols, data = read_csv(out)
    assert cols == ["time_s", "host_time_s", "imu6_hip_roll_deg", "imu6_hip_pitch_deg",
                    "imu6_hip_yaw_deg", "imu17_head_roll_deg", "imu17_head_pitch_deg",
                    "imu17_head_yaw_deg"]
    np.testing.assert_allclose(data[:, 2:5], np.degrees(res.euler[:, 6]), rtol=1e-8,
                               equal_nan=True)
    np.testing.assert_allclose(data[:, 5:8], np.degrees(res.euler[:, 17]), rtol=1e-8,
                               equal_nan=True)


def test_unknown_imu_lists_the_available_ids(recording, tmp_path, capsys):
    _, path = recording
    assert main(["extract", "raw", str(path), "--imu", "18", "-o", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "no IMU '18'" in err and "17 (Head)" in err and "Traceback" not in err


def test_empty_inputs_are_one_line_errors(tmp_path, capsys):
    empty = tmp_path / "Raw_empty.bpmsraw"
    write_raw(empty, np.zeros(0), b"", new_header())
    filtered = tmp_path / "Filtered_empty.csv"
    FilteredWriter(filtered).close()
    for argv in (["raw", str(empty)], ["filtered", str(filtered)]):
        assert main(["extract", *argv, "--imu", "1", "-o", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert "holds no frames" in err and "holds no rows" in err and "Traceback" not in err
    for argv in (["rom", str(empty), "-o", str(tmp_path)], ["track", str(empty)],
                 ["export", "bvh", str(empty)]):
        assert main(argv) == 2
    assert capsys.readouterr().err.count("holds no frames") == 3


def test_vicon_sample_file():
    export = read_vicon(DATA / "vicon_nexus.csv")
    assert export.rate_hz == 100 and set(export.bodies) >= {"Subject:Pelvis", "Subject:LASI"}
    pelvis = export.body("pelvis")
    np.testing.assert_allclose(pelvis.quaternion[0], [np.sqrt(0.5), 0, 0, np.sqrt(0.5)])
    np.testing.assert_allclose(pelvis.position[1], [101.5, 200.5, 951])
    assert np.isnan(pelvis.quaternion[2]).all()  # a gap
    np.testing.assert_allclose(export.body("Subject:Thorax").t, [0, 0.01, 0.02])
    assert export.body("LASI").quaternion is None


def test_qualisys_sample_file():
    export = read_qualisys(DATA / "qualisys_6d.tsv")
    pelvis = export.body("Pelvis")
    np.testing.assert_allclose(pelvis.quaternion[0], [np.sqrt(0.5), 0, 0, np.sqrt(0.5)],
                               atol=1e-12)
    np.testing.assert_allclose(pelvis.euler[0], [0, 0, 90])
    np.testing.assert_allclose(export.body("thorax").quaternion[2], [1, 0, 0, 0])


def test_extract_mocap_bodies_to_csv(tmp_path, capsys):
    out = tmp_path / "pelvis.csv"
    assert main(["extract", "qualisys", str(DATA / "qualisys_6d.tsv"), "--body", "Pelvis",
                 "-o", str(out)]) == 0
    cols, data = read_csv(out)
    assert cols == ["time_s", "frame", "x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz",
                    "roll_deg", "pitch_deg", "yaw_deg"]
    assert data.shape == (3, 12)
    assert main(["extract", "vicon", str(DATA / "vicon_nexus.csv"), "--body", "Femur",
                 "-o", str(tmp_path / "f.csv")]) == 2
    err = capsys.readouterr().err
    assert "no body 'Femur'" in err and "Subject:Pelvis" in err and "Subject:Thorax" in err


@pytest.mark.parametrize(("name", "edit", "expected"), [
    ("vicon_nexus.csv", lambda s: s.replace("2,0,0,0,90", "2,0,0,x,90"), "line 7: 'x' is not"),
    ("vicon_nexus.csv", lambda s: s.replace("2,0,0,0,90,101.5", "2,0,0,0,90,101.5,7,7,7,7"),
     "line 7: 18 values, expected 14"),
    ("vicon_nexus.csv", lambda s: s.replace("RX,RY,RZ,TX", "RX,RY,TX,TX", 1), "line 4: columns"),
    ("vicon_nexus.csv", lambda s: "hello\n", "line 1: no 'Segments'"),
    ("qualisys_6d.tsv", lambda s: s.replace("\t200.25", "\tabc", 1), "line 12: 'abc' is not"),
    ("qualisys_6d.tsv", lambda s: s.replace("BODY_NAMES\tPelvis", "BODY_NAMES\tHead"),
     "line 11: column 3 is 'Pelvis', expected body 'Head'"),
    ("qualisys_6d.tsv", lambda s: s.rsplit("\t", 1)[0] + "\n", "line 14: 33 values, expected 34"),
])
def test_malformed_exports_name_the_line(tmp_path, name, edit, expected):
    bad = tmp_path / name
    bad.write_text(edit((DATA / name).read_text()))
    reader = read_vicon if name.endswith(".csv") else read_qualisys
    with pytest.raises(MocapFormatError, match=expected):
        reader(bad)
    kind = "vicon" if name.endswith(".csv") else "qualisys"
    assert main(["extract", kind, str(bad), "--body", "Pelvis", "-o", str(tmp_path / "o")]) == 2


def test_malformed_filtered_file_names_the_problem(tmp_path, capsys):
    bad = tmp_path / "Filtered.csv"
    bad.write_text("time_s,a,b\n0,1,2\n")
    assert main(["extract", "filtered", str(bad), "--imu", "0", "-o", str(tmp_path / "o")]) == 2
    assert "not a filtered file" in capsys.readouterr().err


def test_missing_arguments_without_a_terminal_are_a_usage_error(recording, tmp_path):
    _, path = recording
    proc = subprocess.run([sys.executable, "-m", "bpms", "extract", "raw", str(path)],
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert "missing IMU id(s)" in proc.stderr and "usage" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_missing_arguments_are_asked_for_on_a_terminal(recording, tmp_path):
    _, path = recording
    out = tmp_path / "asked.csv"
    master, slave = os.openpty()
    try:
        proc = subprocess.Popen([sys.executable, "-m", "bpms", "extract", "raw", str(path)],
                                stdin=slave, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        os.write(master, f"3\n{out}\n".encode())
        _, err = proc.communicate(timeout=60)
    finally:
        os.close(slave)
        os.close(master)
    assert proc.returncode == 0, err
    cols, data = read_csv(out)
    assert cols[2] == "imu3_right_hand_ax_counts" and len(data) == 200
    assert b"available IMUs" in err
