"""The filters' compiled kernels, made ready before they are needed.

The loops that carry state from frame to frame — each attitude filter's step, the state
guard, the disturbance indicators and the knees' and elbows' heading constraint — are numba
kernels (``numba.njit(cache=True)``). The first time on a
machine (or after an update of numba or of the kernel's file) numba compiles them, which takes
a few seconds; later runs load the compiled code from numba's on-disk cache in a fraction of a
second. :func:`ensure_kernels` runs the kernels one filter needs once on a few synthetic
frames, so that this happens at a known moment (at the first frame a processor filters, or
before a live session accepts any frame) and only for what is used. When that takes longer
than :data:`NOTICE_AFTER_S`, a notice and the progress go to stderr: on a terminal one line
updated in place (``\\r``), in a log file or pipe plain lines. ``bpms warmup`` does it ahead
of time for every filter.

numba keys each kernel's cache by its own source file (and numba's version): every kernel
calls only kernels of its own module (tests/test_structure.py checks), so the cache can never
hold machine code built from an older version of another file.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import TextIO

import numpy as np

from bpms.io.frames import N_IMUS

#: Every selectable filter (``vqf`` runs in the vqf package's own code; its warm-up
#: compiles the disturbance indicators' and the hinge constraint's kernels).
FILTERS = ("mahony", "observer", "adaptive", "vqf")
#: Say something when getting the kernels ready takes longer than this, s.
NOTICE_AFTER_S = 2.0

_ready: set[str] = set()
_lock = threading.RLock()


def kernels_ready(algorithm: str) -> bool:
    """True once :func:`ensure_kernels` has run for ``algorithm`` in this process."""
    return algorithm in _ready


class Progress:
    """Progress of a few slow steps on ``stream``, shown only once ``notice_after_s`` passed.
    On a terminal one line is rewritten with ``\\r``; elsewhere each step is its own line."""

    def __init__(self, total: int, stream: TextIO | None = None,
                 notice_after_s: float = NOTICE_AFTER_S) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.total = total
        self.done = 0
        self.label = ""
        self.shown = False
        self.t0 = time.monotonic()
        try:
            self.tty = bool(self.stream.isatty())
        except (AttributeError, ValueError):
            self.tty = False
        self._lock = threading.Lock()
        self._timer = threading.Timer(notice_after_s, self._show)
        self._timer.daemon = True
        self._timer.start()

    def _line(self) -> str:
        return (f"bpms: compiling the filters for this machine (once; 'bpms warmup' does it "
                f"ahead of time): {self.done}/{self.total} {self.label}")

    def _write(self, text: str, end: str) -> None:
        try:
            self.stream.write(text + end)
            self.stream.flush()
        except (OSError, ValueError):
            pass

    def _show(self) -> None:
        with self._lock:
            if self.done >= self.total:
                return
            self.shown = True
            self._write(("\r" if self.tty else "") + self._line(), "" if self.tty else "\n")

    def step(self, label: str) -> None:
        """The next step (``label``) starts."""
        with self._lock:
            self.label = label
        if self.shown:
            self._show()

    def advance(self) -> None:
        with self._lock:
            self.done += 1

    def close(self) -> None:
        self._timer.cancel()
        with self._lock:
            if self.shown:
                seconds = time.monotonic() - self.t0
                self.label = f"done in {seconds:.1f} s"
                self._write(("\r" if self.tty else "") + self._line(), "\n")


def ensure_kernels(algorithms: str | tuple[str, ...] | list[str] | None = None,
                   stream: TextIO | None = None,
                   notice_after_s: float = NOTICE_AFTER_S) -> float:
    """Compile (first run) or load the kernels of ``algorithms`` (default: every filter), once
    per process and filter; thread-safe. Returns the seconds it took (0 when nothing was left
    to do)."""
    if algorithms is None:
        algorithms = FILTERS
    elif isinstance(algorithms, str):
        algorithms = (algorithms,)
    todo = [a for a in algorithms if a not in _ready]
    if not todo:  # the common case, without taking the lock
        return 0.0
    with _lock:
        todo = [a for a in todo if a not in _ready]
        if not todo:
            return 0.0
        t0 = time.monotonic()
        progress = Progress(len(todo), stream, notice_after_s)
        try:
            for algorithm in todo:
                progress.step(algorithm)
                _run_kernels(algorithm)
                _ready.add(algorithm)
                progress.advance()
        finally:
            progress.close()
        return time.monotonic() - t0


def _run_kernels(algorithm: str) -> None:
    """Run ``algorithm``'s bank, the state guard, the disturbance indicators and the hinge
    constraint on a few synthetic frames of a still, level suit, with a failed magnetometer
    and a reset (the argument types are those of every later call, so nothing compiles
    again: tests/test_warmup.py watches numba's compile events on the live path)."""
    from bpms.filter.algorithms import make_bank
    from bpms.filter.disturbance import DisturbanceTracker
    from bpms.filter.guard import StateGuard, guarded_process
    from bpms.filter.hinge import HingeConstraint
    from bpms.io.options import FilterOptions

    n = 4
    gravity = np.full(N_IMUS, 256.0)
    acc = np.zeros((n, N_IMUS, 3))
    acc[..., 2] = 256.0
    mag = np.zeros((n, N_IMUS, 3))
    mag[..., 0], mag[..., 2] = 30.0, 60.0
    gyr = np.zeros((n, N_IMUS, 3))
    errors = np.zeros((n, N_IMUS, 3), np.bool_)
    errors[1, 0, 1] = True
    resets = np.zeros((n, N_IMUS), np.bool_)
    resets[2, 3] = True
    if algorithm != "vqf":  # the vqf package's own code needs no compiling
        bank = make_bank(gravity, FilterOptions(algorithm=algorithm))
        terms = {"store_terms": True} if algorithm == "mahony" else {}
        bank.process(acc, mag, gyr, errors, resets, **terms)
        guarded_process(bank, StateGuard(N_IMUS), acc, mag, gyr, errors, **terms)
    flags = DisturbanceTracker(gravity, 0.02).update(acc, mag, gyr, errors)
    level = np.ascontiguousarray(np.broadcast_to(np.eye(3), (n, N_IMUS, 3, 3)))
    HingeConstraint(0.02).apply_in_place(level.copy(), level.copy(), np.zeros((n, N_IMUS, 3)),
                                         gyr, flags.mag, flags.mag_heading_deg)
