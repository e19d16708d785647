"""Every export states the recording's UTC start and the joint-angle convention (issue 16.5)
and where it came from (issue 43.5: bpms version, filter, Reset Zero, recording): OpenSim .sto
header, MATLAB CSV comment lines, C3D parameters, .mat variables, Parquet schema metadata,
``bpms rom`` CSV and Markdown, and stderr (the only place for BVH: its readers accept no
comment)."""

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
    assert lines[3].startswith("% bpms_version: ")
    assert lines[7].startswith("time_s,")


def test_bvh_states_them_on_stderr(trial, tmp_path, capsys):
    assert main(["export", "bvh", str(trial), "-o", str(tmp_path / "f.bvh")]) == 0
    err = capsys.readouterr().err
    assert f"recording started {UTC} UTC; joint angles: {CONVENTION_TEXT['original']}" in err


def test_rom_csv_and_markdown(trial, tmp_path):
    assert main(["rom", str(trial), "-o", str(tmp_path), "--no-figures"]) == 0
    csv = (tmp_path / "rom.csv").read_text().splitlines()
    assert csv[0].startswith(f"# Raw_stamp_001: utc_start {UTC}; joint_angle_convention "
                             f"{CONVENTION_TEXT['original']}; heading "
                             f"{HEADING_TEXT['magnetic']}; bpms_version ")
    assert csv[1].startswith("joint_angle,")
    md = (tmp_path / "rom.md").read_text()
    assert f"- Raw_stamp_001: recording started {UTC} UTC" in md
    assert CONVENTION_TEXT["original"] in md


def _expected_origin(trial, algorithm="mahony"):
    """What the provenance must say, written from the test's own knowledge: the package's
    version, the filter asked for with its factory gains, the Reset Zero the file implies."""
    import bpms

    return {"bpms_version": bpms.__version__, "filter": algorithm,
            "reset_zero": "automatic Reset Zero", "recording": trial.name}


def _check_origin(found: dict, trial, algorithm="mahony"):
    want = _expected_origin(trial, algorithm)
    assert found["bpms_version"].startswith(want["bpms_version"])
    assert found["filter"].startswith(f"{algorithm} (")
    assert "dt 0.02" in found["filter"]
    assert found["reset_zero"].startswith(want["reset_zero"])
    assert found["recording"] == want["recording"]


def test_every_format_states_its_provenance(trial, tmp_path, capsys):
    """One test over every format's own metadata place (issue 43.5)."""
    ezc3d = pytest.importorskip("ezc3d")
    pq = pytest.importorskip("pyarrow.parquet")
    from scipy.io import loadmat

    from bpms.analysis.stream_export import export_recording

    stem = tmp_path / "o"
    assert main(["export", "c3d", str(trial), "-o", str(stem), "--filter", "observer"]) == 0
    bpms_group = ezc3d.c3d(str(stem.with_suffix(".c3d")))["parameters"]["BPMS"]
    _check_origin({k.lower(): bpms_group[k]["value"][0] for k in
                   ("BPMS_VERSION", "FILTER", "RESET_ZERO", "RECORDING")}, trial, "observer")
    assert main(["export", "opensim", str(trial), "-o", str(stem)]) == 0
    head = tmp_path.joinpath("o_orientations.sto").read_text().split("endheader")[0]
    _check_origin(dict(ln.split("=", 1) for ln in head.splitlines()), trial)
    assert main(["export", "bvh", str(trial), "-o", str(stem)]) == 0
    err = capsys.readouterr().err
    _check_origin(dict(ln.split(": ", 2)[1:] for ln in err.splitlines()
                       if ln.startswith("bpms export: ") and ln.count(": ") >= 2
                       and ln.split(": ")[1] in ("bpms_version", "filter", "reset_zero",
                                                  "recording")), trial)
    export_recording(trial, {"mat": tmp_path / "o.mat", "parquet": tmp_path / "o.parquet"})
    mat = loadmat(tmp_path / "o.mat")
    _check_origin({k: str(mat[k][0]) for k in ("bpms_version", "filter", "reset_zero",
                                                "recording")}, trial)
    import json

    meta = json.loads(pq.read_schema(tmp_path / "o.parquet").metadata[b"bpms"])
    _check_origin(meta, trial)


def test_version_names_the_commit_in_a_checkout():
    """Run from this git checkout, the version names the commit git reports."""
    import shutil
    import subprocess
    from pathlib import Path

    import bpms
    from bpms.analysis.stamp import bpms_version

    root = Path(bpms.__file__).resolve().parent.parent
    if shutil.which("git") is None or not (root / ".git").exists():
        pytest.skip("not a git checkout with git installed")
    head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                          text=True, check=True).stdout.strip()
    text = bpms_version()
    assert text.startswith(f"{bpms.__version__} (commit ")
    assert head.startswith(text.split("commit ")[1].rstrip(")").removesuffix("+dirty"))
