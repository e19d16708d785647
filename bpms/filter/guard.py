"""No silent NaN: catch a filter state that is no rotation any more, in the frame it happens.

A filter state can leave the rotations: a gain outside its stable range, absurd sensor values
(a gyroscope pinned at full scale turns a DCM by 0.8 rad per step, more than the
renormalisation can repair), non-finite input through the API. Left alone, the NaN stays for
the rest of the stream. :func:`guarded_process` runs a bank's batch and checks every output
DCM ``R`` of an IMU whose filter has produced an orientation since its last (re)start:

- *bad* = any element non-finite, or ``‖RᵀR − I‖_F > SO3_TOLERANCE`` (1e-3) plus, for the
  Mahony DCM filter only, what its first-order renormalisation leaves at that frame's turn
  rate: ``MAHONY_RENORM_K · (|ω|·dt)⁴`` (measured: 3.7e-3 at a steady 500 °/s, 0.05 at
  1000 °/s, 0.34 at the gyroscope's full scale on one axis; ≤ 1.6e-3 below 300 °/s). Without
  it, a fast but real arm swing would count as a broken state. The quaternion filters
  (observer, VQF) give exact rotations and get no allowance;
- that IMU's outputs of the bad frame are set to NaN (one frame, never more), the IMU is
  re-initialised: its next valid frame aligns it from its accelerometer and magnetometer
  exactly as at stream start (the bank's own initialisation);
- non-finite *inputs* (only possible through the API: counts from the suit are integers) are
  flagged as failed sensors (:func:`failed_inputs`), so the filter holds the last good value;
- the event is counted per IMU (:attr:`StateGuard.count`) and flagged per frame (the
  ``reinitialised[N, n]`` array returned beside the outputs).

A batch is filtered in one call as before; only when an event happens the bank is rewound to
the start of the batch (its ``snapshot()`` / ``restore()``), re-run up to the bad frame,
re-initialised and continued, so a batch and the same frames one by one give the same
numbers. After an event the rest is filtered in chunks of 1, 2, 4... frames, so a stretch
of absurd input costs one pass, not one pass per frame.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numba import njit

from bpms.filter.bank import BankOutput, MahonyBank

#: ‖RᵀR − I‖ (Frobenius) above which a DCM is no rotation any more.
SO3_TOLERANCE = 1e-3
#: Allowance of the Mahony DCM filter's renormalisation residual: K·(|ω| dt)⁴ (K = 5 bounds the
#: measured residual from 300 °/s to full scale with a margin of 1.3–2.4).
MAHONY_RENORM_K = 5.0


def so3_error(R: np.ndarray) -> np.ndarray:
    """``‖RᵀR − I‖_F`` of ``R[..., 3, 3]`` (NaN where R is not finite)."""
    R = np.asarray(R, dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):  # a runaway state may overflow: bad
        gram = np.swapaxes(R, -1, -2) @ R
        return np.sqrt(((gram - np.eye(3)) ** 2).sum(axis=(-1, -2)))


@njit(cache=True, nogil=True)
def _check(R, gyr, c4, tol, expected, bad):
    """The loop of :func:`check_rotations` (``gyr`` may be ``[0, n, 3]``: no allowance);
    returns the number of bad entries."""
    use_rate = c4 > 0.0 and gyr.shape[0] > 0
    n_bad = 0
    seen = expected.copy()
    for k in range(R.shape[0]):
        for i in range(R.shape[1]):
            finite = True
            for a in range(3):
                for b in range(3):
                    if not math.isfinite(R[k, i, a, b]):
                        finite = False
            if not finite:
                bad[k, i] = seen[i]
                n_bad += seen[i]
                continue
            err2 = 0.0
            for a in range(3):
                for b in range(3):
                    g = (R[k, i, 0, a] * R[k, i, 0, b] + R[k, i, 1, a] * R[k, i, 1, b]
                         + R[k, i, 2, a] * R[k, i, 2, b])
                    if a == b:
                        g -= 1.0
                    err2 += g * g
            limit = tol
            if use_rate:
                w2 = gyr[k, i, 0] ** 2 + gyr[k, i, 1] ** 2 + gyr[k, i, 2] ** 2
                if math.isfinite(w2):
                    limit += c4 * w2 * w2
            bad[k, i] = not (err2 <= limit * limit)  # NaN / overflow count as bad
            n_bad += bad[k, i]
            seen[i] = True
    if n_bad == 0:
        expected[:] = seen
    return n_bad


def check_rotations(R: np.ndarray, gyr: np.ndarray | None, c4: float, expected: np.ndarray
                    ) -> tuple[np.ndarray, bool]:
    """(bad ``[N, n]``, any bad) of the DCMs ``R[N, n, 3, 3]``: bad[k, i] when IMU i should
    give a rotation at frame k (``expected[i]``, or a finite frame before k) and R[k, i] is
    non-finite, or finite with ``‖RᵀR − I‖_F`` > ``SO3_TOLERANCE + c4·|ω|⁴`` (``gyr[N, n,
    3]`` rad/s; ``c4`` = 0 or ``gyr`` None: no allowance). When nothing is bad, ``expected``
    (bool ``[n]``) is updated in place: or'ed with "a finite frame in the batch"; otherwise
    it is left for the caller, who re-runs the batch up to the bad frame.

    A compiled loop because "should give a rotation" carries from frame to frame (and from
    batch to batch through ``expected``); a live frame is N = 1."""
    R = np.ascontiguousarray(R, dtype=np.float64)
    gyr = _NO_RATE if gyr is None else np.ascontiguousarray(gyr, dtype=np.float64)
    bad = np.empty(R.shape[:2], dtype=np.bool_)
    n_bad = _check(R, gyr, float(c4), SO3_TOLERANCE, expected, bad)
    return bad, n_bad > 0


_NO_RATE = np.zeros((0, 0, 3))


class StateGuard:
    """Per-IMU bookkeeping: which IMUs must give a rotation, and the re-initialisation count.

    ``expected[n]``: the IMU gave a finite orientation since the stream (re)started or the
    operator reset it (before that, NaN is its normal output; a re-initialisation by the guard
    keeps it set); ``count[n]``: re-initialisations so far (replaced, never changed in place,
    so a Result holds the counts of its own frames without a copy).
    """

    def __init__(self, n: int) -> None:
        self.n = n
        self.expected = np.zeros(n, dtype=np.bool_)
        self.count = np.zeros(n, dtype=np.int64)
        self.total = 0  # re-initialisations of all IMUs so far (= count.sum(), a plain int)

    def forget(self, imu: int | np.ndarray | None = None) -> None:
        """IMU ``imu`` (a bool mask, an index, or all when None) restarts: NaN is normal again
        until it gives an orientation."""
        if imu is None:
            self.expected[:] = False
        else:
            self.expected[imu] = False

    def accept(self, R: np.ndarray) -> None:
        """Outputs ``R[N, n, 3, 3]`` were delivered: IMUs with a finite one are expected."""
        if len(R):
            self.expected |= np.isfinite(R).all(axis=(-1, -2)).any(axis=0)


def renorm_allowance(bank: Any) -> float:
    """``c4`` of :func:`_check` for ``bank``: ``MAHONY_RENORM_K · dt⁴`` for the Mahony DCM
    filter (:class:`bpms.filter.bank.MahonyBank`), 0 for the quaternion filters."""
    if isinstance(bank, MahonyBank):
        return MAHONY_RENORM_K * float(bank.params[4]) ** 4
    return 0.0


# -- the guarded batch ------------------------------------------------------------------------
def _mark(out: BankOutput, rows: np.ndarray, imus: np.ndarray) -> None:
    out.R[rows, imus] = np.nan


def _concat(parts: list[BankOutput]) -> BankOutput:
    if len(parts) == 1:
        return parts[0]

    def join(name: str) -> np.ndarray | None:
        values = [getattr(p, name) for p in parts]
        return None if any(v is None for v in values) else np.concatenate(values)

    joined: dict[str, Any] = {f.name: join(f.name) for f in dataclasses.fields(BankOutput)}
    return BankOutput(**joined)


def _reinit(bank: Any, guard: StateGuard, imus: np.ndarray) -> None:
    # ``expected`` stays set: a re-initialisation that gives no rotation is caught again
    for i in np.flatnonzero(imus):
        bank.reset(int(i))
    guard.count = guard.count + imus  # a new array: each Result keeps its frame's counts
    guard.total += int(np.count_nonzero(imus))


def failed_inputs(acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray,
                  errors: np.ndarray | None) -> np.ndarray | None:
    """``errors`` (``[..., n, 3]`` accel/mag/gyro flags) with every non-finite input flagged
    too, so the filters hold the last good value instead of taking NaN into their state
    (counted in ``held_count``). ``errors`` itself when every input is finite."""
    bad = np.stack([~np.isfinite(v).all(axis=-1) for v in (acc, mag, gyr)], axis=-1)
    if not bad.any():
        return errors
    return bad if errors is None else (np.asarray(errors, dtype=np.bool_) | bad)


def guarded_process(bank: Any, guard: StateGuard, acc: np.ndarray, mag: np.ndarray,
                    gyr: np.ndarray, errors: np.ndarray | None = None, **bank_options: Any
                    ) -> tuple[BankOutput, np.ndarray]:
    """``bank.process`` of N frames (``[N, n, 3]`` inputs) with the state check: (outputs,
    ``reinitialised[N, n]`` bool). ``bank_options`` go to ``bank.process``, arrays among
    them per frame (``[N, ...]``). See the module docstring; a live frame is N = 1 (nothing
    to rewind)."""
    n_frames = len(acc)
    c4 = renorm_allowance(bank)
    if n_frames == 1:  # a live frame: nothing to rewind, no parts to join
        out = bank.process(acc, mag, gyr, errors, **bank_options)
        bad, any_bad = check_rotations(out.R, gyr, c4, guard.expected)
        if any_bad:  # as the loop below at k = 0
            _mark(out, np.array([0]), bad[0])
            guard.accept(out.R)
            _reinit(bank, guard, bad[0])
        return out, bad

    def frames(sl: slice) -> BankOutput:
        """``bank.process`` of the frames ``sl``, per-frame options (``mag_trust``) sliced."""
        return bank.process(acc[sl], mag[sl], gyr[sl], None if errors is None else errors[sl],
                            **{k: v[sl] if isinstance(v, np.ndarray) else v
                               for k, v in bank_options.items()})

    flags = np.zeros((n_frames, guard.n), dtype=np.bool_)
    parts: list[BankOutput] = []
    pos, chunk = 0, max(n_frames, 1)
    while pos < n_frames:
        end = min(n_frames, pos + chunk)
        snap = bank.snapshot() if end - pos > 1 else None
        out = frames(slice(pos, end))
        bad, any_bad = check_rotations(out.R, gyr[pos:end], c4, guard.expected)
        if not any_bad:  # (expected updated)
            parts.append(out)
            pos, chunk = end, chunk * 2
            continue
        k = int(np.argmax(bad.any(axis=1)))
        if k < end - pos - 1:  # rewind and filter up to the bad frame only
            bank.restore(snap)
            out = frames(slice(pos, pos + k + 1))
        imus = bad[k]
        _mark(out, np.array([k]), imus)
        guard.accept(out.R[:k + 1])
        flags[pos + k] = imus
        _reinit(bank, guard, imus)
        parts.append(out)
        pos, chunk = pos + k + 1, 1
    if not parts:
        return bank.process(acc, mag, gyr, errors, **bank_options), flags
    return _concat(parts), flags


__all__ = ["MAHONY_RENORM_K", "SO3_TOLERANCE", "StateGuard", "check_rotations", "failed_inputs",
           "guarded_process", "renorm_allowance", "so3_error"]
