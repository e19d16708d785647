"""The state arrays of a bank of numba filter kernels, declared by one table per filter."""

from __future__ import annotations

import numpy as np

from bpms.io.frames import N_IMUS


class KernelState:
    """The state of ``n`` IMUs, updated in place by a module's kernels (or a bank's code).

    Each row ``(name, shape per IMU, dtype, initial value)`` of :attr:`LAYOUT` is one attribute,
    an array ``[n, *shape]`` filled with the initial value (a scalar, or an array broadcast
    to each IMU, e.g. ``np.eye(3)``); :meth:`arrays` gives them in the table's order, the
    kernels' argument order.
    """

    LAYOUT: tuple[tuple[str, tuple[int, ...], type, object], ...] = ()

    def __init__(self, n: int = N_IMUS) -> None:
        self.n = n
        for name, shape, dtype, initial in self.LAYOUT:
            setattr(self, name, np.full((n, *shape), initial, dtype=dtype))
        self._arrays = tuple(getattr(self, name) for name, *_ in self.LAYOUT)

    def __getattr__(self, name: str) -> np.ndarray:
        # only called for a name not set: the LAYOUT's attributes are set in __init__; this
        # tells the type checker that they are arrays
        raise AttributeError(f"{type(self).__name__} has no state array '{name}'")

    def arrays(self) -> tuple[np.ndarray, ...]:
        """The state arrays in kernel argument order (the same objects for the state's life:
        they are updated in place, never replaced)."""
        return self._arrays


__all__ = ["KernelState"]
