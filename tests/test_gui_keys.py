"""One source for help: the 3D view's key-and-mouse table is what the views dispatch from, what
the help shows, and what docs/3d-views.md lists (issue 27.4)."""

from __future__ import annotations

import re
from pathlib import Path

from PyQt6.QtCore import Qt

from bpms.gui.view3d_keys import (
    PLOT_BINDINGS,
    VIEW3D_BINDINGS,
    command_for,
    help_html,
    short_help,
)

DOC = Path(__file__).resolve().parents[1] / "docs" / "3d-views.md"


def _doc_table() -> list[tuple[str, str]]:
    text = DOC.read_text(encoding="utf-8")
    section = text[text.index("## Keys and mouse (3D view)"):]
    section = section[:section.index("\n\n", section.index("|---|---|"))]
    rows = [line.strip("|").split("|") for line in section.splitlines()
            if line.startswith("|") and "---" not in line]
    return [(a.strip(), b.strip()) for a, b in rows[1:]]


def test_the_docs_list_exactly_the_table_the_views_use():
    assert _doc_table() == [(b.inputs, b.action) for b in VIEW3D_BINDINGS]


def test_each_key_runs_one_command_and_the_commands_exist_on_the_view():
    seen: dict = {}
    for binding in VIEW3D_BINDINGS:
        for key, shift in binding.presses:
            for s in ((False, True) if shift is None else (shift,)):
                assert (key, s) not in seen, f"{key} bound twice"
                seen[(key, s)] = binding.command
                assert command_for(VIEW3D_BINDINGS, key, s) == binding.command
    assert command_for(VIEW3D_BINDINGS, Qt.Key.Key_F1, False) is None  # to the main window
    assert command_for(VIEW3D_BINDINGS, Qt.Key.Key_Left, True) == "orbit_step"
    assert command_for(VIEW3D_BINDINGS, Qt.Key.Key_Left, False) == "pan_step"
    source = (Path(__file__).resolve().parents[1] / "bpms" / "gui" / "view3d_gl.py").read_text()
    for binding in VIEW3D_BINDINGS:
        if binding.command:
            assert re.search(rf"def {binding.command}\(self, \w+", source), binding.command


def test_the_help_page_and_the_tooltip_come_from_the_table():
    page = help_html("3D view", VIEW3D_BINDINGS) + help_html("Plots", PLOT_BINDINGS)
    for binding in (*VIEW3D_BINDINGS, *PLOT_BINDINGS):
        assert binding.inputs.replace("<", "&lt;") in page
        assert binding.action.replace("<", "&lt;") in page
    tip = short_help()
    assert "c Reset Zero" in tip and "r reset the view" in tip and "left drag" not in tip
