"""What the data table's columns hold and what table, plots and drags call them: the column
layout (:data:`COLUMNS`), the values of a column for blocks of samples, the calibrated
units, the angles shown (output or sensor) and readable joint-angle names. No Qt: the table
(:mod:`bpms.gui.data_table`) and the plots (:mod:`bpms.gui.plots`) both build on it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bpms.filter.calibration import SensorCalibration
from bpms.io.frames import CHANNEL_NAMES
from bpms.pipeline.session import PoseSample


@dataclass(frozen=True)
class Column:
    """One table column: ``group`` raw/cal/euler/errors/disturbance, ``k`` the index inside
    the group."""

    group: str
    k: int
    name: str
    unit: str

    def label(self, angle_unit: str = "deg") -> str:
        unit = angle_unit if self.group == "euler" else self.unit
        return f"{self.name} [{unit}]" if unit else self.name


_CAL_UNITS = ("m/s²", "m/s²", "m/s²", "G", "G", "G", "rad/s", "rad/s", "rad/s")
#: Readable channel names (accelerometer, magnetometer, gyroscope; board axes).
CHANNEL_LABELS = ("acc x", "acc y", "acc z", "mag x", "mag y", "mag z", "gyro x", "gyro y",
                  "gyro z")
#: What matters first: the attitude angles, the error flags, then calibrated, then raw.
COLUMNS: tuple[Column, ...] = (
    *(Column("euler", k, c, "rad") for k, c in enumerate(("roll", "pitch", "yaw"))),
    Column("errors", 0, "errors", ""),
    *(Column("cal", k, c, _CAL_UNITS[k]) for k, c in enumerate(CHANNEL_LABELS)),
    *(Column("raw", k, f"raw {c}", "counts") for k, c in enumerate(CHANNEL_LABELS)),
    # last in the model (cell indices of the others stay put), shown after "errors"
    Column("disturbance", 0, "disturbance", ""),
    # the filter's estimates (observer, adaptive and vqf; Mahony: bias only), after raw
    *(Column("est", k, name, unit) for k, (name, unit) in enumerate(
        [(f"gyro bias {a}", "rad/s") for a in "xyz"]
        + [(f"body acc {a}", "m/s²") for a in ("north", "east", "down")])),
)
#: Columns of text (not plottable).
TEXT_GROUPS = frozenset({"errors", "disturbance"})
assert len(CHANNEL_NAMES) == len(CHANNEL_LABELS)


def calibrated(calibration: SensorCalibration, raw: np.ndarray) -> np.ndarray:
    """Raw ``[..., 18, 9]`` counts → ``[..., 18, 9]`` accel m/s², mag gauss, gyro rad/s."""
    acc, mag, gyr = calibration.physical_units(raw)
    return np.concatenate([acc, mag, gyr], axis=-1)


def column_values(column: Column, raw: np.ndarray, cal: np.ndarray, euler: np.ndarray,
                  degrees: bool, est: np.ndarray | None = None) -> np.ndarray:
    """Values of ``column`` for blocks ``raw/cal [..., 18, 9]``, ``euler [..., 18, 3]`` rad,
    ``est [..., 18, 6]`` (gyro bias rad/s, body acceleration m/s²) → ``[..., 18]`` in the
    column's unit."""
    if column.group == "est":
        if est is None:
            return np.full(raw.shape[:-1], np.nan)
        return est[..., column.k]
    if column.group == "raw":
        return raw[..., column.k].astype(np.float64)
    if column.group == "cal":
        return cal[..., column.k]
    if column.group == "euler":
        values = euler[..., column.k]
        return np.degrees(values) if degrees else values
    raise ValueError(f"column {column.name} has no numeric value")


def shown_angles(sample: PoseSample, output: bool = True) -> tuple[np.ndarray, str]:
    """The ``[18, 3]`` angles (rad) to show and what they are: ``output`` True → the sample's
    output angles, "segment" when they differ from the sensor angles (corrected by Reset Zero),
    else "sensor"; ``output`` False → the sensor angles."""
    out = sample.euler_output
    if not output or out is None:
        return sample.euler, "sensor"
    same = np.array_equal(out, sample.euler, equal_nan=True)
    return out, "sensor" if same else "segment"


def human_joint_name(name: str) -> str:
    """``hip_r.abduction`` → "Right hip abduction"; ``torso.flexion`` → "Torso flexion"."""
    segment, _, angle = name.partition(".")
    side = ""
    if segment.endswith("_r"):
        side, segment = "Right ", segment[:-2]
    elif segment.endswith("_l"):
        side, segment = "Left ", segment[:-2]
    words = f"{segment.replace('_', ' ')} {angle.replace('_', ' ')}".strip()
    return (side + words) if side else words[:1].upper() + words[1:]
