"""Layer contracts (pyproject.toml [tool.importlinter]) hold, and the checker does catch an
upward import: one planted in a scratch copy of the package breaks the right contract."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
LINT = Path(sys.executable).with_name("lint-imports")


def lint(root: Path) -> subprocess.CompletedProcess:
    if not LINT.exists():
        pytest.fail(f"lint-imports not found beside {sys.executable}: pip install import-linter")
    env = {**os.environ, "PYTHONPATH": str(root)}
    return subprocess.run([str(LINT), "--no-cache"], cwd=root, env=env, capture_output=True,
                          text=True, timeout=300)


def test_import_contracts_hold():
    result = lint(REPO)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 broken" in result.stdout


def scratch_copy(tmp_path: Path) -> Path:
    root = tmp_path / "repo"
    shutil.copytree(REPO / "bpms", root / "bpms",
                    ignore=shutil.ignore_patterns("__pycache__", "sketches"))
    shutil.copy(REPO / "pyproject.toml", root / "pyproject.toml")
    return root


@pytest.mark.parametrize(("module", "line", "contract"), [
    ("bpms/io/_planted.py", "from bpms.filter import rotations\n",
     "bpms.io imports nothing from filter, pipeline, gui, commands"),
    ("bpms/firmware/sim/_planted.py", "def f():\n    from bpms.filter.calibration import "
     "SensorCalibration\n    return SensorCalibration\n",
     "The simulated suit imports nothing from bpms.filter"),
    ("bpms/filter/_planted.py", "import PyQt6.QtCore\n", "Qt only in bpms.gui"),
    # upward imports no forbidden list names: the layers contract (docs/architecture.md)
    ("bpms/pipeline/_planted.py", "from bpms.analysis import rom\n",
     "The rooms of docs/architecture.md"),
    ("bpms/pipeline/_planted.py", "def f():\n    from bpms.commands import filter\n",
     "The rooms of docs/architecture.md"),
    ("bpms/filter/_planted.py", "import bpms.analysis.track\n",
     "The rooms of docs/architecture.md"),
    ("bpms/analysis/_planted.py", "from bpms.calibration import procedures\n",
     "The rooms of docs/architecture.md"),
    ("bpms/firmware/sim/_planted.py", "from bpms.io.options import BodyOptions\n",
     "The simulated suit imports from bpms only bpms.io.frames and bpms.io.events"),
    ("bpms/firmware/sim/_planted.py", "def f():\n    from bpms.io.calib_file import "
     "load_factory_calibration\n    return load_factory_calibration\n",
     "The simulated suit imports from bpms only bpms.io.frames and bpms.io.events"),
    # a bpms.io module added after the contract was written is forbidden too
    ("bpms/firmware/sim/_planted.py", "from bpms.io._brand_new import X\n",
     "The simulated suit imports from bpms only bpms.io.frames and bpms.io.events"),
])
def test_planted_upward_import_is_caught(tmp_path, module, line, contract):
    root = scratch_copy(tmp_path)
    (root / "bpms/io/_brand_new.py").write_text("X = 1\n")
    (root / module).write_text(line)
    result = lint(root)
    assert result.returncode != 0
    assert f"{contract} BROKEN" in result.stdout, result.stdout

