"""The release path's facts: the version is written once; the changelog, the citation file and
the extras agree with pyproject.toml; ``[all]`` pulls in no Jupyter package."""

from __future__ import annotations

import contextlib
import importlib.metadata as md
import re
import tomllib
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

import bpms

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
JUPYTER = re.compile(r"^(jupyter.*|ipython|ipykernel|ipywidgets|notebook|nbconvert|nbformat|"
                     r"nbclient|jupyterlab.*|widgetsnbextension)$")


def test_the_version_is_written_once():
    project = PYPROJECT["project"]
    assert "version" not in project and project["dynamic"] == ["version"]
    assert PYPROJECT["tool"]["hatch"]["version"]["path"] == "bpms/__init__.py"
    assert re.fullmatch(r"\d+\.\d+\.\d+", bpms.__version__)



def test_the_citation_states_the_latest_release_and_its_date():
    """GitHub's generated BibTeX takes its version and year from these two keys."""
    citation = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
    changelog = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    dates = dict(re.findall(r"^## \[(\d+\.\d+\.\d+)\] - (\d{4}-\d\d-\d\d)$", changelog, re.M))
    assert re.search(rf'^version: "{re.escape(bpms.__version__)}"$', citation, re.M)
    assert re.search(rf'^date-released: "{dates[bpms.__version__]}"$', citation, re.M)


def test_the_changelog_starts_with_this_version():
    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    releases = re.findall(r"^## \[(\d+\.\d+\.\d+)\] - (\d{4}-\d\d-\d\d)$", text, re.M)
    assert releases and releases[0][0] == bpms.__version__
    assert text.index("## [Unreleased]") < text.index(f"## [{bpms.__version__}]")


def test_the_citation_names_the_authors_pyproject_names():
    citation = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
    assert re.search(r"^cff-version: 1\.2\.0$", citation, re.M)
    names = re.findall(r'^  - name: "(.+)"$', citation, re.M)
    assert names == [a["name"] for a in PYPROJECT["project"]["authors"]]
    assert "doi" not in citation.lower().replace("no doi", "")  # none invented
    assert re.search(r"^license: MIT$", citation, re.M)


def _bpms_requires(extras: set[str]) -> list[str]:
    """bpms's own requirements with ``extras`` (from pyproject.toml: the installed metadata of
    an editable install lags behind until it is reinstalled)."""
    project = PYPROJECT["project"]
    out = list(project["dependencies"])
    for extra in extras:
        out += project["optional-dependencies"][extra]
    return out


def _closure(extras: set[str]) -> set[str]:
    """Every distribution ``bpms[extras]`` pulls in (the others' from their metadata)."""
    seen: set[str] = set()
    todo = [(r, set()) for r in _bpms_requires(extras)]
    while todo:
        text, active = todo.pop()
        req = Requirement(text)
        env = [{"extra": e} for e in active] or [{"extra": ""}]
        if req.marker is not None and not any(req.marker.evaluate(e) for e in env):
            continue
        name = canonicalize_name(req.name)
        if name == "bpms":  # a self-reference: bpms[figures,lsl,...] inside [all]
            todo += [(r, set()) for r in _bpms_requires(set(req.extras))]
            continue
        key = f"{name}[{','.join(sorted(req.extras))}]"
        if key in seen:
            continue
        seen.add(key)
        with contextlib.suppress(md.PackageNotFoundError):
            todo += [(r, set(req.extras)) for r in md.requires(name) or []]
    return {k.split("[")[0] for k in seen}


def test_all_pulls_in_no_jupyter_package_and_vpython_does():
    every = _closure({"all"})
    assert "distributed" in every and "pyarrow" in every and "matplotlib" in every
    assert "vpython" not in every
    assert sorted(n for n in every if JUPYTER.match(n)) == []
    assert any(JUPYTER.match(n) for n in _closure({"vpython"}))  # why it stands alone


def test_every_extra_is_in_the_readme_table():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    table = set(re.findall(r"^\| `(\w+)` \|", readme, re.M))
    extras = set(PYPROJECT["project"]["optional-dependencies"]) - {"dev"}
    assert extras <= table, extras - table


def test_bpms_version_from_a_checkout_names_its_commit():
    """Issue 43.5: a build from a checkout names its commit (the installed copy and the bundle
    print the bare version: tests/test_install_from_index.py, tests/test_bundle.py)."""
    import subprocess
    import sys

    if not (ROOT / ".git").exists():
        import pytest

        pytest.skip("not a git checkout")
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short=12", "HEAD"],
                          capture_output=True, text=True, check=True).stdout.strip()
    done = subprocess.run([sys.executable, "-m", "bpms", "--version"], capture_output=True,
                          text=True, cwd=ROOT, timeout=60)
    assert done.returncode == 0, done.stderr
    assert re.fullmatch(rf"bpms {re.escape(bpms.__version__)} \(commit {head}(\+dirty)?\)",
                        done.stdout.strip()), done.stdout
