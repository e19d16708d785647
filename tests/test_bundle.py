"""Smoke test of the standalone bundle (tools/build_bundle.sh; docs/release.md): on this
computer, without the source tree's Python, the frozen program prints its help, filters a
recording (compiling the filter inside the bundle, then loading it from the cache: the same
bytes), and starts the app offscreen. It needs a built bundle: ``.ci/run`` builds one after
the test command and runs this file with ``BPMS_BUNDLE=dist/bpms``; without that variable the
test is skipped."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import threading
from pathlib import Path

import pytest
from waiting import wait_until

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "docs" / "samples" / "Raw_simulated_arm_raise.bpmsraw"
FOLDER = os.environ.get("BPMS_BUNDLE")

pytestmark = pytest.mark.skipif(
    not FOLDER, reason="no bundle named: bash tools/build_bundle.sh, then BPMS_BUNDLE=dist/bpms "
                       "(.ci/run does both after the test command)")


@pytest.fixture(scope="module")
def program() -> Path:
    exe = Path(FOLDER).resolve() / ("bpms.exe" if os.name == "nt" else "bpms")
    assert exe.is_file(), f"{exe}: no bundle there (bash tools/build_bundle.sh)"
    return exe


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env.update(extra)
    return env


def _run(program: Path, *args: str, cwd: Path, **extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(program), *args], cwd=cwd, env=_env(**extra),
                          capture_output=True, text=True, timeout=600)


def test_the_bundle_prints_its_help_and_its_own_docs(program, tmp_path):
    done = _run(program, "--help", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    for command in ("filter", "record", "export", "gui", "warmup"):
        assert re.search(rf"^\s+{command}\s", done.stdout, re.M), command
    docs = Path(re.search(r"^Documentation: (.+) \(start with index\.md\)\.$", done.stdout,
                          re.M).group(1))
    assert program.parent in docs.parents and (docs / "samples").is_dir()
    import bpms

    assert _run(program, "--version", cwd=tmp_path).stdout.strip() == f"bpms {bpms.__version__}"


def test_the_bundle_compiles_the_filter_then_loads_it(program, tmp_path):
    # frozen, the filter compiles from the bundled sources into a cache of its own ...
    cache = {"NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}
    done = _run(program, "filter", str(SAMPLE), "-o", "first.csv", cwd=tmp_path, **cache)
    assert done.returncode == 0, done.stderr
    assert "compiling the filters" in done.stderr and "\r" not in done.stderr
    assert any((tmp_path / "numba-cache").rglob("*.nbi"))
    # ... and the next run loads it from there, silently, with the same numbers
    done = _run(program, "filter", str(SAMPLE), "-o", "again.csv", cwd=tmp_path, **cache)
    assert done.returncode == 0, done.stderr
    assert "compiling the filters" not in done.stderr
    assert (tmp_path / "again.csv").read_bytes() == (tmp_path / "first.csv").read_bytes()
    rows = [ln for ln in (tmp_path / "first.csv").read_text().splitlines()
            if not ln.startswith("#")]
    from bpms.io.recordings import open_recording

    assert len(rows) == 1 + len(open_recording(SAMPLE))


def test_the_bundle_starts_the_app_offscreen(program, tmp_path):
    proc = subprocess.Popen([str(program), "-v", "gui", "--sim", "--recording-dir",
                             str(tmp_path)], cwd=tmp_path,
                            env=_env(QT_QPA_PLATFORM="offscreen"), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stderr), daemon=True)
    reader.start()
    try:
        assert wait_until(lambda: any("the app is running" in ln for ln in lines)
                          or proc.poll() is not None, 120), "the app never said it runs"
        assert proc.poll() is None, "".join(lines)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 0, "".join(lines)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    reader.join(timeout=10)
    assert not any("Traceback" in ln for ln in lines), "".join(lines)
