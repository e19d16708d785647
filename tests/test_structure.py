"""Structure a newcomer can see (issue 24): no module of ``bpms/`` over 600 lines, and no
import circle inside ``bpms/``.

The import graph is read from the source with :mod:`ast`, not by importing anything: every
``import`` / ``from … import`` of a ``bpms`` module anywhere in a module (at module level,
inside functions and methods, under ``if TYPE_CHECKING:``), with relative imports resolved
and ``from package import module`` counted as an import of that module. Imports made from
strings at run time (``importlib.import_module``) are not seen.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

#: Import circles allowed to stand (each one elementary cycle as the tuple of its modules,
#: starting from the smallest name): none. Keep it empty; test_allowed_cycles_still_exist
#: fails for an entry whose cycle is gone.
ALLOWED_CYCLES: frozenset[tuple[str, ...]] = frozenset()

MAX_LINES = 600
REPO = Path(__file__).resolve().parents[1]
#: Elementary cycles listed per strongly connected component before giving up on listing.
MAX_CYCLES_LISTED = 200


@dataclass(frozen=True)
class Edge:
    importer: str
    imported: str
    where: str  # "path:line"


def module_files(root: Path, package: str = "bpms") -> dict[str, Path]:
    """Dotted module name → file, for every ``.py`` file of ``root/package``."""
    files = {}
    for path in sorted((root / package).rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        files[".".join(parts)] = path
    return files


def import_edges(root: Path, package: str = "bpms") -> dict[str, list[Edge]]:
    """Every import of a module of ``package`` by a module of ``package`` (see the module
    docstring), by importing module."""
    files = module_files(root, package)
    edges: dict[str, list[Edge]] = {name: [] for name in files}
    for name, path in files.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        package_of = name if path.name == "__init__.py" else name.rpartition(".")[0]
        where = path.relative_to(root).as_posix()
        for node in ast.walk(tree):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [_owning_module(a.name, files) for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package_of.split(".")
                    parts = parts[:len(parts) - (node.level - 1)]
                    base = ".".join(parts + ([node.module] if node.module else []))
                for alias in node.names:
                    full = f"{base}.{alias.name}"
                    targets.append(full if full in files else _owning_module(base, files))
            for target in targets:
                if target and target != name:
                    edges[name].append(Edge(name, target, f"{where}:{node.lineno}"))
    return edges


def _owning_module(dotted: str, files: dict[str, Path]) -> str:
    """``dotted`` itself when it is a module of the package, else ""."""
    return dotted if dotted in files else ""


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """The components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for start in sorted(graph):
        if start in index:
            continue
        work: list[tuple[str, Iterator[str]]] = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            v, children = work[-1]
            w = next(children, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                component = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    component.append(w)
                    if w == v:
                        break
                if len(component) > 1:
                    out.append(sorted(component))
    return out


def elementary_cycles(graph: dict[str, set[str]]) -> list[tuple[str, ...]]:
    """Every elementary cycle, each starting from its smallest module name (at most
    :data:`MAX_CYCLES_LISTED` per component; the component is then reported whole)."""
    cycles: list[tuple[str, ...]] = []
    for component in strongly_connected(graph):
        found: list[tuple[str, ...]] = []
        for k, first in enumerate(component):
            found += _cycles_from(graph, first, set(component[k + 1:]),
                                  MAX_CYCLES_LISTED + 1 - len(found))
        if len(found) > MAX_CYCLES_LISTED:
            found = [tuple(component)]  # too many to list: the whole component
        cycles += found
    return cycles


def _cycles_from(graph: dict[str, set[str]], first: str, others: set[str],
                 limit: int) -> list[tuple[str, ...]]:
    """The elementary cycles through ``first`` and modules of ``others`` (at most ``limit``)."""
    found: list[tuple[str, ...]] = []
    path = [first]

    def walk(v: str) -> None:
        for w in sorted(graph[v]):
            if len(found) >= limit:
                return
            if w == first:
                found.append(tuple(path))
            elif w in others and w not in path:
                path.append(w)
                walk(w)
                path.pop()

    walk(first)
    return found


def describe(cycle: tuple[str, ...], edges: dict[str, list[Edge]]) -> str:
    """``a -> b -> a`` with where each import is."""
    steps = []
    for k, a in enumerate(cycle):
        b = cycle[(k + 1) % len(cycle)]
        places = sorted({e.where for e in edges[a] if e.imported == b}) or ["?"]
        steps.append(f"  {a} -> {b}  ({', '.join(places)})")
    return " -> ".join((*cycle, cycle[0])) + "\n" + "\n".join(steps)


def cycles_of(root: Path, package: str = "bpms") -> tuple[list[tuple[str, ...]],
                                                          dict[str, list[Edge]]]:
    edges = import_edges(root, package)
    graph = {m: {e.imported for e in es} for m, es in edges.items()}
    return elementary_cycles(graph), edges


@pytest.fixture(scope="module")
def bpms_cycles():
    return cycles_of(REPO)


def test_no_module_over_600_lines():
    long = {name: n for name, path in module_files(REPO).items()
            if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert not long, (f"modules over {MAX_LINES} lines (split them by job): "
                      + ", ".join(f"{m} {n}" for m, n in sorted(long.items())))


def test_no_import_cycle_in_bpms(bpms_cycles):
    cycles, edges = bpms_cycles
    new = [c for c in cycles if c not in ALLOWED_CYCLES]
    assert not new, "import cycles in bpms/:\n" + "\n".join(describe(c, edges) for c in new)


def test_allowed_cycles_still_exist(bpms_cycles):
    cycles, _ = bpms_cycles
    gone = sorted(ALLOWED_CYCLES - set(cycles))
    assert not gone, ("these import cycles are gone: remove them from ALLOWED_CYCLES in "
                      "tests/test_structure.py: " + "; ".join(" -> ".join(c) for c in gone))


def test_allowed_cycles_are_only_in_the_filter_layer():
    for cycle in ALLOWED_CYCLES:
        assert cycle == min(cycle[k:] + cycle[:k] for k in range(len(cycle))), cycle
        assert all(m.startswith(("bpms.filter.", "bpms.pipeline.")) for m in cycle), cycle
        assert any(m.startswith("bpms.filter.") for m in cycle), cycle


def _package(root: Path, modules: dict[str, str]) -> Path:
    for name, text in modules.items():
        path = root / (name.replace(".", "/") + ".py")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


@pytest.mark.parametrize(("importer", "line"), [
    ("pkg.low.a", "from pkg.high import b\n"),  # from package import module
    ("pkg.low.a", "import pkg.high.b\n"),
    ("pkg.low.a", "def f():\n    from pkg.high.b import B\n    return B\n"),
    ("pkg.low.a", "class A:\n    def m(self):\n        import pkg.high.b as b\n        return b\n"),
    ("pkg.low.a", "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                  "    from pkg.high.b import B\n"),
    ("pkg.low.a", "from ..high import b\n"),  # relative, two levels
    ("pkg.low.a", "from ..high.b import B\n"),
    ("pkg.low.__init__", "from . import a\n"),  # package → its own module, a → package
])
def test_checker_finds_a_planted_cycle(tmp_path, importer, line):
    """Each way of importing closes a cycle the checker names; without the planted line
    the same package has none."""
    modules = {
        "pkg.__init__": "",
        "pkg.low.__init__": "",
        "pkg.high.__init__": "",
        "pkg.low.a": "X = 1\n",
        "pkg.high.b": "from pkg.low.a import X\nB = X\n",
        "pkg.low.c": "import os\nfrom pkg.low.a import X\n",
    }
    if importer == "pkg.low.__init__":
        modules["pkg.low.a"] = "from pkg import low\n"
    root = _package(tmp_path / "clean", modules)
    cycles, _ = cycles_of(root, "pkg")
    assert cycles == []
    planted = dict(modules)
    planted[importer] = planted[importer] + line
    cycles, edges = cycles_of(_package(tmp_path / "planted", planted), "pkg")
    expected = ("pkg.high.b", "pkg.low.a") if importer == "pkg.low.a" else ("pkg.low", "pkg.low.a")
    assert cycles == [expected], cycles
    assert f"{expected[0]} -> {expected[1]} -> {expected[0]}" in describe(cycles[0], edges)


def test_checker_lists_every_elementary_cycle(tmp_path):
    root = _package(tmp_path, {
        "pkg.__init__": "",
        "pkg.a": "import pkg.b\n",
        "pkg.b": "def f():\n    import pkg.c\n",
        "pkg.c": "from pkg import a\nimport pkg.b\n",
    })
    cycles, _ = cycles_of(root, "pkg")
    assert sorted(cycles) == [("pkg.a", "pkg.b", "pkg.c"), ("pkg.b", "pkg.c")]
