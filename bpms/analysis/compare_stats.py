"""The figures of ``bpms compare`` (docs/compare.md): per segment the orientation error split
into inclination and heading, and its drift; per joint angle the errors and a Bland-Altman
summary. Angles in degrees, trends in degrees per minute.

Orientation error of a segment (BROAD's definitions, Laidig et al. 2021): the error rotation in
the world frame ``E = R_bpms · R_opticalᵀ`` as a quaternion (w, x, y, z) with the vertical z;
total error ``2 acos |w|``; heading error ``2 atan(|z / w|)`` (the rotation about the
vertical); inclination error ``2 acos √(w² + z²)`` (the rest).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bpms.analysis.compare_align import angle_deg, project_so3
from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.filter.rotations import dcm_to_quaternion


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if len(x) else float("nan")


def _slope_per_min(t: np.ndarray, y: np.ndarray) -> float:
    """Least-squares trend of ``y`` over ``t`` s, units of y per minute (NaN < 2 samples)."""
    if len(t) < 2 or np.ptp(t) <= 0:
        return float("nan")
    return float(np.polyfit(t, y, 1)[0] * 60.0)


def error_angles(R_est: np.ndarray, R_ref: np.ndarray) -> tuple[np.ndarray, ...]:
    """(total, heading, signed heading, inclination) in degrees ``[N]`` of the world-frame
    error ``R_est R_refᵀ`` (NaN where either is missing)."""
    E = R_est @ np.swapaxes(R_ref, -1, -2)
    q = np.full((*E.shape[:-2], 4), np.nan)
    ok = np.isfinite(E).all(axis=(-1, -2))
    q[ok] = dcm_to_quaternion(E[ok])
    w, z = q[..., 0], q[..., 3]
    with np.errstate(invalid="ignore", divide="ignore"):
        total = 2 * np.arccos(np.clip(np.abs(w), 0, 1))
        heading = 2 * np.arctan(np.abs(z / w))
        signed = 2 * np.arctan(z / w)
        incl = 2 * np.arccos(np.clip(np.sqrt(w**2 + z**2), 0, 1))
    return tuple(np.degrees(a) for a in (total, heading, signed, incl))


@dataclass
class SegmentStats:
    """One optical body against its BPMS segment (degrees; trends deg/min).

    samples: compared samples; gaps: samples inside the optical file's span without a valid
    optical orientation on both sides (occluded), skipped; rmse_* / max_total: over the
    compared samples; trend_total / trend_heading: least-squares slope of the total and of the
    signed heading error; pause_change: angle between the mean error rotation over the first
    and over the last still pause (NaN without two pauses); series: total error ``[N]``.
    """

    body: str
    imu: int
    samples: int
    gaps: int
    rmse_total: float
    rmse_heading: float
    rmse_inclination: float
    max_total: float
    mean_total: float
    trend_total: float
    trend_heading: float
    pause_change: float
    series: np.ndarray


def segment_stats(body: str, imu: int, t: np.ndarray, R: np.ndarray, R_opt: np.ndarray,
                  inside: np.ndarray, gap: np.ndarray, pauses: list[tuple[float, float]]
                  ) -> SegmentStats:
    """The figures of one segment: BPMS ``R[N, 3, 3]`` against the aligned optical
    ``R_opt[N, 3, 3]`` at times ``t[N]`` s."""
    total, heading, signed, incl = error_angles(R, R_opt)
    ok = inside & np.isfinite(total)
    change = float("nan")
    if len(pauses) >= 2:
        E = R @ np.swapaxes(R_opt, -1, -2)
        means = []
        for a, b in (pauses[0], pauses[-1]):
            k = ok & (t >= a) & (t < b)
            means.append(project_so3(E[k].sum(axis=0)) if k.any() else None)
        if means[0] is not None and means[1] is not None:
            change = float(angle_deg(means[1] @ means[0].T))
    series = np.where(ok, total, np.nan)
    return SegmentStats(
        body, imu, int(ok.sum()), int(gap.sum()), _rms(total[ok]), _rms(heading[ok]),
        _rms(incl[ok]), float(np.max(total[ok])) if ok.any() else float("nan"),
        float(np.mean(total[ok])) if ok.any() else float("nan"),
        _slope_per_min(t[ok], total[ok]), _slope_per_min(t[ok], signed[ok]), change, series)


@dataclass
class JointStats:
    """One joint angle, BPMS minus optical (degrees): samples compared; rmse, max_abs; the
    Bland-Altman summary: bias (mean difference), sd, the 95 % limits of agreement
    ``bias ± 1.96 sd``, proportional bias (slope of the difference over the mean of the two);
    trend (deg/min) of the difference over the trial."""

    name: str
    samples: int
    rmse: float
    max_abs: float
    bias: float
    sd: float
    loa_low: float
    loa_high: float
    proportional: float
    trend: float


def joint_stats(t: np.ndarray, bpms_rad: np.ndarray, optical_rad: np.ndarray,
                inside: np.ndarray) -> tuple[list[JointStats], np.ndarray, np.ndarray]:
    """(stats of every joint angle with compared samples, BPMS and optical angles in degrees
    ``[N, J]`` of those joints). Differences wrapped to ±180°."""
    stats, cols = [], []
    for k, name in enumerate(JOINT_ANGLE_NAMES):
        a, b = bpms_rad[:, k], optical_rad[:, k]
        ok = inside & np.isfinite(a) & np.isfinite(b)
        if ok.sum() < 2:
            continue
        d = np.degrees(np.angle(np.exp(1j * (a[ok] - b[ok]))))
        mean = np.degrees(0.5 * (a[ok] + b[ok]))
        bias, sd = float(np.mean(d)), float(np.std(d, ddof=1))
        prop = float(np.polyfit(mean, d, 1)[0]) if np.ptp(mean) > 0 else float("nan")
        stats.append(JointStats(name, int(ok.sum()), _rms(d), float(np.max(np.abs(d))), bias,
                                sd, bias - 1.96 * sd, bias + 1.96 * sd, prop,
                                _slope_per_min(t[ok], d)))
        cols.append(k)
    with np.errstate(invalid="ignore"):
        jb = np.degrees(bpms_rad[:, cols]) if cols else np.empty((len(t), 0))
        jo = np.degrees(optical_rad[:, cols]) if cols else np.empty((len(t), 0))
    return stats, np.where(inside[:, None], jb, np.nan), np.where(inside[:, None], jo, np.nan)
