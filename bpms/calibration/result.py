"""From finished procedures to a calibration table: merging, the old-vs-new summary and the
quality figures.

Merging is per value: only what was measured changes (one IMU, one sensor, even one accel pose);
everything else keeps the existing file's value, so replacing one IMU recalibrates only that
IMU. Gravity of an IMU is recomputed (docs/units.md) whenever its accelerometer values change.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bpms.calibration.ellipsoid import min_max_ellipsoid, sphere_residual
from bpms.calibration.procedures import AccelProcedure, GyroProcedure, MagProcedure
from bpms.filter.calibration import MAG_FULL_SCALE, MagEllipsoid
from bpms.io.calib_file import FIELDS, CalibrationTable


@dataclass
class Quality:
    """Quality figures of a new calibration, per IMU.

    gravity_spread_pct: (max - min) of the calibrated gravity magnitude over the captured
    accel poses, % of Gravity; mag_residual: rms of ``|m| - 100`` over the sweep with the
    min/max calibration, and with the ellipsoid (calibrated units, sphere radius 100; 1 unit
    = 1 %); mag_coverage: fraction of the sphere seen; gyro_std: noise of the still capture
    (not kept: see the procedure).
    """

    gravity_spread_pct: dict[int, float] = field(default_factory=dict)
    mag_residual: dict[int, float] = field(default_factory=dict)
    mag_residual_ellipsoid: dict[int, float] = field(default_factory=dict)
    mag_coverage: dict[int, float] = field(default_factory=dict)

    def lines(self) -> list[str]:
        out = []
        for imu, v in sorted(self.gravity_spread_pct.items()):
            out.append(f"IMU {imu}: gravity magnitude spread {v:.2f} % over the captured poses")
        for imu, v in sorted(self.mag_residual.items()):
            ell = self.mag_residual_ellipsoid.get(imu)
            extra = f", ellipsoid fit {ell:.2f} %" if ell is not None else ""
            cov = self.mag_coverage.get(imu)
            cov_text = f", sphere coverage {100 * cov:.0f} %" if cov is not None else ""
            out.append(f"IMU {imu}: magnetometer sphere residual {v:.2f} % (min/max){extra}"
                       f"{cov_text}")
        return out


@dataclass
class CalibrationUpdate:
    """Measured values to merge: accel (min, max) per IMU ``[3, 2]`` (NaN = not captured),
    magnetometer (min, max) ``[3, 2]``, gyro averages ``[3]``, ellipsoid fits."""

    accel: dict[int, np.ndarray] = field(default_factory=dict)
    mag: dict[int, np.ndarray] = field(default_factory=dict)
    gyro: dict[int, np.ndarray] = field(default_factory=dict)
    ellipsoids: dict[int, MagEllipsoid] = field(default_factory=dict)
    quality: Quality = field(default_factory=Quality)

    @property
    def imus(self) -> list[int]:
        return sorted({*self.accel, *self.mag, *self.gyro})

    def merge(self, old: CalibrationTable, source: str = "calibration tool") -> CalibrationTable:
        """``old`` with the measured values replaced (per value)."""
        table = old.copy()
        table.source = source
        table.problems = []
        v = table.values
        for imu, ext in self.accel.items():
            acc = v[imu, 1:7].reshape(3, 2)
            acc[~np.isnan(ext)] = ext[~np.isnan(ext)]
            v[imu, 1:7] = acc.ravel()
            v[imu, 0] = float(np.mean((acc[:, 1] - acc[:, 0]) / 2))  # eq. 2.4
        for imu, ext in self.mag.items():
            v[imu, 7:13] = ext.ravel()
        for imu, avg in self.gyro.items():
            v[imu, 13:16] = avg
        return table

    def merged_ellipsoids(self, old: dict[int, MagEllipsoid]) -> dict[int, MagEllipsoid]:
        """Existing ellipsoids, minus those of re-swept IMUs, plus the new fits."""
        out = {i: e for i, e in old.items() if i not in self.mag}
        out.update(self.ellipsoids)
        return out


def collect(gyro: GyroProcedure | None = None, accel: AccelProcedure | None = None,
            mag: MagProcedure | None = None, old: CalibrationTable | None = None
            ) -> CalibrationUpdate:
    """Gather the results of finished procedures (unfinished ones contribute nothing) and
    compute the quality figures against the merged values."""
    update = CalibrationUpdate()
    if gyro is not None:
        update.gyro = gyro.averages
    if accel is not None:
        update.accel = accel.extremes()
    if mag is not None and mag.state == "done":
        update.mag = mag.extremes()
        update.ellipsoids = {i: f.ellipsoid for i, f in mag.fits.items()
                             if f is not None and i in update.mag}
    merged = update.merge(old) if old is not None else None
    if accel is not None and merged is not None:
        for imu in {c.imu for c in accel.captures.values()}:
            acc = merged.values[imu, 1:7].reshape(3, 2)
            off = acc.mean(axis=1)
            scale = merged.values[imu, 0] / (acc[:, 1] - off)
            mags = [np.linalg.norm((c.mean - off) * scale) for c in accel.captures.values()
                    if c.imu == imu]
            if len(mags) >= 2:
                update.quality.gravity_spread_pct[imu] = float(
                    100 * (max(mags) - min(mags)) / merged.values[imu, 0])
    if mag is not None and mag.state == "done":
        data = mag.samples()
        cover = mag.coverage()
        for j, imu in enumerate(mag.imus):
            if imu not in update.mag:
                continue
            pts = data[:, j]
            pts = pts[~np.isnan(pts).any(axis=1)]
            update.quality.mag_residual[imu] = sphere_residual(
                pts, min_max_ellipsoid(update.mag[imu])) * 100 / MAG_FULL_SCALE
            if imu in update.ellipsoids:
                update.quality.mag_residual_ellipsoid[imu] = sphere_residual(
                    pts, update.ellipsoids[imu]) * 100 / MAG_FULL_SCALE
            update.quality.mag_coverage[imu] = cover[imu]
    return update


@dataclass(frozen=True)
class SummaryRow:
    imu: int
    field: str
    old: float
    new: float

    @property
    def change(self) -> float:
        return self.new - self.old


def summary(old: CalibrationTable, new: CalibrationTable, imus: list[int] | None = None,
            changed_only: bool = True) -> list[SummaryRow]:
    """Old vs new per value (counts; Gravity in counts per g) for ``imus`` (default: all)."""
    rows = []
    for imu in imus if imus is not None else range(len(old.values)):
        for k, name in enumerate(FIELDS):
            a, b = float(old.values[imu, k]), float(new.values[imu, k])
            if changed_only and a == b:
                continue
            rows.append(SummaryRow(imu, name, a, b))
    return rows


def format_summary(rows: list[SummaryRow]) -> str:
    """The summary as a text table (counts)."""
    if not rows:
        return "no value changed"
    lines = [f"{'IMU':>3}  {'value':<8} {'old':>10} {'new':>10} {'change':>9}  (counts)"]
    lines += [f"{r.imu:>3}  {r.field:<8} {r.old:>10.2f} {r.new:>10.2f} {r.change:>+9.2f}"
              for r in rows]
    return "\n".join(lines)
