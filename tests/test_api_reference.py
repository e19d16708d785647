"""The API reference builds from the docstrings without a warning (pdoc; tools/api_reference.py)
and documents the entry points the docs name."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_the_api_reference_builds_without_warnings(tmp_path):
    pytest.importorskip("pdoc")
    done = subprocess.run([sys.executable, str(ROOT / "tools" / "api_reference.py"), "-o",
                           str(tmp_path)], cwd=tmp_path, capture_output=True, text=True,
                          timeout=300, env={**os.environ, "QT_QPA_PLATFORM": "offscreen"})
    assert done.returncode == 0, done.stderr
    assert "warn" not in done.stderr.lower(), done.stderr
    page = (tmp_path / "bpms" / "filter" / "processor.html").read_text(encoding="utf-8")
    assert "BodyPoseProcessor" in page and "reset_zero" in page
    door = (tmp_path / "bpms" / "filter" / "door.html").read_text(encoding="utf-8")
    assert "process_file" in door and "open_for_processing" in door
    for module in ("analysis/c3d_export", "analysis/batch", "io/rawfile", "pipeline/lsl",
                   "firmware/sim/session", "progress"):
        assert (tmp_path / "bpms" / f"{module}.html").is_file(), module
    assert not (tmp_path / "bpms" / "gui").exists()  # the app is documented in docs/gui.md
