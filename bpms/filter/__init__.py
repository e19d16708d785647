"""Attitude filtering and the body model: calibration, 18 DCM Mahony filters, Reset Zero,
joint angles, stick figure, and the headless processor (see docs/filter.md).

The public entry points (imported lazily, so ``bpms.filter.calibration`` & co. do not pull
in numba)::

    from bpms.filter import BodyPoseProcessor, MahonyBank, PoseCalibrator, Result
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "BankOutput": "bpms.filter.bank",
    "MahonyBank": "bpms.filter.bank",
    "PoseCalibrator": "bpms.filter.pose",
    "Zero": "bpms.filter.pose",
    "average_dcm": "bpms.filter.pose",
    "capture_zero": "bpms.filter.pose",
    "BodyPoseProcessor": "bpms.filter.processor",
    "Result": "bpms.filter.processor",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'bpms.filter' has no attribute {name!r}")
