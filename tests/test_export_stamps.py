"""Every export states the recording's UTC start and the joint-angle convention (issue 16.5):
OpenSim .sto header, MATLAB CSV comment lines, ``bpms rom`` CSV and Markdown, and the stderr
line (the only place for BVH, which has no comments)."""

from __future__ import annotations

import datetime as dt

import pytest

from bpms.cli import main
from bpms.filter.joints import CONVENTION_TEXT
from bpms.firmware.sim.session import simulate
from bpms.io.options import HEADING_TEXT
from bpms.io.rawfile import new_header, write_raw

T0 = 1_700_000_000.25  # the first frame's receive time, s since 1970
UTC = "2023-11-14T22:13:20.250Z"  # T0 written out by hand (date -u -d @1700000000)


@pytest.fixture(scope="module")
def trial(tmp_path_factory):
    rec = simulate(duration_s=4.0, seed=9)
    path = tmp_path_factory.mktemp("stamp") / "Raw_stamp_001.bpmsraw"
    write_raw(path, T0 + rec.t, rec.frames,
              new_header(calibration=rec.calibration.values,
                         options={"joints": {"convention": "original"}}))
    return path


def test_the_hand_written_utc_is_right():
    assert dt.datetime.fromtimestamp(int(T0), dt.UTC).isoformat() == "2023-11-14T22:13:20+00:00"


def test_opensim_header_states_start_and_convention(trial, capsys):
    assert main(["export", "opensim", str(trial), "--force"]) == 0
    text = trial.with_name("Raw_stamp_001_orientations.sto").read_text()
    header = dict(ln.split("=", 1) for ln in text.split("endheader")[0].splitlines())
    assert header["utc_start"] == UTC
    assert header["joint_angle_convention"] == CONVENTION_TEXT["original"]
    assert header["heading"] == HEADING_TEXT["magnetic"]
    err = capsys.readouterr().err
    assert f"recording started {UTC} UTC" in err


def test_matlab_csv_comment_lines(trial, tmp_path):
    out = tmp_path / "m.csv"
    assert main(["export", "matlab", str(trial), "-o", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert lines[0] == f"% utc_start: {UTC}"
    assert lines[1] == f"% joint_angle_convention: {CONVENTION_TEXT['original']}"
    assert lines[2] == f"% heading: {HEADING_TEXT['magnetic']}"
    assert lines[3].startswith("time_s,")


def test_bvh_states_them_on_stderr(trial, tmp_path, capsys):
    assert main(["export", "bvh", str(trial), "-o", str(tmp_path / "f.bvh")]) == 0
    err = capsys.readouterr().err
    assert f"recording started {UTC} UTC; joint angles: {CONVENTION_TEXT['original']}" in err


def test_rom_csv_and_markdown(trial, tmp_path):
    assert main(["rom", str(trial), "-o", str(tmp_path), "--no-figures"]) == 0
    csv = (tmp_path / "rom.csv").read_text().splitlines()
    assert csv[0] == (f"# Raw_stamp_001: utc_start {UTC}; joint_angle_convention "
                      f"{CONVENTION_TEXT['original']}; heading {HEADING_TEXT['magnetic']}")
    assert csv[1].startswith("joint_angle,")
    md = (tmp_path / "rom.md").read_text()
    assert f"- Raw_stamp_001: recording started {UTC} UTC" in md
    assert CONVENTION_TEXT["original"] in md
