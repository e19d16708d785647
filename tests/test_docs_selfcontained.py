"""The documentation is the repository's own: nothing user-facing points outside it, every page
a text names exists, and the installed package finds its copy of the pages."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUTSIDE = re.compile(r"\.\./shared|SPEC\.md|SPEC §")
TEXT_SUFFIXES = {".py", ".md", ".toml", ".h", ".cpp", ".ino", ".txt", ".cfg", ""}


def _texts():
    yield ROOT / "README.md"
    for folder in ("docs", "bpms", "calib"):
        for path in (ROOT / folder).rglob("*"):
            if (path.is_file() and path.suffix in TEXT_SUFFIXES
                    and "__pycache__" not in path.parts):
                yield path


def test_nothing_points_outside_the_repository():
    hits = []
    for path in _texts():
        for n, line in enumerate(path.read_text(encoding="utf-8", errors="replace")
                                 .splitlines(), 1):
            if OUTSIDE.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert hits == []


def test_every_docs_page_named_exists():
    missing = []
    for path in _texts():
        text = path.read_text(encoding="utf-8", errors="replace")
        names = set(re.findall(r"docs/([\w.-]+\.md)", text))
        if path.parent.name == "docs":
            names |= {m.split("#")[0] for m in re.findall(r"\]\(([\w.-]+\.md(?:#[\w-]+)?)\)",
                                                          text)}
        for name in names:
            if name != "README.md" and not (ROOT / "docs" / name).is_file():
                missing.append(f"{path.relative_to(ROOT)} names docs/{name}")
    assert missing == []


def test_the_facts_the_texts_rely_on_are_written_down():
    """Spot checks of the self-contained facts: the conversion constants and formulas."""
    units = (ROOT / "docs" / "units.md").read_text(encoding="utf-8")
    for fact in ("0.06957", "0.000917431", "9.81 / Gravity", "100 / (max − offset)",
                 "Gravity / (max − offset)", "north-east-down", "Rz(ψ) · Ry(θ) · Rx(φ)"):
        assert fact in units, fact
    suit = (ROOT / "docs" / "suit.md").read_text(encoding="utf-8")
    for fact in ("`0x00`", "`0x01`", "`0x02`", "stale", "Right Shoulder | roll 90°"):
        assert fact in suit, fact
    body = (ROOT / "docs" / "body-model.md").read_text(encoding="utf-8")
    for fact in ("R_staticᵀ · R_dynamic", "yaw_i − yaw_hip", "0.43"):
        assert fact in body, fact


def test_the_docs_location_is_found():
    from bpms.docs_location import docs_dir, docs_hint

    where = docs_dir()
    assert where is not None and (where / "index.md").is_file()
    assert str(where) in docs_hint()
