"""Reading the existing calibration and saving the new one: legacy ``Calib.cfg`` + modern
``Calib.json`` beside it (:mod:`bpms.io.calib_modern`)."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

from bpms.calibration.result import CalibrationUpdate
from bpms.filter.calibration import MagEllipsoid
from bpms.io.calib_file import CalibrationTable, load_calibration, save_legacy
from bpms.io.calib_modern import (
    ModernCalibration,
    ellipsoids_beside,
    modern_path,
    save_modern,
)


def load_existing(path: str | Path | None) -> ModernCalibration:
    """The calibration to merge into: the legacy file at ``path`` (factory when missing or
    None), with the ellipsoids and provenance of its modern companion when that exists and
    agrees with it (a stale companion — different numbers — contributes nothing)."""
    if path is None or not Path(path).exists():
        return ModernCalibration(load_calibration(None))
    table = load_calibration(path)
    ellipsoids, provenance, problems = ellipsoids_beside(path, table)
    return ModernCalibration(table, ellipsoids, provenance, [*table.problems, *problems])


def save_pair(existing: ModernCalibration, update: CalibrationUpdate, path: str | Path,
              sensors: list[str], method: str = "bpms calibrate") -> tuple[Path, Path]:
    """Merge ``update`` into ``existing`` and write ``path`` (legacy) and its modern
    companion. Returns both paths."""
    path = Path(path)
    table: CalibrationTable = update.merge(existing.table, source=str(path))
    ellipsoids: dict[int, MagEllipsoid] = update.merged_ellipsoids(existing.ellipsoids)
    provenance = {i: dict(p) for i, p in existing.provenance.items()}
    now = datetime.now(UTC).isoformat(timespec="seconds")
    q = update.quality
    for imu in update.imus:
        prov = provenance.setdefault(imu, {})
        prov["method"] = method
        for sensor, values in (("accel", update.accel), ("mag", update.mag),
                               ("gyro", update.gyro)):
            if imu in values and sensor in sensors:
                prov[sensor] = now
        quality = {k: round(float(v[imu]), 4) for k, v in (
            ("gravity_spread_pct", q.gravity_spread_pct), ("mag_residual_pct", q.mag_residual),
            ("mag_residual_ellipsoid_pct", q.mag_residual_ellipsoid),
            ("mag_coverage", q.mag_coverage)) if imu in v}
        if quality:
            prov["quality"] = quality
    path.parent.mkdir(parents=True, exist_ok=True)
    save_legacy(table, path)
    modern = modern_path(path)
    save_modern(ModernCalibration(table, ellipsoids, provenance), modern)
    return path, modern
