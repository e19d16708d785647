"""Magnetometer ellipsoid fit (hard and soft iron), the approach of the Razor AHRS extended
magnetometer calibration: fit a general quadric to the raw readings, take its centre (hard-iron
offset) and the symmetric matrix that maps the ellipsoid onto a sphere (soft iron).

Model: ``(x - c)ᵀ Q (x - c) = 1`` for raw points x (counts); ``A = 100 · Q^½`` (symmetric) then
maps every point onto the sphere of radius 100 (calibrated units): ``|A (x - c)| = 100``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bpms.filter.calibration import MAG_FULL_SCALE, MagEllipsoid


@dataclass(frozen=True)
class EllipsoidFit:
    """A fit: the ellipsoid (centre counts, matrix units/count), the rms radial residual of
    the corrected points (calibrated units, sphere radius 100) and the point count."""

    ellipsoid: MagEllipsoid
    residual: float
    points: int


def fit_ellipsoid(points: np.ndarray, min_points: int = 50) -> EllipsoidFit | None:
    """Least-squares ellipsoid through ``points [n, 3]`` (raw counts); None when there are too
    few points or the quadric is not an ellipsoid (the sweep did not cover enough)."""
    x = np.asarray(points, dtype=np.float64)
    if len(x) < min_points:
        return None
    mu = x.mean(axis=0)
    s = max(float(np.abs(x - mu).max()), 1.0)
    p = (x - mu) / s  # conditioning
    X, Y, Z = p.T
    # a x² + b y² + c z² + 2f yz + 2g xz + 2h xy + 2u x + 2v y + 2w z = 1
    D = np.stack([X * X, Y * Y, Z * Z, 2 * Y * Z, 2 * X * Z, 2 * X * Y, 2 * X, 2 * Y, 2 * Z], 1)
    coef, *_ = np.linalg.lstsq(D, np.ones(len(p)), rcond=None)
    a, b, c, f, g, h, u, v, w = coef
    M = np.array([[a, h, g], [h, b, f], [g, f, c]])
    try:
        centre = -np.linalg.solve(M, np.array([u, v, w]))
    except np.linalg.LinAlgError:
        return None
    k = 1.0 + centre @ M @ centre
    Q = M / k
    evals, evecs = np.linalg.eigh(Q)
    # A flat sweep (a plane or a line) leaves one axis unconstrained: its eigenvalue is
    # round-off, positive or negative depending on the machine's BLAS.
    if not (np.isfinite(evals).all() and evals.min() > 1e-6 * evals.max()):
        return None
    root = evecs @ np.diag(np.sqrt(evals)) @ evecs.T  # in scaled units
    A = MAG_FULL_SCALE * root / s
    ell = MagEllipsoid(center=mu + s * centre, matrix=A)
    return EllipsoidFit(ell, sphere_residual(x, ell), len(x))


def sphere_residual(points: np.ndarray, ellipsoid: MagEllipsoid) -> float:
    """rms of ``|A (x - c)| - 100`` over ``points [n, 3]`` (calibrated units)."""
    r = np.linalg.norm((np.asarray(points, float) - ellipsoid.center) @ ellipsoid.matrix.T,
                       axis=1)
    return float(np.sqrt(np.mean((r - MAG_FULL_SCALE) ** 2))) if len(r) else float("nan")


def min_max_ellipsoid(min_max: np.ndarray) -> MagEllipsoid:
    """The docs/units.md min/max calibration ``[3, 2]`` written as an axis-aligned ellipsoid."""
    centre = min_max.mean(axis=1)
    return MagEllipsoid(center=centre,
                        matrix=np.diag(MAG_FULL_SCALE / (min_max[:, 1] - centre)))
