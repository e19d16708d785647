"""The modern calibration file: JSON with named fields per IMU, optional magnetometer
ellipsoids and provenance, written beside the legacy ``Calib.cfg`` (``Calib.cfg`` →
``Calib.json``). See docs/calibration.md for the layout.

The legacy file stays the reference for the 16 docs/units.md numbers; the modern one adds what the
legacy format cannot hold (ellipsoids, when and how each IMU was calibrated, quality figures).
Reading never raises for bad content: problems are reported and the IMU falls back.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from bpms.io.bounded import loads_json, read_config_bytes
from bpms.io.calib_file import (
    FIELDS,
    CalibrationTable,
    check_ellipsoid,
    check_record,
    load_factory_calibration,
)
from bpms.io.frames import N_IMUS
from bpms.io.mag_ellipsoid import MagEllipsoid
from bpms.io.problems import FileProblem, report

FORMAT = "bpms-calibration"
VERSION = 1


def modern_path(legacy: str | Path) -> Path:
    """Where the modern file lives for a legacy ``Calib.cfg`` path."""
    return Path(legacy).with_suffix(".json")


@dataclass
class ModernCalibration:
    """The contents of a modern file. ``provenance``: per IMU, what was calibrated when and
    how (free-form dict: ``{"accel": iso time, "method": ..., "quality": {...}}``)."""

    table: CalibrationTable
    ellipsoids: dict[int, MagEllipsoid] = field(default_factory=dict)
    provenance: dict[int, dict[str, Any]] = field(default_factory=dict)
    problems: list[FileProblem] = field(default_factory=list)


def _imu_record(table: CalibrationTable, imu: int, ell: MagEllipsoid | None,
                prov: dict[str, Any]) -> dict[str, Any]:
    v = table.values[imu]
    rec: dict[str, Any] = {
        "id": imu,
        "gravity_counts": float(v[0]),
        "accel": {"min": [float(x) for x in v[1:7:2]], "max": [float(x) for x in v[2:7:2]]},
        "mag": {"min": [float(x) for x in v[7:13:2]], "max": [float(x) for x in v[8:13:2]]},
        "gyro_avg": [float(x) for x in v[13:16]],
    }
    if ell is not None:
        rec["mag"]["ellipsoid"] = {"center": [float(x) for x in ell.center],
                                   "matrix": [[float(x) for x in row] for row in ell.matrix]}
    if prov:
        rec["provenance"] = prov
    return rec


def format_modern(cal: ModernCalibration) -> str:
    """The JSON text."""
    header = {
        "format": FORMAT, "version": VERSION,
        "written": datetime.now(UTC).isoformat(timespec="seconds"),
        "units": {"accel": "counts (gravity_counts per g)", "mag": "counts",
                  "gyro_avg": "counts", "ellipsoid.matrix": "calibrated units (full field 100) "
                  "per count, board axes before the sign vector"},
        "imus": [],
    }
    records = [json.dumps(_imu_record(cal.table, i, cal.ellipsoids.get(i),
                                      cal.provenance.get(i, {})), ensure_ascii=False)
               for i in range(N_IMUS)]
    text = json.dumps(header, indent=1, ensure_ascii=False)
    # one IMU per line: readable and diff-friendly
    return text.replace('"imus": []', '"imus": [\n  ' + ",\n  ".join(records) + "\n ]") + "\n"


def save_modern(cal: ModernCalibration, path: str | Path) -> None:
    """Write atomically (a temporary file renamed over the target)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(format_modern(cal), encoding="utf-8")
    tmp.replace(path)


def _vector(value: Any, n: int = 3) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (n,) or not np.isfinite(arr).all():
        raise ValueError(f"expected {n} finite numbers")
    return arr


def _parse_imu(rec: Any) -> tuple[int, np.ndarray, MagEllipsoid | str | None, dict]:
    """(IMU id, its 16 values, its ellipsoid, or why the ellipsoid is unusable, provenance);
    ValueError (and KeyError, TypeError) for a record whose 16 values are unusable."""
    if not isinstance(rec, dict):
        raise ValueError("an IMU record must be an object")
    imu = rec.get("id")
    if not isinstance(imu, int) or not 0 <= imu < N_IMUS:
        raise ValueError(f"bad IMU id {imu!r}")
    g = float(rec["gravity_counts"])
    if not math.isfinite(g) or g <= 0:
        raise ValueError("gravity_counts must be a positive number")
    amin, amax = _vector(rec["accel"]["min"]), _vector(rec["accel"]["max"])
    mmin, mmax = _vector(rec["mag"]["min"]), _vector(rec["mag"]["max"])
    row = np.concatenate([[g], np.stack([amin, amax], 1).ravel(),
                          np.stack([mmin, mmax], 1).ravel(), _vector(rec["gyro_avg"])])
    bad = check_record(row)  # the same door as Calib.cfg and recording headers
    if bad is not None:
        raise ValueError(bad[1] if bad[0] < 0 else f"{FIELDS[bad[0]]}: {bad[1]}")
    ell: MagEllipsoid | str | None = None
    if "ellipsoid" in rec["mag"]:
        try:
            e = rec["mag"]["ellipsoid"]
            center = np.asarray(e["center"], dtype=np.float64)
            matrix = np.asarray(e["matrix"], dtype=np.float64)
        except (KeyError, TypeError, ValueError) as exc:
            ell = f"the ellipsoid is malformed ({str(exc).strip(chr(39))})"
        else:
            why = check_ellipsoid(center, matrix, row)  # the one check (io/calib_file.py)
            ell = why if why is not None else MagEllipsoid(center=center, matrix=matrix)
    prov = rec.get("provenance", {})
    return imu, row, ell, prov if isinstance(prov, dict) else {}


def load_modern(path: str | Path) -> ModernCalibration:
    """Read a modern file. Unreadable or malformed: the factory table with a problem report;
    a bad IMU record: that IMU falls back to the factory record (its ellipsoid dropped)."""
    path = Path(path)
    problems: list[FileProblem] = []
    factory = load_factory_calibration()
    try:
        doc = loads_json(read_config_bytes(path).decode("utf-8"), "the file")
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise ValueError(f"not a {FORMAT} file")
        records = doc["imus"]
        if not isinstance(records, list):
            raise ValueError("'imus' must be a list")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        report(problems, path, "file", f"cannot be read ({exc})", "factory calibration used")
        factory.problems = problems
        return ModernCalibration(factory, problems=problems)
    values = factory.values.copy()
    seen: set[int] = set()
    out = ModernCalibration(CalibrationTable(values, source=str(path)), problems=problems)
    for k, rec in enumerate(records):
        try:
            imu, row, ell, prov = _parse_imu(rec)
        except (ValueError, KeyError, TypeError) as exc:
            bad_id = rec.get("id") if isinstance(rec, dict) else None
            if isinstance(bad_id, int):
                seen.add(bad_id)  # reported here, not again as missing
            report(problems, path, f"IMU record {k + 1} (id {bad_id})",
                   str(exc).strip("'\"") or "malformed", "factory values used for that IMU")
            continue
        values[imu] = row
        seen.add(imu)
        if isinstance(ell, str):
            report(problems, path, f"IMU {imu} ellipsoid", ell,
                   f"min/max magnetometer calibration used for IMU {imu}")
        elif ell is not None:
            out.ellipsoids[imu] = ell
        if prov:
            out.provenance[imu] = prov
    for imu in sorted(set(range(N_IMUS)) - seen):
        report(problems, path, f"IMU {imu}", "missing", "factory values used")
    out.table = CalibrationTable(values, source=str(path), problems=problems)
    return out


def ellipsoids_beside(legacy: str | Path, table: CalibrationTable
                      ) -> tuple[dict[int, MagEllipsoid], dict[int, dict[str, Any]],
                                 list[FileProblem]]:
    """Ellipsoids and provenance of the modern companion of a legacy file, for the IMUs whose
    16 numbers agree with ``table`` (the legacy file as read): a companion left stale by another
    tool contributes nothing for the IMUs it disagrees on. No companion: empty dicts."""
    modern = modern_path(legacy)
    if not modern.exists():
        return {}, {}, []
    other = load_modern(modern)
    same = {i for i in range(N_IMUS)
            if (np.abs(other.table.values[i] - table.values[i]) < 1e-6).all()}
    return ({i: e for i, e in other.ellipsoids.items() if i in same},
            {i: p for i, p in other.provenance.items() if i in same}, other.problems)
