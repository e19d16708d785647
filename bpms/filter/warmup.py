"""The filters' compiled kernels, made ready before they are needed.

The attitude filters run as numba kernels. The first time on a machine (or after an update)
numba compiles them, which takes several seconds; later runs load the compiled code from
numba's on-disk cache in a fraction of a second. :func:`ensure_kernels` runs every kernel of a
filter once on a few synthetic frames, so that this happens at a known moment (when a
processor is built, before any live frame is accepted) instead of inside the first frames.
When that takes longer than :data:`NOTICE_AFTER_S`, a notice and the progress go to stderr:
on a terminal one line updated in place (``\\r``), in a log file or pipe plain lines.
``bpms warmup`` does it ahead of time.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import TextIO

import numpy as np

from bpms.io.frames import N_CHANNELS, N_IMUS, encode_frame

#: Filters whose kernels numba compiles (``vqf`` runs in the vqf package's own code).
COMPILED_FILTERS = ("mahony", "observer", "adaptive")
#: Filters whose whole path has numpy twins (:mod:`bpms.filter.twins`: calibration, the
#: Mahony filter, the state guard, the disturbance indicators, Reset Zero; vqf is its own
#: package): short recordings run without numba.
TWIN_FILTERS = ("mahony", "vqf")
#: Say something when getting the kernels ready takes longer than this, s.
NOTICE_AFTER_S = 2.0

_ready: set[str] = set()
_lock = threading.RLock()


#: The two ways the kernels are called: whole recordings in batches, and frame by frame live.
PATHS = ("batch", "live")


def kernels_ready(algorithm: str, paths: tuple[str, ...] = PATHS) -> bool:
    """True once :func:`ensure_kernels` has run for ``algorithm`` and ``paths`` here."""
    return algorithm not in COMPILED_FILTERS or all((algorithm, p) in _ready for p in paths)


def _frames(n: int = 4) -> np.ndarray:
    """A still, level suit in raw counts ``[n, 18, 9]`` int16 (values only need to be valid)."""
    raw = np.zeros((n, N_IMUS, N_CHANNELS), dtype=np.int16)
    raw[..., 2] = 256  # accelerometer z: 1 g
    raw[..., 3] = 150  # magnetometer x
    raw[..., 5] = 300  # magnetometer z (dip)
    return raw


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
                   paths: tuple[str, ...] = PATHS, stream: TextIO | None = None,
                   notice_after_s: float = NOTICE_AFTER_S) -> float:
    """Compile (first run) or load the kernels of ``algorithms`` (default: every compiled
    filter) for ``paths`` (``"batch"``: whole recordings, ``"live"``: frame by frame). Once per
    process, filter and path; thread-safe. Returns the seconds it took (0 when nothing was
    left to do)."""
    if algorithms is None:
        algorithms = COMPILED_FILTERS
    elif isinstance(algorithms, str):
        algorithms = (algorithms,)
    todo = [(a, p) for a in algorithms if a in COMPILED_FILTERS for p in PATHS
            if p in paths and (a, p) not in _ready]
    if not todo:  # the common case, without taking the lock
        return 0.0
    with _lock:
        todo = [key for key in todo if key not in _ready]
        if not todo:
            return 0.0
        _ready.update(todo)  # the processors built and run below must not warm up again
        from bpms.filter.processor import BodyPoseProcessor
        from bpms.io.options import Options

        t0 = time.monotonic()
        raw = _frames()
        errors = np.zeros((len(raw), N_IMUS, 3), dtype=bool)
        errors[1, 0, 1] = True  # one failed magnetometer: the hold path runs too
        progress = Progress(len(todo), stream, notice_after_s)
        try:
            for algorithm, path in todo:
                options = Options()
                options.filter.algorithm = algorithm
                processor = BodyPoseProcessor(options=options)
                progress.step(f"{algorithm}, {'whole recordings' if path == 'batch' else 'live'}")
                if path == "batch":
                    processor.process(raw)
                    last = processor.process(raw, errors)
                else:
                    for k in range(len(raw)):
                        processor.step(raw[k])
                        processor.step(raw[k], errors[k])
                    processor.step_wire(encode_frame(raw[0]))  # bpms.filter.live_frame
                    processor.reset_zero()
                    last = processor.step(raw[0])
                # the body's kernels (bpms.filter.body_kernels)
                _ = (last.euler_output, last.joint_angles, last.joint_positions)
                progress.advance()
        except BaseException:
            _ready.difference_update(todo)
            raise
        finally:
            progress.close()
        return time.monotonic() - t0
