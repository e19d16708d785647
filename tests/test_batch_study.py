"""A study laid out as a study (issue 49.3) and a failed batch that says so (issue 43.4):

- the study sheet's subject, trial, condition and other columns reach batch_rom.csv and the
  Parquet dataset, which pandas, duckdb and polars read whole in one call, partitioned by
  subject; batch_rom.csv stays outside the Parquet tree; --no-figures draws nothing;
- a sheet naming a missing recording is one line, exit 2;
- a worker process killed mid-batch: exit 3, the lost recordings reported apart from bad
  files;
- a skip reason with a newline or a ``|`` keeps the summary's table one row per file.
"""

from __future__ import annotations

import csv
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bpms.analysis.batch import Job, Outcome, write_summary
from bpms.firmware.sim.session import simulate

ROOT = Path(__file__).resolve().parents[1]
SECONDS = 3.0


def bpms(*args: str, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bpms", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=300, **kw)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("study")
    rows = [("S01/a.bpmsraw", "P01", "walk 1", "low", "20"),
            ("S01/b.bpmsraw", "P01", "walk 2", "high", "60"),
            ("S02/a.bpmsraw", "P02", "walk 1", "low", "20"),
            ("S02/b.bpmsraw", "P02", "walk 2", "high", "60")]
    for k, (file, *_) in enumerate(rows):
        (folder / file).parent.mkdir(exist_ok=True)
        simulate(SECONDS, seed=50 + k).save_raw(folder / file)
    (folder / "S02" / "extra.bpmsraw").write_bytes(b"not in the sheet, not a recording")
    sheet = folder / "sheet.csv"
    with open(sheet, "w", encoding="utf-8", newline="") as f:
        w = csv.writer(f)
        w.writerow(["file", "subject", "trial", "condition", "pressure_kpa"])
        w.writerows(rows)
    out = folder / "out"
    done = bpms("batch", str(folder), "-o", str(out), "--study", str(sheet), "--outputs",
                "rom,parquet", "--workers", "1", "--no-figures")
    assert done.returncode == 0, done.stderr
    return folder, out, rows, done


def test_the_sheet_columns_reach_the_tidy_table(study):
    _, out, rows, done = study
    with open(out / "batch_rom.csv", encoding="utf-8") as f:
        table = list(csv.DictReader(f))
    assert len(table) == 4 * 28
    assert list(table[0])[:5] == ["subject", "trial", "condition", "pressure_kpa", "joint"]
    got = {(r["subject"], r["trial"], r["condition"], r["pressure_kpa"]) for r in table}
    assert got == {tuple(r[1:]) for r in rows}
    assert all(r["filter"].startswith("mahony (") and r["bpms_version"] for r in table)
    assert "1 recording(s) under" in done.stderr  # extra.bpmsraw: not in the sheet
    summary = (out / "batch_summary.md").read_text()
    assert "subject and trial from the study sheet" in summary
    assert "batch_rom.png" not in summary and not (out / "batch_rom.png").exists()


def test_the_parquet_dataset_reads_whole_in_pandas_duckdb_and_polars(study):
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    _, out, _, _ = study
    dataset = out / "parquet"
    assert sorted(p.name for p in dataset.iterdir()) == ["subject=P01", "subject=P02"]
    assert not list(dataset.rglob("*.csv"))  # batch_rom.csv lives beside, not inside
    frames = round(SECONDS * 50)
    df = pd.read_parquet(dataset)
    assert len(df) == 4 * frames
    counts = df.groupby(["subject", "condition"], observed=True).size()
    assert counts.to_dict() == {("P01", "high"): frames, ("P01", "low"): frames,
                                ("P02", "high"): frames, ("P02", "low"): frames}
    assert set(df["trial"]) == {"walk 1", "walk 2"}
    duckdb = pytest.importorskip("duckdb")
    n = duckdb.sql(f"SELECT count(*), count(DISTINCT subject) FROM read_parquet("
                   f"'{dataset.as_posix()}/**/*.parquet', hive_partitioning = true)").fetchall()
    assert n == [(4 * frames, 2)]
    pl = pytest.importorskip("polars")
    lazy = pl.scan_parquet(dataset / "**" / "*.parquet", hive_partitioning=True)
    assert lazy.select(pl.len()).collect().item() == 4 * frames
    assert sorted(lazy.select("subject").unique().collect()["subject"].to_list()) == [
        "P01", "P02"]


def test_a_sheet_naming_a_missing_recording_is_one_line(study, tmp_path):
    folder, _, _, _ = study
    sheet = tmp_path / "bad.csv"
    sheet.write_text("file,subject,condition\nS01/a.bpmsraw,P01,low\nS09/gone.bpmsraw,P09,low\n",
                     encoding="utf-8")
    done = bpms("batch", str(folder), "-o", str(tmp_path / "o"), "--study", str(sheet))
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1].startswith("bpms batch: ")
    assert "S09/gone.bpmsraw" in done.stderr and "Traceback" not in done.stderr


def test_a_skip_reason_with_a_newline_keeps_the_table_one_row(tmp_path):
    bad = Outcome(Job("x.bpmsraw", "S", "x"), error="first line\nsecond | line",
                  failure="recording")
    text = write_summary(tmp_path, [bad], tmp_path, 0.1, 1, figures=False).read_text()
    rows = [ln for ln in text.splitlines() if ln.startswith("| x.bpmsraw")]
    assert rows == ["| x.bpmsraw | first line second \\| line |"]


def test_a_killed_worker_exits_3_and_is_not_called_a_bad_file(tmp_path):
    psutil = pytest.importorskip("psutil")
    import numpy as np

    from bpms.io.rawfile import new_header, write_raw

    folder = tmp_path / "study"
    folder.mkdir()
    rec = simulate(20.0, seed=60)
    reps = 12  # 4 minutes a file: the work outlasts the kill on a busy machine too
    times = 1.7e9 + np.arange(len(rec.t) * reps) * 0.02
    for k in range(6):
        write_raw(folder / f"Raw_t_{k:03d}.bpmsraw", times, rec.frames * reps,
                  new_header(calibration=rec.calibration.values))
    proc = subprocess.Popen([sys.executable, "-m", "bpms", "batch", str(folder), "--workers",
                             "2", "--no-figures"], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    parent = psutil.Process(proc.pid)
    deadline = time.monotonic() + 60
    victim = None
    while victim is None and time.monotonic() < deadline and proc.poll() is None:
        # a pool worker: a child of the batch (the resource tracker is not one)
        kids = [c for c in parent.children() if "resource_tracker" not in " ".join(
            c.cmdline())]
        victim = kids[0] if kids else None
        if victim is None:
            time.sleep(0.01)  # polling for the worker to exist (deadline above)
    assert victim is not None, "no worker process appeared"
    victim.kill()
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 3, err
    assert "lost by the machinery" in err and "a worker process died" in err
    summary = (folder / "batch" / "batch_summary.md").read_text()
    assert "## Not processed (the machinery failed, not the file)" in summary
    assert "## Skipped" not in summary


def test_the_study_reaches_the_mat_file_and_the_filtered_header(study, tmp_path):
    from scipy.io import loadmat

    from bpms.analysis.batch import process_one

    folder, _, rows, _ = study
    job = Job(str(folder / rows[1][0]), "P01", "walk 2", {"condition": "high",
                                                           "pressure_kpa": "60"})
    outcome = process_one(job, str(tmp_path), ("filter", "mat"))
    assert outcome.error is None, outcome.error
    mat = loadmat(tmp_path / "P01" / "walk_2.mat", simplify_cells=True)
    assert mat["study"] == {"subject": "P01", "trial": "walk 2", "condition": "high",
                            "pressure_kpa": "60"}
    assert mat["recording"] == "b.bpmsraw" and mat["filter"].startswith("mahony (")
    head = (tmp_path / "P01" / "walk_2_filtered.csv").read_text().split("\ntime")[0]
    assert "# study: subject=P01; trial=walk 2; condition=high; pressure_kpa=60" in head
    assert "# recording: b.bpmsraw" in head
