"""``bpms batch``: a small study (2 subjects × 2 trials + a broken file) through 2 worker
processes; the tidy table checked against the simulated suit's true segment geometry."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.io as sio

from bpms.analysis.batch import find_recordings
from bpms.firmware.sim.session import simulate

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("study")
    truth = {}
    for subject in ("S01", "S02"):
        (folder / subject).mkdir()
        for trial in (1, 2):
            rec = simulate(9.0, seed=len(truth) + 20)
            name = f"Raw_trial_00{trial}"
            rec.save_raw(folder / subject / f"{name}.bpmsraw")
            C = rec.truth.C
            arm = np.einsum("nji,njk,k->ni", C[:, 15], C[:, 4], np.array([0.0, 0.0, 1.0]))
            truth[(subject, name)] = np.degrees(np.arctan2(arm[:, 0], arm[:, 2])).max()
    (folder / "S02" / "Raw_broken_003.bpmsraw").write_bytes(b"not a recording at all")
    (folder / "notes.txt").write_text("a text file that is no recording\n")
    return folder, truth


def test_batch_writes_a_tidy_table_summary_and_outputs(study):
    folder, truth = study
    assert len(find_recordings(folder)) == 5  # 4 good + the broken one; notes.txt is not
    out = subprocess.run([sys.executable, "-m", "bpms", "batch", str(folder), "--workers", "2",
                          "--outputs", "rom,mat"], cwd=ROOT, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 1, out.stderr  # a recording could not be processed: incomplete
    assert "INCOMPLETE: 1 recording(s) could not be processed" in out.stderr
    assert "[5/5]" in out.stdout and "skipped" in out.stderr and "Raw_broken_003" in out.stderr
    batch = folder / "batch"
    with open(batch / "batch_rom.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4 * 28
    assert {(r["subject"], r["trial"]) for r in rows} == set(truth)
    for (subject, trial), flexion_max in truth.items():
        row = next(r for r in rows if r["subject"] == subject and r["trial"] == trial
                   and r["joint"] == "joint_shoulder_r_flexion")
        assert flexion_max > 50  # the script's forward arm raise
        assert float(row["max_deg"]) == pytest.approx(flexion_max, abs=5.0)
        assert float(row["range_deg"]) == pytest.approx(
            float(row["max_deg"]) - float(row["min_deg"]), abs=1e-3)
        assert row["convention"] == "isb" and row["utc_start"].startswith("2023-11-14T22:13:20")
        m = sio.loadmat(batch / subject / f"{trial}.mat")
        assert m["joint_angles"].shape == (450, 28)
    summary = (batch / "batch_summary.md").read_text()
    assert "processed: 4; skipped: 1" in summary and "Raw_broken_003" in summary
    assert "subject and trial from the file naming rules" in summary
    assert "batch_rom.png" in summary and (batch / "batch_rom.png").stat().st_size > 1000


def test_batch_without_recordings_is_a_clear_error(tmp_path):
    out = subprocess.run([sys.executable, "-m", "bpms", "batch", str(tmp_path)], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode != 0 and "no raw recording found" in out.stderr
    assert "Traceback" not in out.stderr


def test_batch_runs_under_spawn_as_on_windows(study, tmp_path):
    """The worker function and its arguments survive the "spawn" start method (Windows)."""
    from bpms.analysis.batch import run_batch

    folder, truth = study
    jobs = [j for j in find_recordings(folder) if j.subject == "S01"]
    outcomes = run_batch(jobs, tmp_path, ("rom",), workers=2, start_method="spawn")
    assert [o.error for o in outcomes] == [None, None]
    for o in outcomes:
        flexion = dict((name, hi) for name, _, hi in o.rows)["shoulder_r.flexion"]
        assert flexion == pytest.approx(truth[(o.job.subject, o.job.trial)], abs=5.0)
