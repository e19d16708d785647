"""``bpms convert``: MATLAB v5 and Parquet exports read back with scipy and pyarrow, checked
against the simulated suit's true segment geometry and the recording's known start time."""

from __future__ import annotations

import datetime as dt
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import scipy.io as sio

from bpms.firmware.sim.session import simulate

ROOT = Path(__file__).resolve().parents[1]
START = 1.7e9  # the receive time of frame 0 in the saved recording
SECONDS = 8.0


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    rec = simulate(SECONDS, seed=3)
    folder = tmp_path_factory.mktemp("bin")
    raw = rec.save_raw(folder / "Raw_bin_001.bpmsraw", start_time=START)
    out = subprocess.run([sys.executable, "-m", "bpms", "convert", str(raw), "-o",
                          str(folder / "trial")], cwd=ROOT, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    return rec, folder / "trial.mat", folder / "trial.parquet", out.stdout


def _shoulder_flexion_truth(rec):
    C = rec.truth.C
    arm = np.einsum("nji,njk,k->ni", C[:, 15], C[:, 4], np.array([0.0, 0.0, 1.0]))
    return np.degrees(np.arctan2(arm[:, 0], arm[:, 2]))


def test_mat_file_has_names_units_time_and_utc_start(exported):
    rec, mat, _, stdout = exported
    m = sio.loadmat(mat)
    n = round(SECONDS * 50)
    assert m["t"].shape == (n, 1) and m["joint_angles"].shape == (n, 28)
    assert m["quaternions"].shape == (n, 18, 4) and m["joint_positions"].shape == (n, 21, 3)
    expected = dt.datetime.fromtimestamp(START, dt.UTC).strftime("%Y-%m-%dT%H:%M:%S")
    assert expected == "2023-11-14T22:13:20"
    assert str(m["utc_start"][0]).startswith(expected) and expected in stdout
    assert float(m["utc_start_posix"][0, 0]) == START
    names = [str(x[0][0]) for x in m["joint_names"]]
    assert names[2] == "joint_knee_r_flexion" and len(names) == 28
    assert str(m["joint_angle_convention"][0]).startswith("isb")
    assert m["units"]["joint_angles"][0, 0][0] == "deg"
    np.testing.assert_allclose(np.diff(m["t"][:, 0]), 0.02, atol=1e-9)
    # the script raises the right arm forward from 3 s: the exported angle follows the truth
    k = names.index("joint_shoulder_r_flexion")
    truth = _shoulder_flexion_truth(rec)
    late = slice(round(4.5 * 50), n)
    assert truth[late].max() > 40
    assert np.abs(m["joint_angles"][late, k] - truth[late]).max() < 5.0


def test_parquet_holds_the_same_numbers_with_utc_times(exported):
    _, mat, parquet, _ = exported
    table = pq.read_table(parquet)
    meta = json.loads(table.schema.metadata[b"bpms"])
    assert meta["utc_start"].startswith("2023-11-14T22:13:20")
    assert meta["units"]["joint_angles"] == "deg"
    m = sio.loadmat(mat)
    assert table.num_rows == len(m["t"])
    utc = table.column("utc").to_numpy().astype("datetime64[us]").astype(np.int64) / 1e6
    np.testing.assert_allclose(utc, START + m["t"][:, 0], atol=1e-6)
    np.testing.assert_allclose(table.column("joint_knee_r_flexion_deg").to_numpy(),
                               m["joint_angles"][:, 2])
    np.testing.assert_allclose(table.column("point_head_top_z_m").to_numpy(),
                               m["joint_positions"][:, 4, 2])


def test_streamed_mat_arrays_equal_the_whole_arrays(tmp_path):
    """Chunks of uneven size written into reserved space read back as the whole arrays
    (scipy's own reader is the judge)."""
    from bpms.analysis.mat5_stream import Mat5Stream

    rng = np.random.default_rng(0)
    n = 1003
    a = rng.normal(size=(n, 21, 3)).astype(np.float32)
    b = rng.normal(size=(n, 1))
    c = rng.normal(size=(n, 28)).astype(np.float32)
    stream = Mat5Stream(tmp_path / "s.mat", {"label": "x", "names": np.array(["p", "q"],
                                                                            dtype=object)},
                        {"a": (a.shape, np.float32), "b": (b.shape, np.float64),
                         "c": (c.shape, np.float32)})
    for lo, hi in ((0, 1), (1, 500), (500, 1003)):
        stream.write_rows("a", lo, a[lo:hi])
        stream.write_rows("c", lo, c[lo:hi])
        stream.write_rows("b", lo, b[lo:hi])
    stream.close()
    m = sio.loadmat(tmp_path / "s.mat")
    np.testing.assert_array_equal(m["a"], a)
    np.testing.assert_array_equal(m["b"], b)
    np.testing.assert_array_equal(m["c"], c)
    assert str(m["label"][0]) == "x"


def test_a_damaged_start_time_gives_null_timestamps_not_wrapped_integers(tmp_path):
    """A recording whose first receive time is damaged (1e300 s, NaN) still exports: its UTC
    column is null where no timestamp exists, and the stream times are written as they are."""
    from bpms.analysis.binary_out import ExportMeta, ParquetWriter
    from bpms.filter.processor import BodyPoseProcessor

    result = BodyPoseProcessor().process(simulate(0.4, seed=1).raw)
    for start in (1e300, float("nan")):
        path = tmp_path / f"damaged_{start}.parquet"
        writer = ParquetWriter(path, ExportMeta(utc_start=start))
        writer.write(result)
        writer.close()
        table = pq.read_table(path)
        assert table.num_rows == len(result)
        assert table.column("utc").null_count == len(result)
        np.testing.assert_array_equal(table.column("time_s").to_numpy(), result.t)
