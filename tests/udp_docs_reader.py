"""The third-party UDP decoder of docs/udp.md (the ``# bpms-udp-reader`` block), loaded from the
documentation itself: the tests decode datagrams with what a lab would copy, not with the
suite's own codec."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "udp.md"


def docs_reader() -> Callable[[bytes], dict | None]:
    """The docs decoder's ``parse(datagram)``."""
    text = DOC.read_text(encoding="utf-8")
    start = text.index("# bpms-udp-reader")
    namespace: dict = {"__name__": "docs_example"}
    exec(compile(text[start:text.index("```", start)], "docs/udp.md", "exec"), namespace)
    return namespace["parse"]
