"""Progress lines: rewritten in place on a terminal, one plain line each elsewhere.

A carriage return (``\\r``) only makes sense on a terminal; in a log file or a pipe it leaves
every update on one garbled line, so there each update is a line of its own.
"""

from __future__ import annotations

import sys
from typing import TextIO


def is_terminal(stream: TextIO) -> bool:
    """True when ``stream`` is an interactive terminal."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def write_progress(text: str, stream: TextIO | None = None, final: bool = False) -> None:
    """Show one progress update: on a terminal it replaces the previous one (and ``final``
    ends the line), elsewhere it is written as its own line."""
    stream = sys.stderr if stream is None else stream
    if is_terminal(stream):
        stream.write("\r" + text + ("\n" if final else ""))
    else:
        stream.write(text + "\n")
    stream.flush()
