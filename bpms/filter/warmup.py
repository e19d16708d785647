"""The filters' compiled kernels, made ready before they are needed.

The loops that carry state from frame to frame — each attitude filter's step, the state
guard, the disturbance indicators and the knees' and elbows' heading constraint — are numba
kernels (``numba.njit(cache=True)``). The first time on a
machine (or after an update of numba or of the kernel's file) numba compiles them, which takes
a few seconds; later runs load the compiled code from numba's on-disk cache in a fraction of a
second. :func:`ensure_kernels` runs the kernels one filter needs once on a few synthetic
frames, so that this happens at a known moment (at the first frame a processor filters, or
before a live session accepts any frame) and only for what is used. When that takes longer
than :data:`NOTICE_AFTER_S` *and* something actually compiles (numba's ``numba:compile``
events, which loading from the cache does not raise; a child process says so on its
standard output), a notice and the progress go to stderr: on a terminal one line updated in
place (``\\r``), in a log file or pipe plain lines. Loading cached kernels on a busy machine
may take as long, and says nothing (issue 43.7). ``bpms warmup`` does it ahead
of time for every filter, sharing the parts out over one process per core.

numba keys each kernel's cache by its own source file (and numba's version): every kernel
calls only kernels of its own module (tests/test_structure.py checks), so the cache can never
hold machine code built from an older version of another file.
"""

from __future__ import annotations

import contextlib
import subprocess
import sys
import threading
import time
from typing import Any, TextIO

import numpy as np

from bpms.io.frames import N_IMUS
from bpms.progress import write_progress

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
    """Progress of a few slow steps on ``stream``, shown only once ``notice_after_s`` passed:
    each step as :func:`bpms.progress.write_progress` shows it (in place on a terminal)."""

    def __init__(self, total: int, stream: TextIO | None = None,
                 notice_after_s: float = NOTICE_AFTER_S) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.total = total
        self.done = 0
        self.label = ""
        self.shown = False
        self.due = False  # notice_after_s has passed
        self.compiling = False  # something compiles (not only loads from the cache)
        self.t0 = time.monotonic()
        self._lock = threading.Lock()
        self._timer = threading.Timer(notice_after_s, self._due)
        self._timer.daemon = True
        self._timer.start()

    def _line(self) -> str:
        return (f"bpms: compiling the filters for this machine (once; 'bpms warmup' does it "
                f"ahead of time): {self.done}/{self.total} {self.label}")

    def _write(self, final: bool = False) -> None:
        with contextlib.suppress(OSError, ValueError):  # a closed stream
            write_progress(self._line(), self.stream, final)

    def _due(self) -> None:
        self.due = True
        self._show()

    def _show(self) -> None:
        with self._lock:
            if self.done >= self.total or not (self.due and self.compiling):
                return
            self.shown = True
            self._write()

    def compile_started(self) -> None:
        """Something compiles (a numba compile event here, or a child said so)."""
        if not self.compiling:
            self.compiling = True
            self._show()

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
                self._write(final=True)


#: The compiled parts each filter needs (``adaptive`` runs the observer's kernel; ``vqf``
#: runs in the vqf package's own code).
PARTS = {"mahony": ("mahony", "disturbance", "hinge"),
         "observer": ("observer", "disturbance", "hinge"),
         "adaptive": ("observer", "disturbance", "hinge"),
         "vqf": ("disturbance", "hinge")}
#: Seconds each part takes to compile on the bench machine: how the parts are shared out.
_COMPILE_S = {"mahony": 2.6, "observer": 3.3, "disturbance": 1.7, "hinge": 1.8}
_done_parts: set[str] = set()


def ensure_kernels(algorithms: str | tuple[str, ...] | list[str] | None = None,
                   stream: TextIO | None = None,
                   notice_after_s: float = NOTICE_AFTER_S, processes: int = 1) -> float:
    """Compile (first run) or load the kernels of ``algorithms`` (default: every filter), once
    per process and filter; thread-safe. With ``processes`` > 1 the parts are compiled in
    that many processes at once (this one and child processes, which leave their work in
    numba's on-disk cache; whatever a child did not leave there is compiled here after it).
    Returns the seconds it took (0 when nothing was left to do)."""
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
        for algorithm in todo:
            if algorithm not in PARTS:
                raise ValueError(f"unknown attitude filter '{algorithm}'")
        parts = list(dict.fromkeys(p for a in todo for p in PARTS[a] if p not in _done_parts))
        t0 = time.monotonic()
        progress = Progress(len(parts), stream, notice_after_s)
        children: list[tuple[subprocess.Popen, list[str]]] = []
        listening = _CompileListener(progress.compile_started)
        try:
            listening.__enter__()
            here, elsewhere = _share_out(parts, processes)
            children = [(_start_child(group, progress.compile_started), group)
                        for group in elsewhere]
            for part in here:
                progress.step(part)
                _run_part(part)
                progress.advance()
            for child, group in children:
                progress.step(f"{', '.join(group)} (in another process)")
                child.wait()
                for part in group:  # from the cache the child left (compiled here if not)
                    _run_part(part)
                    progress.advance()
            _ready.update(todo)
        finally:
            listening.__exit__(None, None, None)
            for child, _ in children:
                if child.poll() is None:
                    child.kill()
            progress.close()
        return time.monotonic() - t0


def _share_out(parts: list[str], processes: int) -> tuple[list[str], list[list[str]]]:
    """The parts this process compiles and the groups for child processes: the longest part
    first to the group with the least work, so the processes finish together."""
    groups: list[list[str]] = [[] for _ in range(max(1, min(processes, len(parts))))]
    if len(groups) > 1 and getattr(sys, "frozen", False):  # a bundle has no ``-m``
        groups = groups[:1]
    load = [0.0] * len(groups)
    for part in sorted(parts, key=lambda name: -_COMPILE_S[name]):
        k = load.index(min(load))
        groups[k].append(part)
        load[k] += _COMPILE_S[part]
    return groups[0], [g for g in groups[1:] if g]


class _CompileListener:
    """Calls ``on_compile`` when numba starts compiling (in this process), while entered."""

    def __init__(self, on_compile) -> None:
        self.on_compile = on_compile
        self._listener: Any = None  # a numba event listener while registered

    def __enter__(self) -> _CompileListener:
        from numba.core import event

        outer = self

        class Listener(event.Listener):
            def on_start(self, ev) -> None:
                outer.on_compile()

            def on_end(self, ev) -> None:
                pass

        self._listener = Listener()
        event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc) -> None:
        from numba.core import event

        if self._listener is not None:
            event.unregister("numba:compile", self._listener)
            self._listener = None


def _start_child(parts: list[str], on_compile=None) -> subprocess.Popen:
    """A child Python compiling ``parts`` into numba's on-disk cache (whatever it fails at
    is compiled by this process afterwards). It writes a line on its standard output when it
    starts compiling (not when it only loads from the cache): ``on_compile`` is called then."""
    child = subprocess.Popen([sys.executable, "-m", "bpms.filter.warmup", *parts],
                             stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                             stderr=subprocess.DEVNULL)

    def watch() -> None:
        assert child.stdout is not None
        with child.stdout:
            for _ in child.stdout:
                if on_compile is not None:
                    on_compile()

    threading.Thread(target=watch, name="bpms-warmup-child", daemon=True).start()
    return child


def _run_part(part: str) -> None:
    """Run one compiled part on a few synthetic frames of a still, level suit, with a failed
    magnetometer and a reset (the argument types are those of every later call, so nothing
    compiles again: tests/test_warmup.py watches numba's compile events on the live path)."""
    if part in _done_parts:
        return
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
    if part in ("mahony", "observer"):
        bank = make_bank(gravity, FilterOptions(algorithm=part))
        terms = {"store_terms": True} if part == "mahony" else {}
        bank.process(acc, mag, gyr, errors, resets, **terms)
        guarded_process(bank, StateGuard(N_IMUS), acc, mag, gyr, errors, **terms)
    if part == "disturbance":
        DisturbanceTracker(gravity, 0.02).update(acc, mag, gyr, errors)
    if part == "hinge":  # the flags as the disturbance indicators give them, made up here so
        # that this part compiles nothing of theirs (another process may be doing that)
        flagged = np.zeros((n, N_IMUS), np.bool_)
        flagged[1, 0] = True
        heading_deg = np.where(flagged, 10.0, 0.0)
        level = np.ascontiguousarray(np.broadcast_to(np.eye(3), (n, N_IMUS, 3, 3)))
        HingeConstraint(0.02).apply_in_place(level.copy(), level.copy(), gyr, flagged,
                                             heading_deg)
    _done_parts.add(part)


def _say_compiling() -> None:
    print("compiling", flush=True)


if __name__ == "__main__":  # a child of ensure_kernels(processes > 1): compile these parts
    with _CompileListener(_say_compiling):
        for name in sys.argv[1:]:
            _run_part(name)
