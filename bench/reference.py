"""The tree before the one-implementation work (issue 24), checked out beside this one, so that a
benchmark prints each figure beside the same figure of that tree, measured in the same run.

``reference_tree()`` makes (once) a detached ``git worktree`` of :data:`BEFORE_ONE_IMPLEMENTATION`
in the temporary folder and returns its path; ``python_in(tree)`` is the environment that runs a
child Python on that tree's ``bpms`` with this tree's virtualenv (the dependencies are the same).
The reference's numba caches stay inside its worktree, so they never mix with this tree's.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

#: main before the one-implementation work (the commit that issue 24 measured).
BEFORE_ONE_IMPLEMENTATION = "ae4a6b92cbf1450118dd80991ec484115b98ce92"
ROOT = Path(__file__).resolve().parents[1]


def reference_tree(commit: str = BEFORE_ONE_IMPLEMENTATION) -> Path:
    """The path of a worktree of ``commit`` (made with ``git worktree add --detach`` the first
    time). Raises RuntimeError with git's message when it cannot be made."""
    path = Path(tempfile.gettempdir()) / f"bpms-bench-{commit[:10]}"
    if (path / "bpms" / "__init__.py").is_file():
        return path
    done = subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(path),
                           commit], capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"cannot check out {commit[:7]}: {done.stderr.strip()}")
    return path


def python_in(tree: Path) -> dict[str, str]:
    """Environment for a child ``sys.executable`` that imports ``bpms`` from ``tree``."""
    return {**os.environ, "PYTHONPATH": str(tree), "PYTHONDONTWRITEBYTECODE": ""}


def run_in(tree: Path, code: str, *args: str, timeout: float = 3600.0
           ) -> subprocess.CompletedProcess:
    """Run ``python -c code args`` on ``tree``'s bpms (cwd: the tree)."""
    return subprocess.run([sys.executable, "-c", code, *args], cwd=tree, env=python_in(tree),
                          capture_output=True, text=True, timeout=timeout)


def as_version_1(path: Path) -> None:
    """Mark a raw recording without event records as format version 1 (docs/raw-format.md:
    the same bytes but the version, in the preamble and the header), in place, so that the
    tree before version 2 reads it too."""
    data = bytearray(path.read_bytes())
    length = int.from_bytes(data[10:14], "little")
    header = bytes(data[14:14 + length])
    assert data[8:10] == (2).to_bytes(2, "little") and b'"format_version": 2' in header
    data[8:10] = (1).to_bytes(2, "little")
    data[14:14 + length] = header.replace(b'"format_version": 2', b'"format_version": 1')
    path.write_bytes(bytes(data))
