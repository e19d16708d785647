"""Optical exports made from known orientations: Vicon Nexus CSV and Qualisys TSV writers, and
an optical file of the simulated suit's truth with a known clock offset, known IMU-to-cluster
and world rotations, marker noise and occlusion gaps (the proofs of docs/compare.md and its
worked example).

``tools/make_compare_sample.py`` writes the sample ``docs/samples/
optical_simulated_arm_raise.csv`` with it, from the simulation of ``Raw_simulated_arm_raise``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bpms.analysis.compare_align import exp_map
from bpms.filter.rotations import rotation_vector


def _rows(data: np.ndarray, fmt: str, sep: str, missing: str) -> list[str]:
    """Rows of ``data`` as text, every cell ``fmt``, NaN written as ``missing``."""
    row = sep.join([fmt] * data.shape[1])
    text = "\n".join(row % tuple(r) for r in data)
    return text.replace("nan", missing).split("\n")


def write_vicon_csv(path: str | Path, rate_hz: float, bodies: dict[str, tuple[np.ndarray,
                    np.ndarray]], subject: str = "Subject") -> Path:
    """A Nexus "Export CSV" ``Segments`` block: per body ``(R[N, 3, 3] body → capture,
    position[N, 3] mm)``; a NaN orientation is an empty (occluded) row of that body."""
    path = Path(path)
    names = list(bodies)
    head = ["Segments", f"{rate_hz:g}",
            ",," + ",".join(f"{subject}:{b},,,,," for b in names).rstrip(","),
            "Frame,Sub Frame" + ",RX,RY,RZ,TX,TY,TZ" * len(names),
            ",," + ",".join("deg,deg,deg,mm,mm,mm" for _ in names)]
    cols = []
    for R, pos in bodies.values():
        helical = np.degrees(rotation_vector(R))
        helical[~np.isfinite(R).all(axis=(1, 2))] = np.nan
        cols.append(np.concatenate([helical, np.where(np.isfinite(helical), pos, np.nan)], 1))
    data = np.concatenate(cols, axis=1)
    rows = [f"{k + 1},0,{r}" for k, r in enumerate(_rows(data, "%.4f", ",", ""))]
    path.write_text("\n".join(head + rows) + "\n", encoding="utf-8")
    return path


def write_qualisys_tsv(path: str | Path, rate_hz: float, bodies: dict[str, tuple[np.ndarray,
                       np.ndarray]]) -> Path:
    """A QTM 6DOF TSV export (16 columns per body, the rotation matrix column-major); a NaN
    orientation is a row of NaN for that body (QTM's occluded body)."""
    path = Path(path)
    names = list(bodies)
    n = len(next(iter(bodies.values()))[0])
    head = [f"NO_OF_FRAMES\t{n}", "NO_OF_CAMERAS\t8", f"NO_OF_BODIES\t{len(names)}",
            f"FREQUENCY\t{rate_hz:g}", "NO_OF_ANALOG\t0", "ANALOG_FREQUENCY\t0",
            "DESCRIPTION\t--", "DATA_INCLUDED\t6D", "BODY_NAMES\t" + "\t".join(names)]
    labels = ["Frame", "Time"]
    for b in names:
        labels += [b, "Y", "Z", "Roll", "Pitch", "Yaw", "Residual",
                   *(f"Rot[{i}]" for i in range(9))]
    cols = []
    for R, pos in bodies.values():
        ok = np.isfinite(R).all(axis=(1, 2))
        roll = np.degrees(np.arctan2(-R[:, 1, 2], R[:, 2, 2]))
        pitch = np.degrees(np.arcsin(np.clip(R[:, 0, 2], -1, 1)))
        yaw = np.degrees(np.arctan2(-R[:, 0, 1], R[:, 0, 0]))
        rot = np.swapaxes(R, 1, 2).reshape(-1, 9)  # column-major
        block = np.concatenate([pos, np.stack([roll, pitch, yaw, np.full(n, 0.8)], 1), rot], 1)
        block[~ok] = np.nan
        cols.append(block)
    data = np.concatenate(cols, axis=1)
    rows = [f"{k + 1}\t{k / rate_hz:.5f}\t{r}"
            for k, r in enumerate(_rows(data, "%.6f", "\t", "NaN"))]
    path.write_text("\n".join([*head, "\t".join(labels), *rows]) + "\n", encoding="utf-8")
    return path


def interpolate_rotations(t: np.ndarray, R: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """``R[N, ..., 3, 3]`` at times ``t[N]`` interpolated on the geodesic at ``t_new``
    (clamped to the ends)."""
    u = np.clip(np.interp(t_new, t, np.arange(len(t))), 0, len(t) - 1)
    i = np.minimum(np.floor(u).astype(int), len(t) - 2)
    f = (u - i).reshape((-1,) + (1,) * (R.ndim - 2))
    rel = rotation_vector(np.swapaxes(R[i], -1, -2) @ R[i + 1])
    return R[i] @ exp_map(rel * f)


@dataclass
class SyntheticOptical:
    """What :func:`optical_from_truth` wrote: offset_s (``t_bpms = t_optical + offset``), the
    per-IMU IMU-to-cluster rotation ``S[18, 3, 3]``, the world rotation ``W`` (optical world →
    NED), the occluded samples per body."""

    path: Path
    offset_s: float
    S: np.ndarray
    W: np.ndarray
    gaps: dict[str, int]


def optical_from_truth(path: str | Path, t: np.ndarray, R_true: np.ndarray,
                       positions_m: np.ndarray, names: dict[int, str], *, rate_hz: float = 100.0,
                       offset_s: float = 0.73, seed: int = 0, noise_deg: float = 0.2,
                       noise_mm: float = 0.5, gaps: int = 3, gap_s: float = 0.3,
                       rotation_deg: float = 20.0) -> SyntheticOptical:
    """Write the optical export (``.csv`` Vicon, else Qualisys) of true IMU orientations
    ``R_true[N, 18, 3, 3]`` (IMU → NED) at BPMS times ``t[N]``: ``Q = Wᵀ R_true Sᵀ`` with random
    ``S`` per IMU and a random ``W`` (angles up to ``rotation_deg``, W with a 90° heading
    turn on top), sampled at ``rate_hz`` from ``t[0] - offset_s`` on, a random rotation of
    ``noise_deg`` RMS per axis and ``noise_mm`` on positions per sample, and ``gaps`` occlusions
    of ``gap_s`` per body. ``names``: IMU index → optical body name."""
    rng = np.random.default_rng(seed)
    span = t[-1] - t[0]
    t_opt = np.arange(0.0, span - 0.05, 1.0 / rate_hz)
    t_b = np.clip(t_opt + offset_s, t[0], t[-1])  # BPMS time of each optical sample
    S = exp_map(rng.normal(size=(18, 3)) * np.radians(rotation_deg) / np.sqrt(3))
    W = exp_map(np.array([0, 0, np.pi / 2])) @ exp_map(
        rng.normal(size=3) * np.radians(rotation_deg) / np.sqrt(3))
    bodies, gap_count = {}, {}
    for imu, name in names.items():
        Rt = interpolate_rotations(t, R_true[:, imu], t_b)
        noise = exp_map(rng.normal(size=(len(t_opt), 3)) * np.radians(noise_deg))
        Q = W.T @ Rt @ S[imu].T @ noise
        pos = np.stack([np.interp(t_b, t, positions_m[:, imu, k]) for k in range(3)], 1)
        pos = pos * 1000.0 + rng.normal(size=pos.shape) * noise_mm
        length = max(1, round(gap_s * rate_hz))
        for _ in range(gaps):
            start = int(rng.integers(length, len(t_opt) - 2 * length))
            Q[start:start + length] = np.nan
        gap_count[name] = int(np.isnan(Q[:, 0, 0]).sum())
        bodies[name] = (Q, pos)
    path = Path(path)
    if path.suffix.lower() == ".csv":
        write_vicon_csv(path, rate_hz, bodies)
    else:
        write_qualisys_tsv(path, rate_hz, bodies)
    return SyntheticOptical(path, offset_s, S, W, gap_count)
