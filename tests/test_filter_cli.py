"""The filtered CSV file and ``bpms filter`` on a recording made from simulated data."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from bpms.cli import main
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.session import simulate
from bpms.io.filtered_file.columns import filtered_columns
from bpms.io.filtered_file.reader import FilteredFileError, read_filtered
from bpms.io.filtered_file.writer import FilteredWriter, default_output_path
from bpms.io.rawfile import RECORD_SIZE, new_header, write_raw


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    rec = simulate(duration_s=6.0, seed=4, error_rate=0.001)
    path = tmp_path_factory.mktemp("raw") / "Raw_trial_001.bpmsraw"
    rec.save_raw(path)
    return rec, path


def test_columns_name_every_value_with_its_unit():
    cols = filtered_columns()
    assert len(cols) == 3 + 54 and cols[:3] == ["time_s", "host_time_s", "hole"]
    assert cols[3:6] == ["imu0_right_leg_roll_rad", "imu0_right_leg_pitch_rad",
                         "imu0_right_leg_yaw_rad"]
    assert cols[-1] == "imu17_head_yaw_rad"
    deg = filtered_columns(degrees=True, joints=True)
    assert len(deg) == 57 + 28 and deg[-1].endswith("_deg") and "joint_knee_r_flexion_deg" in deg


def test_writer_reader_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    t = np.arange(7) * 0.02
    euler = rng.uniform(-3, 3, (7, 18, 3))
    euler[0, 5] = np.nan
    joints = rng.uniform(-2, 2, (7, 28))
    for degrees in (False, True):
        path = tmp_path / f"f{degrees}.csv"
        with FilteredWriter(path, degrees=degrees, joints=True) as w:
            w.write_block(t[:4], euler[:4], joints[:4])
            for k in range(4, 7):
                w.write(t[k], euler[k], joints[k])
        data = read_filtered(path)
        assert data.unit == ("deg" if degrees else "rad") and not data.legacy
        np.testing.assert_allclose(data.euler, euler, rtol=1e-9, equal_nan=True)
        np.testing.assert_allclose(data.joint_angles, joints, rtol=1e-9)
        np.testing.assert_allclose(data.t, t)


def test_reader_accepts_legacy_headerless_layout(tmp_path):
    rows = np.arange(3 * 55, dtype=float).reshape(3, 55) / 100
    path = tmp_path / "Filtered.txt"
    path.write_text("\n".join(", ".join(str(float(v)) for v in row) for row in rows) + "\n")
    data = read_filtered(path)
    assert data.legacy and data.joint_angles is None
    np.testing.assert_allclose(data.euler[1, 2], rows[1, 7:10])
    bad = tmp_path / "bad.csv"
    bad.write_text("a,b,c\n1,2,3\n")
    with pytest.raises(FilteredFileError):
        read_filtered(bad)


def test_bpms_filter_writes_one_row_per_frame_like_the_api(recording, tmp_path):
    rec, raw_path = recording
    out = tmp_path / "out.csv"
    assert main(["filter", str(raw_path), "-o", str(out), "--joints"]) == 0
    data = read_filtered(out)
    api = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors)
    assert len(data.t) == len(rec)
    np.testing.assert_allclose(data.t, np.arange(len(rec)) * 0.02, atol=1e-12)
    np.testing.assert_allclose(data.euler, api.euler_output, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(data.joint_angles, api.joint_angles, rtol=1e-9, atol=1e-12)
    # degrees, default output name beside the raw file
    assert main(["filter", str(raw_path), "--degrees"]) == 0
    deg = read_filtered(default_output_path(raw_path))
    assert default_output_path(raw_path).name == "Filtered_trial_001.csv"
    assert deg.unit == "deg"
    np.testing.assert_allclose(deg.euler, api.euler_output, rtol=1e-9, atol=1e-12)


def _run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bpms", "filter", *args], capture_output=True,
                          text=True, timeout=60)


def test_bad_inputs_give_one_line_and_nonzero_exit(tmp_path, recording):
    _, raw_path = recording
    not_raw = tmp_path / "notes.bpmsraw"
    not_raw.write_text("hello")
    cut = tmp_path / "cut.bpmsraw"
    cut.write_bytes(raw_path.read_bytes()[:40])  # inside the header
    for path in (tmp_path / "missing.bpmsraw", not_raw, cut):
        proc = _run_cli(str(path), "-o", str(tmp_path / "x.csv"))
        assert proc.returncode != 0
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("bpms filter: "), proc.stderr
        assert "Traceback" not in proc.stderr
    assert not (tmp_path / "x.csv").exists()


def test_torn_last_record_is_filtered_with_a_warning(tmp_path, recording):
    rec, raw_path = recording
    torn = tmp_path / "torn.bpmsraw"
    torn.write_bytes(raw_path.read_bytes()[: -RECORD_SIZE // 2])
    out = tmp_path / "torn.csv"
    proc = _run_cli(str(torn), "-o", str(out))
    assert proc.returncode == 0
    assert "incomplete" in proc.stderr
    assert len(read_filtered(out).t) == len(rec) - 1


def test_bpms_filter_reads_legacy_pickled_raw_files(tmp_path):
    """The original suite's raw file (pickled [time, frame] records) filters like the API."""
    import pickle

    rec = simulate(duration_s=2.0, seed=6)
    path = tmp_path / "Raw_legacy.txt"
    with path.open("wb") as f:
        for k in range(len(rec)):
            frame = rec.frames[340 * k: 340 * (k + 1)].decode("latin1")  # a Python 2 str
            pickle.dump([1.3e9 + 0.02 * k, frame], f, protocol=0)
    out = tmp_path / "legacy.csv"
    assert main(["filter", str(path), "-o", str(out)]) == 0
    data = read_filtered(out)
    api = BodyPoseProcessor().process(rec.raw, rec.errors)  # no calibration stored: factory
    np.testing.assert_allclose(data.euler, api.euler_output, rtol=1e-9, atol=1e-12)


def test_bpms_filter_uses_the_options_stored_in_the_recording(tmp_path):
    from bpms.io.options import Options

    rec = simulate(duration_s=3.0, seed=8)
    path = tmp_path / "Raw_opts.bpmsraw"
    header = new_header(calibration=rec.calibration.values,
                        options={"filter": {"kp_yaw": 0.3, "kp_rollpitch": 0.05}})
    write_raw(path, rec.t, rec.frames, header)
    out = tmp_path / "opts.csv"
    assert main(["filter", str(path), "-o", str(out)]) == 0
    opts = Options()
    opts.filter.kp_yaw, opts.filter.kp_rollpitch = 0.3, 0.05
    api = BodyPoseProcessor(rec.calibration, opts).process(rec.raw, rec.errors)
    factory = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors)
    got = read_filtered(out).euler
    np.testing.assert_allclose(got, api.euler_output, rtol=1e-9, atol=1e-12)
    assert not np.allclose(got, factory.euler_output)
