"""One column-naming scheme across every output (docs/analysis.md, "Column names"): the same
quantity has the same name in the filtered file, the MATLAB CSV, Parquet, the .mat file's
names, LSL channel labels, bpms extract and the ROM tables. The expected names are written
here by hand from the docs' rule, not produced by the helpers under test."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from bpms.io.filtered_file.columns import column_groups, filtered_columns

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "docs" / "samples" / "Raw_simulated_arm_raise.bpmsraw"
#: GROUP_ITEM_QUANTITY[_UNIT], or one of the time and row columns.
SCHEME = re.compile(r"^(time_s|host_time_s|utc|hole|corrected|imu\d{1,2}_[a-z]+(_[a-z0-9]+)+|"
                    r"joint_[a-z]+_[rl]_[a-z]+(_[a-z_]+)?|joint_(torso|head)_[a-z]+(_[a-z_]+)?|"
                    r"point_[a-z]+(_[a-z]+)*_[xyz](_m)?)$")


def _all_names() -> dict[str, list[str]]:
    from bpms.analysis.binary_out import parquet_columns
    from bpms.analysis.matlab import matlab_columns
    from bpms.pipeline.lsl import (
        disturbance_channels,
        joint_channels,
        segment_channels,
        sensor_channels,
    )

    return {
        "filtered": filtered_columns(degrees=True, groups=list(column_groups())),
        "matlab": matlab_columns(),
        "parquet": parquet_columns(),
        "lsl": [c.label for f in (segment_channels, joint_channels, sensor_channels,
                                  disturbance_channels) for c in f()],
    }


def test_every_column_follows_the_scheme():
    for output, names in _all_names().items():
        bad = [n for n in names if not SCHEME.match(n)]
        assert bad == [], (output, bad[:5])
        assert len(set(names)) == len(names), output


def test_the_same_quantity_has_the_same_name_everywhere():
    names = _all_names()
    knee = "joint_knee_r_flexion"
    for output in ("filtered", "matlab", "parquet"):
        assert f"{knee}_deg" in names[output], output
    assert knee in names["lsl"]  # the unit is the channel's own field
    # the right leg segment's orientation after Reset Zero; the IMU's own filter attitude
    assert "imu0_right_leg_qw" in names["parquet"] and "imu0_right_leg_qw" in names["lsl"]
    assert "imu6_hip_sensor_yaw_deg" in names["matlab"]
    assert "imu6_hip_sensor_yaw_deg" in names["filtered"]
    assert "imu6_hip_yaw_deg" in names["filtered"]  # the output angles (segment after RZ)
    assert "imu5_right_forearm_mag_disturbed" in names["filtered"]
    assert "imu5_right_forearm_mag_disturbed" in names["lsl"]
    assert "imu0_right_leg_ax" in names["lsl"] and "point_head_top_z_m" in names["parquet"]


@pytest.mark.parametrize("fmt", ["mat", "rom", "extract"])
def test_the_files_use_the_names(tmp_path, fmt, monkeypatch):
    from bpms.cli import main

    monkeypatch.chdir(tmp_path)

    def bpms(*args: str) -> None:
        assert main(list(args)) == 0

    if fmt == "mat":
        import scipy.io as sio

        bpms("convert", str(SAMPLE), "-f", "mat", "-o", "t")
        m = sio.loadmat(tmp_path / "t.mat")
        assert [str(x[0][0]) for x in m["joint_names"]][2] == "joint_knee_r_flexion"
        assert str(m["segment_names"][0][0][0]) == "right_leg"
    elif fmt == "rom":
        bpms("rom", str(SAMPLE), "-o", "rom", "--no-figures")
        rows = [ln.split(",")[0] for ln in (tmp_path / "rom" / "rom.csv").read_text()
                .splitlines() if not ln.startswith("#")]
        assert rows[0] == "joint_angle" and "joint_knee_r_flexion" in rows
    else:
        bpms("extract", "raw", str(SAMPLE), "--imu", "0", "--calibrated", "-o", "x.csv")
        head = (tmp_path / "x.csv").read_text().splitlines()[0].split(",")
        assert head[:3] == ["time_s", "host_time_s", "imu0_right_leg_ax_m_s2"]
        assert all(SCHEME.match(n) for n in head)
