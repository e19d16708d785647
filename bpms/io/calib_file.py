"""Sensor calibration values and the legacy ``Calib.cfg`` file (docs/units.md).

Per IMU, 16 numbers in this order: ``Gravity, AxMin, AxMax, AyMin, AyMax, AzMin, AzMax,
MxMin, MxMax, MyMin, MyMax, MzMin, MzMax, GxAvg, GyAvg, GzAvg`` (raw counts, except Gravity,
which is in accelerometer counts per 1 g). The legacy file holds the 18 records in IMU id
order separated by ``;`` and the 16 values of a record separated by ``,``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bpms.io.bounded import BoundError, read_config_bytes
from bpms.io.frames import N_IMUS
from bpms.io.mag_ellipsoid import MAG_FULL_SCALE
from bpms.io.paths import factory_calibration_path
from bpms.io.problems import FileProblem, report

FIELDS: tuple[str, ...] = (
    "Gravity", "AxMin", "AxMax", "AyMin", "AyMax", "AzMin", "AzMax",
    "MxMin", "MxMax", "MyMin", "MyMax", "MzMin", "MzMax", "GxAvg", "GyAvg", "GzAvg",
)
N_FIELDS = len(FIELDS)

#: Physical ranges of one IMU record, from the sensors' data sheets (docs/configuration.md,
#: "Calibration ranges"). A value outside cannot come from a working sensor stick: the IMU
#: gets its factory record, with a warning, as for NaN.
#: ADXL345 sensitivity in full resolution, 230–282 counts per g at every range (data sheet),
#: widened by 10 % for the measurement (tilt, noise, temperature): Gravity and every
#: accelerometer half-range (max − min) / 2, which is that axis' 1 g.
GRAVITY_RANGE = (207.0, 310.0)
#: ADXL345 0 g offset: at most ±250 mg (z; x and y ±150 mg) × 310 counts per g, counts.
ACCEL_OFFSET_MAX = 80.0
#: ADXL345 in full resolution at ±16 g: 13-bit readings, −4096 … 4095 counts.
ACCEL_COUNTS = (-4096.0, 4095.0)
#: HMC5883L 12-bit readings, −2048 … 2047 counts (−4096 marks an overflow).
MAG_COUNTS = (-2048.0, 2047.0)
#: Smallest magnetometer half-range, counts: the weakest Earth field (0.22 G) at the
#: HMC5883L's least sensitive gain (230 counts per G) reads 50 counts.
MAG_HALF_RANGE_MIN = 50.0
#: ITG-3200 zero-rate output: at most ±40 °/s × 14.375 counts per °/s = ±575 counts.
GYRO_BIAS_MAX = 575.0


@dataclass
class CalibrationTable:
    """Calibration values ``[18, 16]`` (float64), columns as :data:`FIELDS`."""

    values: np.ndarray
    source: str = "factory"
    problems: list[FileProblem] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.values = np.array(self.values, dtype=np.float64)
        if self.values.shape != (N_IMUS, N_FIELDS):
            raise ValueError(f"calibration values must be [{N_IMUS}, {N_FIELDS}]")

    def column(self, name: str) -> np.ndarray:
        """One named column for all 18 IMUs."""
        return self.values[:, FIELDS.index(name)]

    @property
    def gravity(self) -> np.ndarray:
        """Accelerometer counts per 1 g, ``[18]``."""
        return self.values[:, 0]

    @property
    def accel_min_max(self) -> np.ndarray:
        """``[18, 3, 2]`` accelerometer (min, max) per axis, counts."""
        return self.values[:, 1:7].reshape(N_IMUS, 3, 2)

    @property
    def mag_min_max(self) -> np.ndarray:
        """``[18, 3, 2]`` magnetometer (min, max) per axis, counts."""
        return self.values[:, 7:13].reshape(N_IMUS, 3, 2)

    @property
    def gyro_avg(self) -> np.ndarray:
        """``[18, 3]`` gyroscope zero-rate averages, counts."""
        return self.values[:, 13:16]

    def copy(self) -> CalibrationTable:
        return CalibrationTable(self.values.copy(), self.source, list(self.problems))

    def replace_imus(self, other: CalibrationTable, imu_ids: list[int]) -> CalibrationTable:
        """A copy where the records of ``imu_ids`` come from ``other`` (one IMU replaced)."""
        merged = self.copy()
        merged.values[imu_ids] = other.values[imu_ids]
        return merged


def _record_problem(values: list[str]) -> tuple[int, str] | None:
    """(field index, message) of the first bad value of a record, or None."""
    if len(values) != N_FIELDS:
        return -1, f"has {len(values)} values, expected {N_FIELDS}"
    for k, text in enumerate(values):
        try:
            number = float(text)
        except ValueError:
            return k, f"'{text.strip()[:20]}' is not a number"
        if not math.isfinite(number):
            return k, f"'{text.strip()}' is not a finite number"
    return check_record(np.array([float(v) for v in values]))


def as_table(table: object) -> CalibrationTable:
    """A ``CalibrationTable`` of ``table``: itself when it is one, else a new table of its
    ``values [18, 16]`` (and ``source`` when it has one), e.g. the simulated suit's own copy of
    its true table. Raises ValueError when it has no such values."""
    if isinstance(table, CalibrationTable):
        return table
    values = getattr(table, "values", None)
    if values is None:
        raise ValueError(f"not a calibration table: {type(table).__name__}")
    return CalibrationTable(np.asarray(values, dtype=np.float64),
                            str(getattr(table, "source", "given")))


def check_record(row: np.ndarray) -> tuple[int, str] | None:
    """(field index, message) of the first unusable value of one IMU record, or None. The
    index is -1 for a min/max pair (the message names both fields).

    The one check every calibration door uses (``Calib.cfg``, JSON, a recording's header,
    whatever reaches the filter): every value finite and inside the physical ranges above
    (Gravity, each accelerometer axis' half-range and offset, magnetometer readings and
    half-range, gyro zero-rate average), every max above its min."""
    row = np.asarray(row, dtype=np.float64)
    for k, value in enumerate(row):
        if not math.isfinite(value):
            return k, f"{float(value)!r} is not a finite number"
    lo_g, hi_g = GRAVITY_RANGE
    if not lo_g <= row[0] <= hi_g:
        return 0, (f"Gravity {row[0]:g} is outside {lo_g:g} … {hi_g:g} counts per g (the "
                   "ADXL345's sensitivity)")
    for axis, (lo, hi) in enumerate(row[1:13].reshape(6, 2)):
        k = 1 + 2 * axis
        lo_name, hi_name = FIELDS[k], FIELDS[k + 1]
        counts = ACCEL_COUNTS if axis < 3 else MAG_COUNTS
        for j, value in ((k, lo), (k + 1, hi)):
            if not counts[0] <= value <= counts[1]:
                return j, (f"{FIELDS[j]} {value:g} is outside the sensor's readings "
                           f"{counts[0]:g} … {counts[1]:g} counts")
        if hi <= lo:  # (the message names both fields: no single field index)
            return -1, f"{lo_name} ≥ {hi_name} (min must be below max: {lo:g} ≥ {hi:g})"
        half, offset = (hi - lo) / 2, (hi + lo) / 2
        if axis < 3 and not lo_g <= half <= hi_g:
            return -1, (f"{lo_name} {lo:g} … {hi_name} {hi:g}: half-range {half:g} counts is "
                        f"not 1 g ({lo_g:g} … {hi_g:g} counts, the ADXL345's sensitivity)")
        if axis < 3 and abs(offset) > ACCEL_OFFSET_MAX:
            return -1, (f"{lo_name} {lo:g} … {hi_name} {hi:g}: offset {offset:g} counts is "
                        f"beyond the ADXL345's ±{ACCEL_OFFSET_MAX:g}")
        if axis >= 3 and half < MAG_HALF_RANGE_MIN:
            return -1, (f"{lo_name} {lo:g} … {hi_name} {hi:g}: half-range {half:g} counts is "
                        f"below the weakest Earth field ({MAG_HALF_RANGE_MIN:g} counts)")
    for k in range(13, 16):
        if abs(row[k]) > GYRO_BIAS_MAX:
            return k, (f"{FIELDS[k]} {row[k]:g} is beyond the ITG-3200's zero-rate output "
                       f"±{GYRO_BIAS_MAX:g} counts (±40 °/s)")
    return None


def check_ellipsoid(center: np.ndarray, matrix: np.ndarray, row: np.ndarray | None = None
                    ) -> str | None:
    """Why a magnetometer ellipsoid (``m = matrix @ (raw - center)`` on the sphere of radius
    100, :class:`bpms.io.mag_ellipsoid.MagEllipsoid`) cannot come from this sensor, or None:
    every number finite; the centre (raw counts) inside the HMC5883L's readings and, given
    the IMU's record ``row``, inside its magnetometer min … max on each axis (the sweep that
    measured both went round it); the matrix not singular, its radii (100 / each singular
    value, counts) between the weakest Earth field's :data:`MAG_HALF_RANGE_MIN` and the
    readings' span. The same check for every door that
    reads an ellipsoid (issue 43: a centre of 1e300 turned an IMU to NaN without a warning,
    one of 5,000 counts moved its yaw by 1 rad)."""
    center = np.asarray(center, dtype=np.float64)
    matrix = np.asarray(matrix, dtype=np.float64)
    if center.shape != (3,) or matrix.shape != (3, 3):
        return "the ellipsoid needs a centre of 3 numbers and a 3×3 matrix"
    if not (np.isfinite(center).all() and np.isfinite(matrix).all()):
        return "the ellipsoid holds a number that is not finite"
    lo, hi = MAG_COUNTS
    for axis, c in enumerate(center):
        if not lo <= c <= hi:
            return (f"ellipsoid centre {'xyz'[axis]} {c:g} is outside the sensor's readings "
                    f"{lo:g} … {hi:g} counts")
        if row is not None and not row[7 + 2 * axis] <= c <= row[8 + 2 * axis]:
            return (f"ellipsoid centre {'xyz'[axis]} {c:g} is outside the IMU's magnetometer "
                    f"{FIELDS[7 + 2 * axis]} … {FIELDS[8 + 2 * axis]} "
                    f"({row[7 + 2 * axis]:g} … {row[8 + 2 * axis]:g} counts)")
    gains = np.linalg.svd(matrix, compute_uv=False)  # calibrated units per count, per axis
    if gains.min() <= 1e-12 * max(float(gains.max()), 1e-300):
        return "the ellipsoid matrix is singular"
    radii = MAG_FULL_SCALE / gains
    if radii.min() < MAG_HALF_RANGE_MIN or radii.max() > hi - lo:
        return (f"ellipsoid radii {radii.min():.4g} … {radii.max():.4g} counts are outside "
                f"{MAG_HALF_RANGE_MIN:g} … {hi - lo:g} (the weakest Earth field … the "
                "sensor's span)")
    return None


def checked(table: CalibrationTable, where: str | Path | None = None) -> CalibrationTable:
    """``table`` itself when every record passes :func:`check_record`; otherwise a copy in
    which each bad record is that IMU's factory record, with one problem (naming the IMU
    and the field) per record, logged as a warning."""
    bad = [(imu, found) for imu in range(N_IMUS)
           if (found := check_record(table.values[imu])) is not None]
    if not bad:
        return table
    factory = load_factory_calibration()
    out = table.copy()
    for imu, (k, message) in bad:
        out.values[imu] = factory.values[imu]
        field_name = f" field {k + 1} ({FIELDS[k]})" if k >= 0 else ""
        report(out.problems, where or table.source, f"IMU {imu}{field_name}",
               message, f"factory values used for IMU {imu}")  # report() logs it
    return out


def parse_legacy(text: str, path: str | Path = "<text>") -> CalibrationTable:
    """Parse ``Calib.cfg`` text. Bad records fall back to the factory record, with a problem
    report naming the IMU, the field and the line; a wrong record count falls back entirely."""
    problems: list[FileProblem] = []
    factory = load_factory_calibration()
    chunks = text.split(";")
    # Line on which each record starts, for the messages.
    starts, offset = [], 0
    for chunk in chunks:
        lead = len(chunk) - len(chunk.lstrip())
        starts.append(text.count("\n", 0, offset + lead) + 1)
        offset += len(chunk) + 1
    records = [(c, s) for c, s in zip(chunks, starts, strict=True) if c.strip()]
    if len(records) != N_IMUS:
        report(problems, path, "whole file",
               f"holds {len(records)} IMU records, expected {N_IMUS}",
               "factory calibration used for every IMU")
        return CalibrationTable(factory.values, source=f"factory (bad {path})", problems=problems)
    values = factory.values.copy()
    for imu, (chunk, line) in enumerate(records):
        fields = chunk.split(",")
        bad = _record_problem(fields)
        if bad is None:
            values[imu] = np.array([float(v) for v in fields])
            continue
        k, message = bad
        where = f"IMU {imu} (line {line})" + (f" field {k + 1} ({FIELDS[k]})" if k >= 0 else "")
        report(problems, path, where, message, f"factory values used for IMU {imu}")
    return CalibrationTable(values, source=str(path), problems=problems)


def load_calibration(path: str | Path | None) -> CalibrationTable:
    """Load a calibration file; a missing or unreadable file gives the factory table and a
    problem report. ``None`` means the factory table."""
    if path is None:
        return load_factory_calibration()
    path = Path(path)
    try:
        text = read_config_bytes(path).decode("utf-8", errors="replace")
    except (BoundError, OSError) as exc:
        big = isinstance(exc, BoundError)
        table = load_factory_calibration().copy()
        report(table.problems, path, "file", str(exc) if big else
               f"cannot be read ({getattr(exc, 'strerror', None) or exc})",
               "factory calibration used")
        table.source = f"factory ({path} {'too big' if big else 'unreadable'})"
        return table
    return parse_legacy(text, path)


_FACTORY: CalibrationTable | None = None


def load_factory_calibration() -> CalibrationTable:
    """The shipped prototype calibration (dissertation Table 2.2)."""
    global _FACTORY
    if _FACTORY is None:
        text = factory_calibration_path().read_text(encoding="utf-8")
        rows = [[float(v) for v in rec.split(",")] for rec in text.split(";") if rec.strip()]
        _FACTORY = CalibrationTable(np.array(rows), source="factory")
    return _FACTORY.copy()


def format_legacy(table: CalibrationTable) -> str:
    """Legacy ``Calib.cfg`` text: one record per line, ``;`` between records."""
    lines = [",".join(repr(float(v)) for v in row) for row in table.values]
    return ";\n".join(lines) + "\n"


def save_legacy(table: CalibrationTable, path: str | Path) -> None:
    """Write ``Calib.cfg`` atomically (a temporary file renamed over the target)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(format_legacy(table), encoding="utf-8")
    tmp.replace(path)
