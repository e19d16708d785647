"""Bounded waiting for tests: never sleep a fixed time, never hang."""

from __future__ import annotations

import time
from collections.abc import Callable

from deadlines import deadline_scale


def wait_until(predicate: Callable[[], bool], timeout: float = 20.0) -> bool:
    """Poll ``predicate`` every 20 ms until it is true (True) or ``timeout`` s pass (False).
    ``timeout`` is the deadline on a quiet machine: it is scaled by the machine's load
    (tests/deadlines.py)."""
    end = time.monotonic() + timeout * deadline_scale()
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.02)
    return False


def inside(thread, function: str) -> bool:
    """True while ``thread`` is running ``function`` (a Python function of that name is on
    its stack): a test can wait until a reader thread has entered its blocking read instead
    of sleeping and hoping it has."""
    import sys

    frame = sys._current_frames().get(thread.ident)
    while frame is not None:
        if frame.f_code.co_name == function:
            return True
        frame = frame.f_back
    return False


def receive_until_exit(sock, proc, silence: float = 30.0, quiet: float = 0.5) -> list[bytes]:
    """Every datagram ``sock`` receives until the sender process ``proc`` has exited and the
    socket then stayed quiet for ``quiet`` s. While ``proc`` runs, ``silence`` s without a
    datagram raise TimeoutError (a stuck sender fails the test instead of hanging it).

    The socket is polled in short steps, so the end of the sender is seen within ~50 ms: a long
    blocking ``recv`` would otherwise wait its whole timeout after the last datagram."""
    out: list[bytes] = []
    silence *= deadline_scale()
    sock.settimeout(0.05)
    last = time.monotonic()
    exited_at = None
    while True:
        try:
            out.append(sock.recv(65535))
            last = time.monotonic()
            continue
        except TimeoutError:
            pass
        now = time.monotonic()
        if proc.poll() is not None:
            exited_at = exited_at or now
            if now - max(last, exited_at) >= quiet:
                return out
        elif now - last > silence:
            raise TimeoutError(f"no datagram for {silence:g} s while the sender runs")
