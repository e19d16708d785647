"""A user's install, as it will be from PyPI: the sdist and the wheel built from this tree
(``python -m build``: the wheel is built from the sdist, so the sdist is complete), published
to a local package index (a ``--find-links`` folder), installed into a fresh virtualenv outside
the source tree with their dependencies from PyPI (pip's cache makes later runs quick).

There, a plain install (no extra) runs ``bpms --help``, ``bpms warmup``, and a record → filter
→ export chain on the simulated suit; ``.mat`` needs nothing more; a missing extra is named in
one line; the documentation and the sample recordings are inside the installed package.
Without a network (and nothing in pip's cache) the test is skipped, saying so.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import venv
from pathlib import Path

import pytest

import bpms

ROOT = Path(__file__).resolve().parents[1]
OFFLINE = ("Network is unreachable", "Failed to establish a new connection",
           "Temporary failure in name resolution", "Name or service not known",
           "No route to host", "getaddrinfo failed")

pytestmark = [pytest.mark.slow, pytest.mark.install]


@pytest.fixture(scope="module")
def index(tmp_path_factory) -> Path:
    """The local index: a folder holding the built sdist and wheel."""
    dist = tmp_path_factory.mktemp("index")
    done = subprocess.run([sys.executable, "-m", "build", "--no-isolation", "--outdir",
                           str(dist), str(ROOT)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    names = sorted(p.name for p in dist.iterdir())
    version = bpms.__version__
    assert names == [f"bpms-{version}-py3-none-any.whl", f"bpms-{version}.tar.gz"], names
    return dist


@pytest.fixture(scope="module")
def installed(index, tmp_path_factory) -> Path:
    """The ``bin`` folder of a fresh virtualenv with ``bpms`` installed from the index."""
    env_dir = tmp_path_factory.mktemp("user") / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    bindir = env_dir / ("Scripts" if os.name == "nt" else "bin")
    python = bindir / ("python.exe" if os.name == "nt" else "python")
    done = subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check",
                           "--python", str(python), "install", "-q", "--no-compile",
                           "--find-links", str(index), f"bpms=={bpms.__version__}"],
                          capture_output=True, text=True, timeout=900)
    if done.returncode != 0 and any(s in done.stderr for s in OFFLINE):
        pytest.skip("no network to fetch the dependencies from PyPI: "
                    + done.stderr.strip().splitlines()[-1])
    assert done.returncode == 0, done.stderr[-3000:]
    return bindir


def _run(bindir: Path, *args: str, cwd: Path, **extra_env: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(extra_env)
    exe = bindir / ("bpms.exe" if os.name == "nt" else "bpms")
    return subprocess.run([str(exe), *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600)


def test_the_sdist_holds_the_sources_tests_docs_and_samples(index):
    import tarfile

    with tarfile.open(index / f"bpms-{bpms.__version__}.tar.gz") as sdist:
        names = {n.split("/", 1)[1] for n in sdist.getnames() if "/" in n}
    for name in ("pyproject.toml", "README.md", "LICENSE", "CHANGELOG.md", "CITATION.cff",
                 "bpms/cli.py", "tests/test_install_from_index.py", "docs/index.md",
                 "docs/samples/Raw_simulated_walk.bpmsraw", "calib/Calib.cfg"):
        assert name in names, name


def test_installed_bpms_help_and_the_shipped_docs(installed, tmp_path):
    done = _run(installed, "--help", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    for command in ("filter", "record", "export", "convert", "batch", "warmup", "gui"):
        assert re.search(rf"^\s+{command}\s", done.stdout, re.M), command
    where = re.search(r"^Documentation: (.+) \(start with index\.md\)\.$", done.stdout, re.M)
    assert where, done.stdout
    docs = Path(where.group(1))
    assert docs.parent.name == "bpms" and ROOT not in docs.parents  # the installed copy
    for page in ("index.md", "units.md", "README.md", "LICENSE", "CHANGELOG.md",
                 "samples/Raw_simulated_arm_raise.bpmsraw"):
        assert (docs / page).is_file(), page
    assert _run(installed, "--version", cwd=tmp_path).stdout.strip() == (
        f"bpms {bpms.__version__}")


def test_installed_bpms_warmup_then_record_filter_export(installed, tmp_path):
    # the filters compile for this machine (the default filter: mahony), announced in plain
    # lines in a pipe
    # (a cache of its own: the tests share one installed copy and run in any order, so
    # another test may already have compiled into the package's own cache)
    done = _run(installed, "warmup", "--filter", "mahony", cwd=tmp_path,
                NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))
    assert done.returncode == 0, done.stderr
    assert "compiling the filters" in done.stderr and "\r" not in done.stderr
    done = _run(installed, "record", "--sim", "--seconds", "5", "-o", "rec", "--name", "chain",
                cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    (raw,) = (tmp_path / "rec").glob("Raw_chain*.bpmsraw")  # the recorder numbers its files
    done = _run(installed, "filter", str(raw), "-o", "chain.csv", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    rows = [ln for ln in (tmp_path / "chain.csv").read_text().splitlines()
            if not ln.startswith("#")]
    from bpms.io.recordings import open_recording

    frames = len(open_recording(raw))
    assert frames >= 50 and len(rows) == 1 + frames  # the column row, a row per frame
    (tmp_path / "out").mkdir()
    done = _run(installed, "export", "opensim", str(raw), "-o", "out/chain", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "out" / "chain_orientations.sto").is_file()
    done = _run(installed, "convert", str(raw), "-f", "mat", "-o", "out/chain", cwd=tmp_path)
    assert done.returncode == 0, done.stderr  # .mat: no extra needed
    assert (tmp_path / "out" / "chain.mat").read_bytes()[:10] == b"MATLAB 5.0"


@pytest.mark.parametrize(("args", "extra"), [
    (("convert", "{raw}", "-f", "parquet"), "parquet"),
    (("rom", "{raw}", "-o", "rom"), "figures"),
])
def test_a_missing_extra_is_named_in_one_line(installed, tmp_path, args, extra):
    raw = ROOT / "docs" / "samples" / "Raw_simulated_arm_raise.bpmsraw"
    done = _run(installed, *(a.format(raw=raw) for a in args), cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    assert f'pip install "bpms[{extra}]"' in done.stderr.strip().splitlines()[-1]
