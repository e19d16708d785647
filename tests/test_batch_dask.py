"""``bpms batch --scheduler``: a study on a Dask distributed cluster made of separate processes
on 127.0.0.1 (one scheduler, two workers) gives the same bytes as the local process pool; a
scheduler killed mid-batch is reported as the machinery's failure, exit 3 (issue 43.4)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from waiting import wait_until

from bpms.firmware.sim.session import simulate

pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[1]


def bpms(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bpms", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)


@pytest.fixture()
def cluster(cluster_processes):
    """``tcp://127.0.0.1:PORT`` of a scheduler with two single-threaded workers."""
    return cluster_processes[0]


@pytest.fixture()
def cluster_processes(tmp_path):
    """(``tcp://127.0.0.1:PORT``, [scheduler, worker, worker] processes): a scheduler with two
    single-threaded workers, each its own process (``python -m dask scheduler|worker``, no
    nanny, no dashboard)."""
    env = dict(os.environ)
    info = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1",
                               "--port", "0", "--no-dashboard", "--scheduler-file", str(info)],
                              cwd=tmp_path, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)]
    try:
        assert wait_until(lambda: info.is_file() and info.stat().st_size > 0, 60), \
            "the scheduler never wrote its address"
        address = json.loads(info.read_text())["address"]
        for k in range(2):
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "dask", "worker", address, "--host", "127.0.0.1",
                 "--nthreads", "1", "--no-nanny", "--no-dashboard", "--name", f"w{k}",
                 "--local-directory", str(tmp_path / f"w{k}")],
                cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        yield address, procs
    finally:  # the workers first (they would wait for a scheduler that has gone)
        for proc in reversed(procs):
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != "batch_summary.md"}  # the summary states the timing


def test_a_dask_cluster_gives_the_same_bytes_as_local_processes(tmp_path, cluster):
    study = tmp_path / "study"
    for subject, seed in (("S01", 30), ("S01", 31), ("S02", 32)):
        (study / subject).mkdir(parents=True, exist_ok=True)
        simulate(4.0, seed=seed).save_raw(study / subject / f"Raw_trial_{seed}.bpmsraw")
    (study / "S02" / "Raw_broken.bpmsraw").write_bytes(b"not a recording")
    outputs = "rom,filter,mat,parquet"
    local = bpms("batch", str(study), "-o", str(tmp_path / "local"), "--outputs", outputs,
                 "--workers", "2")
    assert local.returncode == 1, local.stderr  # the broken file: an incomplete study
    done = bpms("batch", str(study), "-o", str(tmp_path / "dask"), "--outputs", outputs,
                "--scheduler", cluster)
    assert done.returncode == 1, done.stderr
    assert f"on the Dask cluster at {cluster} (2 workers)" in done.stdout
    assert "3 processed, 1 skipped" in done.stdout
    a, b = _files(tmp_path / "local"), _files(tmp_path / "dask")
    assert sorted(a) == sorted(b) and len(a) == 2 + 3 * 3  # table, figure, 3 × (csv, mat, pq)
    assert [name for name in a if a[name] != b[name]] == []
    summary = (tmp_path / "dask" / "batch_summary.md").read_text()
    assert "processed: 3; skipped: 1" in summary


def test_an_unreachable_scheduler_is_one_line(tmp_path):
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    study = tmp_path / "study"
    study.mkdir()
    simulate(1.0, seed=1).save_raw(study / "Raw_1.bpmsraw")
    done = subprocess.run([sys.executable, "-m", "bpms", "batch", str(study), "--scheduler",
                           f"tcp://127.0.0.1:{port}"], cwd=ROOT, capture_output=True, text=True,
                          timeout=120, env={**os.environ, "DASK_DISTRIBUTED__COMM__TIMEOUTS__"
                                                          "CONNECT": "2s"})
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert lines[-1].startswith("bpms batch: cannot reach the Dask scheduler at tcp://127.0.0.1:")
    assert "Traceback" not in done.stderr


def test_a_scheduler_killed_mid_batch_exits_3(tmp_path, cluster_processes):
    import threading

    address, procs = cluster_processes
    study = tmp_path / "study"
    study.mkdir()
    for k in range(8):
        simulate(20.0, seed=70 + k).save_raw(study / f"Raw_t_{k:03d}.bpmsraw")
    batch = subprocess.Popen([sys.executable, "-m", "bpms", "batch", str(study), "--scheduler",
                              address, "--no-figures"], cwd=ROOT, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True,
                             env={**os.environ, "DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT":
                                  "3s"})
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(batch.stdout), daemon=True)
    reader.start()
    try:
        assert wait_until(lambda: any(ln.startswith("[1/8]") for ln in list(lines)), 120), \
            "no recording finished"
        procs[0].kill()  # the scheduler dies mid-batch
        err = batch.stderr.read()
        batch.wait(180)
    finally:
        if batch.poll() is None:
            batch.kill()
    reader.join(10)
    assert batch.returncode == 3, err
    assert "lost by the machinery" in err and "Traceback" not in err
    summary = (study / "batch" / "batch_summary.md").read_text()
    assert "## Not processed (the machinery failed, not the file)" in summary
    assert "## Skipped" not in summary
