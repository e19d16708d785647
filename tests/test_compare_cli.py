"""``bpms compare`` as a command (docs/compare.md): the worked example of the page, the outputs,
the JSON document given back as ``--alignment``, and every refusal as one line with exit 2."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bpms.cli import main

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "docs" / "samples"
RAW = SAMPLES / "Raw_simulated_arm_raise.bpmsraw"
OPTICAL = SAMPLES / "optical_simulated_arm_raise.csv"


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    """The worked example, run as the page shows it (in a folder holding the two samples)."""
    folder = tmp_path_factory.mktemp("example")
    for f in (RAW, OPTICAL):
        shutil.copy(f, folder / f.name)
    done = subprocess.run([sys.executable, "-m", "bpms", "compare", RAW.name, OPTICAL.name,
                           "-o", "compare/"], cwd=folder, capture_output=True, text=True,
                          timeout=120, env=_env())
    assert done.returncode == 0, done.stderr
    return folder, done.stdout


def _env() -> dict:
    import os

    return {**os.environ, "PYTHONPATH": str(ROOT)}


def test_worked_example_prints_what_the_page_shows(example):
    folder, out = example
    page = (ROOT / "docs" / "compare.md").read_text(encoding="utf-8")
    block = re.search(r"```text\n(.*?)```", page[page.index("## A worked example"):], re.S)
    shown = [line for line in block.group(1).splitlines() if line.strip()]
    assert len(shown) >= 6
    for line in shown:
        assert line in out.splitlines(), line
    out_dir = folder / "compare"
    names = {p.name for p in out_dir.iterdir()}
    assert {"compare.csv", "compare.md", "compare_series.csv", "compare_errors.png",
            "compare_bland_altman.png"} <= names
    assert (out_dir / "compare.md").read_text(encoding="utf-8") == out


def test_the_sample_optical_file_is_what_the_tool_makes():
    done = subprocess.run([sys.executable, str(ROOT / "tools" / "make_compare_sample.py"),
                           "--check"], capture_output=True, text=True, timeout=120, env=_env())
    assert done.returncode == 0, done.stderr


def test_csv_holds_every_figure_of_the_report(example):
    folder, out = example
    rows = (folder / "compare" / "compare.csv").read_text(encoding="utf-8").splitlines()
    assert rows[0] == "section,name,figure,value,unit"
    cells = [r.split(",") for r in rows[1:]]
    rmse = {c[1]: float(c[3]) for c in cells if c[0] == "segment" and c[2] == "rmse_total"}
    # the report's RMSE column, rounded, is the CSV's
    for line in out.splitlines():
        m = re.match(r"\| (Subject:\w+) \| ([\w ]+) \| \d+ \| \d+ \| ([\d.]+) \|", line)
        if m:
            assert f"{rmse[f'{m.group(1)} / {m.group(2)}']:.2f}" == m.group(3)
    joints = {c[1] for c in cells if c[0] == "joint"}
    assert {"elbow_r.flexion", "torso.flexion"} <= joints
    series = (folder / "compare" / "compare_series.csv").read_text().splitlines()
    assert series[0].startswith("time_s,error_RHumerus_deg")
    # occluded samples are empty cells, not interpolated values
    assert any(",," in r for r in series[1:])


def test_json_and_alignment_given_back(tmp_path, capsys):
    assert main(["compare", str(RAW), str(OPTICAL), "--json", "--no-figures",
                 "-o", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert abs(doc["offset_s"] - 0.73) < 0.02
    assert len(doc["segments"]) == 6 and doc["joints"]
    first = {s["body"]: s["rmse_total"] for s in doc["segments"]}
    path = tmp_path / "alignment.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    assert main(["compare", str(RAW), str(OPTICAL), "--json", "--no-figures",
                 "--alignment", str(path), "--offset", str(doc["offset_s"]),
                 "-o", str(tmp_path)]) == 0
    again = json.loads(capsys.readouterr().out)
    for seg in again["segments"]:
        assert seg["alignment"]["mode"] == "given"
        assert seg["rmse_total"] == pytest.approx(first[seg["body"]], abs=1e-6)


def _refused(capsys, args: list[str], words: str) -> None:
    assert main(["compare", *args, "--no-figures"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err and "Traceback" not in "\n".join(err)
    assert words in err[-1], err
    assert err[-1].startswith("bpms compare: ")


def test_refusals_are_one_line_exit_2(tmp_path, capsys):
    out = ["-o", str(tmp_path / "out")]
    _refused(capsys, [str(RAW), str(OPTICAL), "--offset", "1000", *out], "overlap")
    bad = tmp_path / "bad.map"
    bad.write_text("RHumerus = Right Elbow\n", encoding="utf-8")
    _refused(capsys, [str(RAW), str(OPTICAL), "--map", str(bad), *out], "not a BPMS segment")
    missing = tmp_path / "missing.map"
    missing.write_text("# mine\nNobody = Right Arm\n", encoding="utf-8")
    _refused(capsys, [str(RAW), str(OPTICAL), "--map", str(missing), *out], "no body 'Nobody'")
    twice = tmp_path / "twice.map"
    twice.write_text("RHumerus = Right Arm\nLHumerus = 4\n", encoding="utf-8")
    _refused(capsys, [str(RAW), str(OPTICAL), "--map", str(twice), *out], "mapped twice")
    syntax = tmp_path / "syntax.map"
    syntax.write_text("RHumerus Right Arm\n", encoding="utf-8")
    _refused(capsys, [str(RAW), str(OPTICAL), "--map", str(syntax), *out], "line 1")
    junk = tmp_path / "junk.csv"
    junk.write_text("hello,world\n1,2\n", encoding="utf-8")
    _refused(capsys, [str(RAW), str(junk), *out], "not a Vicon Nexus CSV")
    other = tmp_path / "other.csv"
    other.write_text(OPTICAL.read_text().replace("Subject:", "Subject:X"), encoding="utf-8")
    _refused(capsys, [str(RAW), str(other), *out], "default map")
    short = tmp_path / "short.csv"
    short.write_text("\n".join(OPTICAL.read_text().splitlines()[:5 + 150]) + "\n")
    _refused(capsys, [str(RAW), str(short), "--offset", "8.5", *out], "overlap")
    _refused(capsys, [str(RAW), str(OPTICAL), "--alignment", str(junk), *out],
             "not an alignment document")
    # bodies of the standard names that move unlike anything in the recording
    from bpms.analysis.compare_align import exp_map
    from bpms.analysis.compare_synth import write_vicon_csv

    rng = np.random.default_rng(5)
    walk = np.cumsum(rng.normal(size=(1000, 3)) * 0.05, axis=0)
    unrelated = write_vicon_csv(tmp_path / "unrelated.csv", 100.0, {
        "RHumerus": (exp_map(walk), np.zeros((1000, 3)))})
    _refused(capsys, [str(RAW), str(unrelated), *out], "match the recording's at no offset")
    assert not (tmp_path / "out").exists()


def test_filtered_file_needs_the_orientation_alignment(tmp_path, capsys):
    """A filtered CSV has no raw sensors: 'sensors' refuses in one line, 'orientation'
    works, the clock offset found from the orientations' rates."""
    filtered = tmp_path / "arm.csv"
    assert main(["filter", str(RAW), "-o", str(filtered)]) == 0
    capsys.readouterr()
    _refused(capsys, [str(filtered), str(OPTICAL), "-o", str(tmp_path)], "--align orientation")
    assert main(["compare", str(filtered), str(OPTICAL), "--align", "orientation", "--json",
                 "--no-figures", "-o", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    # from the filter's orientations, not the gyros: its dynamics shift the found offset
    # (measured 0.705 s here, 1.3 samples early; from the gyros 0.731 s)
    assert abs(doc["offset_s"] - 0.73) < 0.04
    assert all(np.isfinite(s["rmse_total"]) for s in doc["segments"])


def test_window_limits_the_alignment_not_the_figures(tmp_path, capsys):
    args = [str(RAW), str(OPTICAL), "--json", "--no-figures", "-o", str(tmp_path)]
    assert main(["compare", *args]) == 0
    whole = json.loads(capsys.readouterr().out)
    assert main(["compare", *args, "--window", "2:9"]) == 0
    part = json.loads(capsys.readouterr().out)
    for a, b in zip(whole["segments"], part["segments"], strict=True):
        assert b["alignment"]["samples"] < a["alignment"]["samples"]
        assert b["samples"] == a["samples"]  # the figures still cover the whole overlap
    with pytest.raises(SystemExit) as stop:  # argparse's own refusal
        main(["compare", *args, "--window", "9:2"])
    assert stop.value.code == 2
    assert "END must be after START" in capsys.readouterr().err
