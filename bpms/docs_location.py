"""Where the user's documentation is: the ``docs`` folder shipped inside the installed package,
or ``docs/`` of the source tree when running from a checkout. Only the standard library."""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def docs_dir() -> Path | None:
    """The folder holding ``index.md`` and the other pages, or None when it is missing."""
    return next((candidate for candidate in (_PACKAGE / "docs", _PACKAGE.parent / "docs")
                 if (candidate / "index.md").is_file()), None)


def docs_hint() -> str:
    """One sentence telling where the documentation is (for ``--help`` texts and messages)."""
    where = docs_dir()
    if where is None:
        return "Documentation: the docs/ folder of the BPMS Suite source distribution."
    return f"Documentation: {where} (start with index.md)."
