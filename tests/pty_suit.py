"""The simulated suit on a pseudo-terminal, reached through a path used by one test only.

The kernel hands a closed ``/dev/pts/N`` number to the next pseudo-terminal at once, so a path
kept after its server closed (a session still reopening it, a subprocess still running) would
open the *next* test's simulated suit. :func:`suit_pty` gives each server a symlink of its own
in a fresh folder and removes it before the server closes: a late opener finds nothing there
(and the port is opened for exclusive access besides, bpms/io/link.py)."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from bpms.firmware.sim.arbiter import Arbiter
from bpms.firmware.sim.server import PtyServer


@contextlib.contextmanager
def suit_pty(arbiter: Arbiter) -> Iterator[tuple[PtyServer, str]]:
    """(the started :class:`PtyServer`, the one-off path to open it by)."""
    with tempfile.TemporaryDirectory(prefix="bpms-pty-") as folder, PtyServer(arbiter) as server:
        link = Path(folder) / "suit"
        os.symlink(server.path, link)
        try:
            yield server, str(link)
        finally:
            link.unlink(missing_ok=True)  # first: nobody reaches the number once it is freed
