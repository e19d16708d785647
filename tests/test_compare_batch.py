"""``bpms batch --outputs compare`` (docs/compare.md, "In a study"): every recording with an
optical file beside it is compared; one without is reported, not skipped."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

from bpms.cli import main

SAMPLES = Path(__file__).resolve().parents[1] / "docs" / "samples"
RAW = SAMPLES / "Raw_simulated_arm_raise.bpmsraw"
OPTICAL = SAMPLES / "optical_simulated_arm_raise.csv"


def test_batch_compares_each_recording_with_its_optical_file(tmp_path, capsys):
    study = tmp_path / "study"
    (study / "S1").mkdir(parents=True)
    (study / "S2").mkdir()
    shutil.copy(RAW, study / "S1" / "arm.bpmsraw")
    shutil.copy(OPTICAL, study / "S1" / "arm.csv")
    (study / "S1" / "compare.map").write_text("RHumerus = Right Arm\nThorax = Spine\n",
                                              encoding="utf-8")
    shutil.copy(RAW, study / "S2" / "alone.bpmsraw")
    assert main(["batch", str(study), "--outputs", "rom,compare", "--workers", "1"]) == 0
    captured = capsys.readouterr()
    assert "compare: no optical file beside alone.bpmsraw" in captured.err
    out = study / "batch"
    assert (out / "S1" / "arm_compare.md").is_file()
    assert (out / "S1" / "arm_compare_series.csv").is_file()
    assert not list((out / "S2").glob("*_compare*"))
    with (out / "batch_compare.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert [(r["subject"], r["trial"], r["segment"]) for r in rows] == [
        ("S1", "arm", "Right Arm"), ("S1", "arm", "Spine")]
    # the same figures as the command on its own, with the same map
    assert main(["compare", str(study / "S1" / "arm.bpmsraw"), str(study / "S1" / "arm.csv"),
                 "--map", str(study / "S1" / "compare.map"), "--json", "--no-figures",
                 "-o", str(tmp_path / "alone")]) == 0
    doc = json.loads(capsys.readouterr().out)
    for row, seg in zip(rows, doc["segments"], strict=True):
        assert float(row["rmse_total"]) == round(seg["rmse_total"], 4)
