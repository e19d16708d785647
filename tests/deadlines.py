"""How long a test may wait on this machine: one scale for every deadline (issue 46.7).

A deadline in a test is a bound for a condition that normally comes true quickly; on a loaded
machine (a lab's CI runner, or ``bash tools/dev.sh test --load 2``) the same work takes longer.
:func:`deadline_scale` is the one factor every waiting deadline is multiplied by:

- ``BPMS_TEST_DEADLINE_SCALE`` (a number >= 1) when set, else
- ``1 + load`` where load is the 1-minute load average per CPU core (``os.getloadavg``; 0 where
  the platform has none, e.g. Windows), plus the CPU-bound processes ``BPMS_TEST_LOAD`` says
  were started beside the suite (their share is already in the load average after a minute,
  not at once), capped at 8.

The product's own time rules (1 s of silence, the rate window) are tested with injected clocks,
never with this: a scale only lengthens how long a test waits, never what it expects."""

from __future__ import annotations

import functools
import os

MAX_SCALE = 8.0


@functools.cache
def deadline_scale() -> float:
    """The factor (>= 1) for every deadline a test waits on (see the module's text)."""
    fixed = os.environ.get("BPMS_TEST_DEADLINE_SCALE")
    if fixed:
        return max(1.0, float(fixed))
    cores = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):  # Windows
        load = 0.0
    extra = float(os.environ.get("BPMS_TEST_LOAD", "0") or 0)
    return min(MAX_SCALE, 1.0 + max(load, extra) / cores)


def scaled(seconds: float) -> float:
    """``seconds`` times :func:`deadline_scale`."""
    return seconds * deadline_scale()
