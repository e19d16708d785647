"""The filters' kernels: compiled by numba when there is enough work, numpy twins when not.

Every per-frame loop of the filter layer (calibration, the attitude filters, the state guard,
the disturbance indicators, Reset Zero) is written once as a scalar loop and compiled by numba
(``cache=True``: compiled once per machine, later loaded from disk). Importing numba and
loading its cached code costs about 0.6 s, several times the work of a short recording. So:

- :func:`kernel` replaces ``numba.njit(cache=True)``. It does not import numba: the first call
  of any kernel outside :func:`twins` imports numba and gives *every* registered kernel its
  numba dispatcher at once. A compiled kernel calling another by its global name sees that
  dispatcher (numba's ``_numba_type_`` protocol); Python callers go through the kernel object,
  which picks the twin or the dispatcher;
- a kernel may name a *twin*: a numpy function with the same arguments that writes the same
  outputs in place, **the same numbers bit for bit** (the same operations in the same order,
  elementwise over IMUs or frames; transcendental functions through :mod:`math`, the C
  library numba also calls). Inside :func:`twins` a kernel with a twin runs the twin and numba
  stays unloaded. tests/test_kernels.py holds every twin to bit-equality with its kernel;
- :func:`claim_twin_frames` decides: twins for the first :data:`TWIN_FRAME_BUDGET` frames a
  process filters while numba is not loaded, compiled kernels after that. A whole recording
  is decided at once by its length (:meth:`bpms.filter.processor.BodyPoseProcessor.plan`).
  The environment variable ``BPMS_TWIN_FRAMES`` sets the budget (0: always compiled).

Live sessions never use twins: they load the compiled kernels before the first frame
(:mod:`bpms.filter.warmup`).
"""

from __future__ import annotations

import importlib
import logging
import os
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

log = logging.getLogger(__name__)

#: Frames a process filters with the numpy twins before numba pays off (≈ 1 min at 50 Hz:
#: the twins take ~0.3 ms per frame of 18 IMUs, importing numba and loading its cache ~0.6 s).
DEFAULT_TWIN_FRAMES = 3000
#: Environment variable that sets the budget (0: always compiled).
TWIN_FRAMES_ENV = "BPMS_TWIN_FRAMES"


def _budget() -> int:
    text = os.environ.get(TWIN_FRAMES_ENV, "").strip()
    if not text:
        return DEFAULT_TWIN_FRAMES
    try:
        value = int(text)
        if value < 0:
            raise ValueError
    except ValueError:
        log.warning("%s=%r is not a whole number of frames ≥ 0: using %d", TWIN_FRAMES_ENV,
                    text, DEFAULT_TWIN_FRAMES)
        return DEFAULT_TWIN_FRAMES
    return value


#: This process's budget (the environment variable, else the default).
TWIN_FRAME_BUDGET = _budget()

_kernels: list[Kernel] = []
_lock = threading.RLock()
_local = threading.local()
_numba_loaded = False
_twin_frames = 0


class Kernel:
    """A numba kernel that is compiled on first use, with an optional numpy twin.

    ``twin``: ``"module:function"`` of the numpy twin (imported when first used)."""

    def __init__(self, func: Callable[..., Any], twin: str | None = None) -> None:
        self.func = func
        self.twin_name = twin
        self.dispatcher: Any = None
        self._twin: Callable[..., Any] | None = None
        self.__name__ = func.__name__
        self.__qualname__ = func.__qualname__
        self.__module__ = func.__module__
        self.__doc__ = func.__doc__

    def twin(self) -> Callable[..., Any] | None:
        """The numpy twin, or None."""
        if self._twin is None and self.twin_name is not None:
            module, _, name = self.twin_name.partition(":")
            self._twin = getattr(importlib.import_module(module), name)
        return self._twin

    def __call__(self, *args: Any) -> Any:
        if getattr(_local, "twins", False) and self.twin_name is not None:
            return self.twin()(*args)
        if self.dispatcher is None:
            load_numba()
        return self.dispatcher(*args)

    @property
    def _numba_type_(self) -> Any:
        """What numba sees when a compiled kernel calls this one by its global name: the
        dispatcher's type (numba's ``typeof`` protocol)."""
        if self.dispatcher is None:
            load_numba()
        return self.dispatcher._numba_type_

    def __repr__(self) -> str:
        return f"<kernel {self.__module__}.{self.__qualname__}>"


def kernel(func: Callable[..., Any] | None = None, *, twin: str | None = None) -> Any:
    """Decorator for a numba kernel (``@kernel`` or ``@kernel(twin="module:function")``).

    Once numba is loaded, a new kernel gets its numba dispatcher straight away."""

    def wrap(f: Callable[..., Any]) -> Any:
        k = Kernel(f, twin)
        with _lock:
            _kernels.append(k)
            if _numba_loaded:  # a module imported later: its dispatcher at once
                _bind([k])
        return k

    return wrap(func) if func is not None else wrap


#: The modules that define kernels. A compiled kernel may call kernels of other modules (the
#: live frame calls the filter's, the guard's, ...), but numba keys its on-disk cache by the
#: kernel's own file only: a change to a callee's file would leave stale machine code in the
#: caller's cache. Each kernel's cache is therefore keyed by all of these files
#: (tests/test_kernels.py checks the list is complete).
KERNEL_MODULES = ("mahony", "guard", "disturbance", "body_kernels", "live_frame", "observer",
                  "adaptive_observer")


def _sources_stamp() -> tuple:
    """(name, mtime, size) of every kernel module's file."""
    here = os.path.dirname(os.path.abspath(__file__))
    stamp = []
    for name in KERNEL_MODULES:
        try:
            st = os.stat(os.path.join(here, f"{name}.py"))
        except OSError:
            continue
        stamp.append((name, st.st_mtime, st.st_size))
    return tuple(stamp)


def _keyed_by_every_kernel_module(dispatcher: Any, stamp: tuple) -> None:
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    own = getattr(cache_file, "_source_stamp", None)
    if own is not None:  # numba's layout (0.5x-0.6x); another layout keeps numba's own key
        cache_file._source_stamp = (own, stamp)


def _bind(kernels: list[Kernel]) -> None:
    from numba import njit

    stamp = _sources_stamp()
    for k in kernels:
        k.dispatcher = njit(cache=True)(k.func)
        _keyed_by_every_kernel_module(k.dispatcher, stamp)


def load_numba() -> None:
    """Import numba and make every registered kernel a numba dispatcher (once; thread-safe).
    Compiling or loading each kernel's machine code still happens at its first call."""
    global _numba_loaded
    with _lock:
        if _numba_loaded:
            return
        _bind(_kernels)
        _numba_loaded = True


def numba_loaded() -> bool:
    """True once the kernels are numba dispatchers in this process."""
    return _numba_loaded


def claim_twin_frames(frames: int) -> bool:
    """True when ``frames`` more frames should run on the numpy twins: numba is not loaded and
    they fit in what is left of :data:`TWIN_FRAME_BUDGET` (then counted against it)."""
    global _twin_frames
    with _lock:
        if _numba_loaded or _twin_frames + frames > TWIN_FRAME_BUDGET:
            return False
        _twin_frames += frames
        return True


@contextmanager
def twins(on: bool = True) -> Iterator[None]:
    """Within this block (this thread only), kernels that have a numpy twin run it."""
    before = getattr(_local, "twins", False)
    _local.twins = on
    try:
        yield
    finally:
        _local.twins = before


def twins_active() -> bool:
    """True inside a :func:`twins` block of this thread."""
    return bool(getattr(_local, "twins", False))


def registered() -> list[Kernel]:
    """Every kernel defined so far (for tests and the warm-up)."""
    return list(_kernels)
