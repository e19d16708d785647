"""The main window is built from explicit parts (issue 44.4): it inherits from Qt's main
window only, and no part reaches into another part's (or any other object's) private
attributes; each part gets what it uses in its constructor (docs/main-window.md)."""

from __future__ import annotations

import ast
from pathlib import Path

from PyQt6.QtWidgets import QMainWindow

from bpms.gui.main_window import MainWindow

ROOT = Path(__file__).resolve().parents[1]
WINDOW_FILES = [ROOT / "bpms/gui/main_window.py",
                *sorted((ROOT / "bpms/gui/window").glob("*.py"))]


def test_main_window_inherits_from_qt_main_window_only():
    assert MainWindow.__bases__ == (QMainWindow,)


def _foreign_private(tree: ast.AST) -> list[tuple[int, str]]:
    """``x._name`` where ``x`` is not ``self`` itself (``self._a._b``, ``part._b``):
    a private attribute of another object. Dunder names are not private."""
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Attribute):
            continue
        name = node.attr
        if not name.startswith("_") or (name.startswith("__") and name.endswith("__")):
            continue
        owner = node.value
        if isinstance(owner, ast.Name) and owner.id in ("self", "cls"):
            continue
        found.append((node.lineno, ast.unparse(node)))
    return found


def test_no_part_reaches_into_private_attributes_of_another():
    offences = []
    for path in WINDOW_FILES:
        for line, text in _foreign_private(ast.parse(path.read_text(encoding="utf-8"))):
            offences.append(f"{path.relative_to(ROOT)}:{line}: {text}")
    assert not offences, "private attributes reached from outside: " + "; ".join(offences)


def test_no_part_is_a_mixin():
    """The window's parts are classes of their own: none is mixed into MainWindow and none
    uses attributes it does not set itself (each ``self.x`` read is set in that class, or
    is a method or a Qt base class's)."""
    for path in WINDOW_FILES[1:]:
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for cls in (n for n in tree.body if isinstance(n, ast.ClassDef)):
            bases = [ast.unparse(b) for b in cls.bases]
            if bases:  # a Qt class (a QObject with signals, a dialog), never a mixin host
                assert all(b.startswith("Q") for b in bases), (path.name, cls.name, bases)
                continue
            own = {n.name for n in cls.body if isinstance(n, ast.FunctionDef)}
            for node in ast.walk(cls):
                if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                        and node.value.id == "self" and isinstance(node.ctx, ast.Store):
                    own.add(node.attr)
            used = {node.attr for node in ast.walk(cls) if isinstance(node, ast.Attribute)
                    and isinstance(node.value, ast.Name) and node.value.id == "self"}
            assert used <= own, (path.name, cls.name, sorted(used - own))


def test_the_private_reach_check_would_catch_one():
    """The check above is not vacuous: a part reading another's private attribute, or an
    object's, is found."""
    tree = ast.parse("class A:\n    def f(self):\n        return self._views._serial, "
                     "rec._logged, self._mine\n")
    assert [text for _, text in _foreign_private(tree)] == ["self._views._serial",
                                                           "rec._logged"]
