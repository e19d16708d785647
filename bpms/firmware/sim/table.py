"""The simulated suit's own copy of the suit's true calibration table, read apart from the product.

The simulated suit makes its raw counts from the *meaning* of the calibration table (the
readings at ∓1 g, ∓ the Earth's field and the gyro's zero rate, :func:`.sensors.to_raw`), so
it needs the table's numbers, but it reads them itself: from the dissertation's Table 2.2 as
``calib/calibration-table-2.2.csv`` (one row per IMU: ``id, name`` and the 16 fields), never
through the product's calibration-file parser. A wrong parser or a wrong formula in the
product then disagrees with the simulated suit instead of being copied by it.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bpms.io.frames import N_IMUS

#: The 16 numbers per IMU, in the table's column order (docs/units.md).
TABLE_FIELDS: tuple[str, ...] = (
    "Gravity", "AxMin", "AxMax", "AyMin", "AyMax", "AzMin", "AzMax",
    "MxMin", "MxMax", "MyMin", "MyMax", "MzMin", "MzMax", "GxAvg", "GyAvg", "GzAvg",
)
TABLE_FILE = "calibration-table-2.2.csv"


def table_path() -> Path:
    """``calib/calibration-table-2.2.csv``: at the top of a checkout or inside the package."""
    here = Path(__file__).resolve()
    for root in (here.parents[3], here.parents[2]):  # checkout top, installed package
        candidate = root / "calib" / TABLE_FILE
        if candidate.is_file():
            return candidate
    raise FileNotFoundError(f"{TABLE_FILE} is missing from this installation")


@dataclass
class TrueTable:
    """A true calibration table ``values [18, 16]`` (float64, columns :data:`TABLE_FIELDS`),
    with the few read-only views the simulated suit and its tests use."""

    values: np.ndarray
    source: str = "simulated truth"
    problems: list = field(default_factory=list)

    def __post_init__(self) -> None:
        self.values = np.array(self.values, dtype=np.float64)
        if self.values.shape != (N_IMUS, len(TABLE_FIELDS)):
            raise ValueError(f"a true table is [{N_IMUS}, {len(TABLE_FIELDS)}]")

    @property
    def gravity(self) -> np.ndarray:
        return self.values[:, 0]

    @property
    def accel_min_max(self) -> np.ndarray:
        return self.values[:, 1:7].reshape(N_IMUS, 3, 2)

    @property
    def mag_min_max(self) -> np.ndarray:
        return self.values[:, 7:13].reshape(N_IMUS, 3, 2)

    @property
    def gyro_avg(self) -> np.ndarray:
        return self.values[:, 13:16]

    def column(self, name: str) -> np.ndarray:
        return self.values[:, TABLE_FIELDS.index(name)]

    def copy(self) -> TrueTable:
        return TrueTable(self.values.copy(), self.source, list(self.problems))


_TABLE_2_2: np.ndarray | None = None


def table_2_2() -> TrueTable:
    """The prototype's table (dissertation Table 2.2), read from its CSV copy (a fresh copy
    each call: callers may change it)."""
    global _TABLE_2_2
    if _TABLE_2_2 is None:
        with table_path().open(newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
        rows.sort(key=lambda r: int(r["id"]))
        if [int(r["id"]) for r in rows] != list(range(N_IMUS)):
            raise ValueError(f"{TABLE_FILE}: expected IMU ids 0..{N_IMUS - 1}")
        _TABLE_2_2 = np.array([[float(r[f]) for f in TABLE_FIELDS] for r in rows])
    return TrueTable(_TABLE_2_2.copy(), "factory (dissertation Table 2.2, simulated truth)")
