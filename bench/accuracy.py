"""Accuracy of the Mahony filter bank against the simulated suit's ground truth.

Run: ``.venv/bin/python bench/accuracy.py [--seed 0] [--from-s 1.0]``. Prints Markdown tables
(the figures in docs/filter.md come from here): per IMU and overall, RMS and max of the
inclination error (angle between true and estimated down vector) and of the heading error
(vertical component of the error rotation), from ``--from-s`` on (after the initial
convergence and the automatic Reset Zero); per joint, RMS and max of the joint-angle error;
per phase of the script, the overall RMS. Without and with the magnetic disturbance.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np

from bpms.filter.joints import JOINT_ANGLE_NAMES
from bpms.filter.processor import BodyPoseProcessor, Result
from bpms.filter.rotations import heading_error, inclination_error
from bpms.firmware.sim.session import Recording, simulate
from bpms.io.frames import IMU_NAMES


@dataclass
class Accuracy:
    """Errors in degrees after ``from_s``: per IMU ``[18]`` and per joint ``[28]``."""

    incl_rms: np.ndarray
    incl_max: np.ndarray
    head_rms: np.ndarray
    head_max: np.ndarray
    joint_rms: np.ndarray
    joint_max: np.ndarray
    incl_all: np.ndarray  # [M, 18] deg, for per-phase figures
    head_all: np.ndarray
    joint_all: np.ndarray  # [M, 28]
    t: np.ndarray  # [M]

    @property
    def incl_rms_overall(self) -> float:
        return float(np.sqrt(np.mean(self.incl_all**2)))

    @property
    def head_rms_overall(self) -> float:
        return float(np.sqrt(np.mean(self.head_all**2)))

    @property
    def joint_rms_overall(self) -> float:
        return float(np.sqrt(np.mean(self.joint_all**2)))


def _rms(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(x**2, axis=0))


def accuracy(rec: Recording, result: Result, from_s: float = 1.0) -> Accuracy:
    """Compare a processed simulated recording with its truth."""
    k = rec.t >= from_s
    incl = np.degrees(inclination_error(result.R[k], rec.truth.R[k]))
    head = np.degrees(heading_error(result.R[k], rec.truth.R[k]))
    diff = result.joint_angles[k] - rec.truth.joint_angles[k]
    joint = np.degrees(np.angle(np.exp(1j * diff)))
    return Accuracy(_rms(incl), np.abs(incl).max(0), _rms(head), np.abs(head).max(0),
                    _rms(joint), np.abs(joint).max(0), incl, head, joint, rec.t[k])


def run(seed: int = 0, mag_disturbance: bool = False, from_s: float = 1.0,
        ) -> tuple[Recording, Accuracy]:
    rec = simulate(seed=seed, mag_disturbance=mag_disturbance)
    result = BodyPoseProcessor(rec.calibration).process(rec.raw, rec.errors)
    return rec, accuracy(rec, result, from_s)


def print_tables(seed: int, from_s: float) -> None:
    recs = {name: run(seed, dist, from_s) for name, dist in (("undisturbed", False),
                                                             ("magnet", True))}
    acc = {name: a for name, (_, a) in recs.items()}
    rec = recs["undisturbed"][0]
    print(f"Simulated suit, seed {seed}, {len(rec)} frames ({len(rec) * 0.02:.1f} s), "
          f"factory gains, errors from t = {from_s} s.\n")
    print("| IMU | incl. RMS | incl. max | heading RMS | heading max | incl. RMS (magnet) | "
          "heading RMS (magnet) | heading max (magnet) |")
    print("|---|---|---|---|---|---|---|---|")
    u, m = acc["undisturbed"], acc["magnet"]
    for i, name in enumerate(IMU_NAMES):
        print(f"| {i} {name} | {u.incl_rms[i]:.2f}° | {u.incl_max[i]:.1f}° | {u.head_rms[i]:.2f}° "
              f"| {u.head_max[i]:.1f}° | {m.incl_rms[i]:.2f}° | {m.head_rms[i]:.2f}° "
              f"| {m.head_max[i]:.1f}° |")
    print(f"| **all** | **{u.incl_rms_overall:.2f}°** | {u.incl_max.max():.1f}° | "
          f"**{u.head_rms_overall:.2f}°** | {u.head_max.max():.1f}° | "
          f"{m.incl_rms_overall:.2f}° | {m.head_rms_overall:.2f}° | {m.head_max.max():.1f}° |")
    print("\n| joint angle | RMS | max | RMS (magnet) | max (magnet) |")
    print("|---|---|---|---|---|")
    for j, name in enumerate(JOINT_ANGLE_NAMES):
        print(f"| {name} | {u.joint_rms[j]:.2f}° | {u.joint_max[j]:.1f}° | "
              f"{m.joint_rms[j]:.2f}° | {m.joint_max[j]:.1f}° |")
    print(f"| **all** | **{u.joint_rms_overall:.2f}°** | {u.joint_max.max():.1f}° | "
          f"{m.joint_rms_overall:.2f}° | {m.joint_max.max():.1f}° |")
    print("\n| phase | incl. RMS | heading RMS | joint RMS | heading RMS (magnet) | "
          "joint RMS (magnet) |")
    print("|---|---|---|---|---|---|")
    for t0, t1, name in rec.phases:
        sel = (u.t >= t0) & (u.t < t1)
        if not sel.any():
            continue
        r = [np.sqrt(np.mean(x[sel] ** 2)) for x in (u.incl_all, u.head_all, u.joint_all,
                                                      m.head_all, m.joint_all)]
        print(f"| {t0:.1f}–{t1:.1f} s {name} | " + " | ".join(f"{v:.2f}°" for v in r) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--from-s", type=float, default=1.0,
                        help="ignore errors before this time, s (initial convergence)")
    args = parser.parse_args()
    print_tables(args.seed, args.from_s)


if __name__ == "__main__":
    main()
