"""The filtered file (issue 12.6): versioned header, host time, holes, column groups, and one
reader for every version, the original suite's header-less files included."""

from __future__ import annotations

import numpy as np
import pytest

from bpms.cli import main
from bpms.io.filtered_file.columns import ColumnGroup, column_groups, register_column_group
from bpms.io.filtered_file.reader import FilteredFileError, iter_filtered, read_filtered
from bpms.io.filtered_file.writer import FilteredWriter

START = 1354312345.678  # an epoch time (s) in December 2012, when the original suite ran


def _original_file(path, n=40, fmt="%.12g"):
    """A filtered file as the original suite wrote it (dissertation §2.3.2.4, the format
    description of the original code): no header; per line ``str(Time)`` — ``time.time()`` at
    the start plus 0.02 s per frame — then roll, pitch, yaw (rad) of IMU 0..17, every value
    followed by a comma. Python 2's ``str(float)`` prints 12 significant digits (``%.12g``)."""
    rng = np.random.default_rng(1)
    times = START + 0.02 * np.arange(n)
    euler = rng.uniform(-np.pi, np.pi, (n, 18, 3))
    with open(path, "w", newline="\n") as f:
        for k in range(n):
            f.write(fmt % times[k] + ",")
            for v in euler[k].reshape(-1):
                f.write(f"{v:.12g},")
            f.write("\n")
    return np.array([float(fmt % t) for t in times]), euler


def test_original_files_are_read_with_their_absolute_times(tmp_path):
    for fmt in ("%.12g", "%.3f"):  # Python 2 str(), and a file written with milliseconds
        path = tmp_path / f"Filtered_{len(fmt)}.txt"
        host, euler = _original_file(path, fmt=fmt)
        assert path.read_text().splitlines()[0].endswith(",")
        data = read_filtered(path)
        assert data.legacy and data.version == 0 and not data.problems
        np.testing.assert_allclose(data.host_time, host, rtol=0, atol=1e-6)
        np.testing.assert_allclose(data.t, host - host[0], rtol=0, atol=1e-6)
        np.testing.assert_allclose(data.euler, euler, rtol=1e-11)
        assert not data.hole.any() and data.joint_angles is None


def test_extract_filtered_keeps_the_original_absolute_time_to_the_millisecond(tmp_path, capsys):
    path = tmp_path / "Filtered_trial.txt"
    host, euler = _original_file(path, fmt="%.3f")
    out = tmp_path / "imu6.csv"
    assert main(["extract", "filtered", str(path), "--imu", "6", "-o", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert lines[0] == ("time_s,host_time_s,imu6_hip_roll_rad,imu6_hip_pitch_rad,"
                        "imu6_hip_yaw_rad")
    rows = [ln.split(",") for ln in lines[1:]]
    assert [r[1] for r in rows[:2]] == ["1354312345.678000", "1354312345.698000"]
    got = np.array([[float(c) for c in r] for r in rows])
    np.testing.assert_allclose(got[:, 1], host, rtol=0, atol=5e-4)
    np.testing.assert_allclose(got[:, 2:], euler[:, 6], rtol=1e-9)


def test_an_original_file_is_accepted_by_the_exports(tmp_path, capsys):
    path = tmp_path / "Filtered_trial.txt"
    _original_file(path, n=120)
    out = tmp_path / "m.csv"
    assert main(["export", "matlab", str(path), "-o", str(out)]) == 0
    assert "calibration: not used" in capsys.readouterr().err
    lines = out.read_text().splitlines()
    assert len([ln for ln in lines if not ln.startswith("%")]) == 1 + 120
    # the original's absolute time is the recording's UTC start: 1354312345.68 s as written
    # with Python 2's 12 significant digits, by hand 2012-11-30 21:52:25.68 UTC
    assert lines[0] == "% utc_start: 2012-11-30T21:52:25.680Z"


def test_version_2_round_trip_with_host_time_holes_and_header(tmp_path):
    rng = np.random.default_rng(0)
    n = 9
    t = np.arange(n) * 0.02
    host = START + t
    euler = rng.uniform(-3, 3, (n, 18, 3))
    joints = rng.uniform(-2, 2, (n, 28))
    path = tmp_path / "f.csv"
    with FilteredWriter(path, joints=True, euler="segment", meta={"subject": "S01"}) as w:
        w.write_block(t[:4], euler[:4], joints[:4], host_time=host[:4])
        w.write_holes(t[4:6], host[4:6])
        w.write_block(t[6:], euler[6:], joints[6:], host_time=host[6:])
    head = path.read_text().splitlines()[:6]
    assert head[0] == "# bpms-filtered-file 2" and "# euler: segment" in head
    data = read_filtered(path)
    assert data.version == 2 and data.info.euler_kind == "segment"
    assert data.info.meta["subject"] == "S01"
    assert list(data.hole) == [False] * 4 + [True] * 2 + [False] * 3
    np.testing.assert_allclose(data.host_time, host, rtol=0, atol=1e-6)
    keep = ~data.hole
    np.testing.assert_allclose(data.euler[keep], euler[keep], rtol=1e-9)
    np.testing.assert_allclose(data.joint_angles[keep], joints[keep], rtol=1e-9)
    assert np.isnan(data.euler[data.hole]).all()


def test_a_column_group_is_one_call_and_unknown_groups_survive(tmp_path):
    if "test_flags" not in column_groups():
        register_column_group(ColumnGroup(
            "test_flags", lambda unit: [f"imu{i}_test_flag" for i in range(18)], (18,),
            fmt="%d", description="a test group"))
    with pytest.raises(ValueError, match="already exists"):
        register_column_group(ColumnGroup("other", lambda unit: ["hole"], (1,)))
    flags = np.zeros((3, 18))
    flags[1, 4] = 1
    path = tmp_path / "g.csv"
    with FilteredWriter(path, groups=["euler", "test_flags"]) as w:
        w.write_block(np.arange(3) * 0.02, np.zeros((3, 18, 3)), test_flags=flags)
    info, blocks, _ = iter_filtered(path)
    assert info.groups == ["euler", "test_flags"]
    np.testing.assert_array_equal(next(blocks).groups["test_flags"], flags)
    # a reader that does not know a group keeps its columns by name
    text = path.read_text().replace("imu4_test_flag", "imu4_future_flag")
    other = tmp_path / "h.csv"
    other.write_text(text.replace("test_flags", "future"))
    with pytest.raises(FilteredFileError, match="incomplete"):
        read_filtered(other)
    future = tmp_path / "k.csv"
    future.write_text("\n".join(
        ln if ln.startswith("#") or not ln.startswith("time_s") else
        ln.replace("_test_flag", "_future_flag") for ln in text.splitlines()) + "\n")
    data = read_filtered(future)
    assert data.extra["imu4_future_flag"][1] == 1 and "imu0_future_flag" in data.extra


def test_newer_versions_and_foreign_files_are_one_line_errors(tmp_path):
    newer = tmp_path / "n.csv"
    newer.write_text("# bpms-filtered-file 99\ntime_s\n")
    with pytest.raises(FilteredFileError, match="newer than this software"):
        read_filtered(newer)
    for text in ("", "a,b\n1,2\n", "1,2,3,\n"):
        bad = tmp_path / "bad.csv"
        bad.write_text(text)
        with pytest.raises(FilteredFileError):
            read_filtered(bad)


def test_flag_columns_are_written_as_the_row_format_writes_them(tmp_path):
    # The 0/1 flag columns, and any other value in them (NaN, -0.0, 2): the text must be what
    # the row's printf format gives.
    import io

    from bpms.io.filtered_file.writer import FilteredWriter

    groups = ["euler", "corrected", "joints", "reinitialised", "mag_disturbed"]
    rng = np.random.default_rng(0)
    n = 12
    flags = (rng.random((n, 18)) < 0.3).astype(float)
    cases = [flags, np.where(np.arange(18) == 4, np.nan, flags), flags * -0.0 + flags,
             np.where(np.arange(18) == 2, -0.0, flags), flags * 2]
    for values in cases:
        out = io.StringIO()
        writer = FilteredWriter(out, groups=groups)
        arrays = {"euler": rng.normal(size=(n, 18, 3)), "corrected": np.ones((n, 1)),
                  "joints": rng.normal(size=(n, 28)), "reinitialised": values,
                  "mag_disturbed": values[:, ::-1]}
        writer.write_block(np.arange(n) * 0.02, arrays["euler"], arrays["joints"],
                           host_time=1.7e9 + np.arange(n), corrected=arrays["corrected"],
                           reinitialised=values, mag_disturbed=values[:, ::-1])
        rows = out.getvalue().splitlines()[-n:]
        block = np.column_stack([np.arange(n) * 0.02, 1.7e9 + np.arange(n), np.zeros(n),
                                 arrays["euler"].reshape(n, -1), arrays["corrected"],
                                 arrays["joints"], values, values[:, ::-1]])
        fmt = ",".join(["%.10g", "%.6f", "%d"] + ["%.10g"] * 54 + ["%.0f"] + ["%.10g"] * 28
                       + ["%.0f"] * 36)  # the columns' formats (docs/filtered-file.md)
        assert rows == [fmt % tuple(r) for r in block.tolist()]
