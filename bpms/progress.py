"""Progress lines: rewritten in place on a terminal, a few plain lines elsewhere.

A carriage return (``\\r``) only makes sense on a terminal; in a log file or a pipe it leaves
every update on one garbled line. So on a terminal each update replaces the previous one; in a
log or a pipe an update becomes a line of its own only every 10 % of the work or every 5 s
(whichever comes first), plus the last one.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TextIO

#: Outside a terminal: a line at least every this many percent of the work ...
STEP_PERCENT = 10
#: ... or every this many seconds, whichever comes first.
EVERY_S = 5.0


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


class ProgressLine:
    """The progress of one job of ``total`` units on ``stream`` (default stderr).

    :meth:`update` with the units done so far: on a terminal every update is shown (in place);
    elsewhere only when :data:`STEP_PERCENT` more percent are done or :data:`EVERY_S` seconds
    passed since the last line, and always the last (``done >= total``)."""

    def __init__(self, total: int, stream: TextIO | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.total = max(int(total), 1)
        self.stream = sys.stderr if stream is None else stream
        self.clock = clock
        self.lines = 0  # updates shown
        self.done = 0  # units done at the last update
        self._last_percent = -STEP_PERCENT
        self._last_time = -float("inf")

    def update(self, done: int, text: str) -> bool:
        """Show ``text`` for ``done`` units if it is due; True when it was shown."""
        self.done = done
        percent = 100 * done // self.total
        final = done >= self.total
        now = self.clock()
        if not (is_terminal(self.stream) or final
                or percent >= self._last_percent + STEP_PERCENT
                or now - self._last_time >= EVERY_S):
            return False
        write_progress(text, self.stream, final)
        self._last_percent, self._last_time = percent, now
        self.lines += 1
        return True


_open: dict[str, ProgressLine] = {}


def report(label: str, done: int, total: int, stream: TextIO | None = None) -> None:
    """``label: 42% (n/N frames)`` through one :class:`ProgressLine` per label (a new one when
    ``done`` goes back, i.e. the next job of that label); the line ends at ``done >= total``."""
    line = _open.get(label)
    if line is None or line.total != max(total, 1) or done < line.done:
        line = _open[label] = ProgressLine(total, stream)
    line.update(done, f"{label}: {100 * done // max(total, 1):3d}% ({done}/{total} frames)")
    if done >= total:
        _open.pop(label, None)


def stderr_progress(label: str, done: int, total: int) -> None:
    """:func:`report` on stderr for work above 30,000 frames (10 minutes at 50 Hz), the
    analysis commands' progress per chunk; shorter work shows none."""
    if total > 30_000:
        report(label, done, total)
