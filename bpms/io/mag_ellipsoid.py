"""The magnetometer ellipsoid record, shared by the calibration file, the calibration tool and
the filter's calibration (it lives here, in the lowest layer, so that ``bpms.io`` need not
import ``bpms.filter``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAG_FULL_SCALE = 100.0  # calibrated magnetometer units at the end of each axis range


@dataclass(frozen=True)
class MagEllipsoid:
    """A magnetometer ellipsoid fit (hard and soft iron, as the Razor AHRS extended
    calibration): ``m = matrix @ (raw - center)`` lies on the sphere of radius 100 (calibrated
    units), in board axes before the sign vector. ``center`` ``[3]`` raw counts; ``matrix``
    ``[3, 3]`` calibrated units per count (symmetric)."""

    center: np.ndarray
    matrix: np.ndarray
