"""A malformed or pathologically nested options file gives one clear problem (factory options
used), never a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from bpms.io.options import Options, load_options

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("text", [
    "a = " + "[" * 100_000 + "1" + "]" * 100_000 + "\n",
    "[serial]\nbaud = " + "{x = " * 5000 + "1" + "}" * 5000 + "\n",
    "[filter\nkp_yaw = 1\n",
])
def test_deep_or_broken_files_give_one_problem(tmp_path, text):
    path = tmp_path / "options.toml"
    path.write_text(text)
    options = load_options(path)
    assert len(options.problems) == 1 and "factory options used" in str(options.problems[0])
    assert options.serial == Options().serial and options.filter == Options().filter


def test_record_with_a_deeply_nested_options_file_says_one_line(tmp_path):
    path = tmp_path / "options.toml"
    path.write_text("a = " + "[" * 100_000 + "]" * 100_000 + "\n")
    done = subprocess.run([sys.executable, "-m", "bpms", "record", "/dev/nonexistent-bpms",
                           "--options", str(path), "-o", str(tmp_path)], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert "Traceback" not in done.stderr and "RecursionError" not in done.stderr
    assert "nested too deeply; factory options used" in done.stderr
