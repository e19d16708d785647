"""Accuracy against the simulated suit's ground truth.

Run: ``.venv/bin/python bench/accuracy.py [--seed 0] [--from-s 1.0] [--no-tables]
[--minutes 10]``. Prints Markdown tables (the figures in docs/filter.md and docs/filters.md
come from here):

- the default (Mahony) filter: per IMU and overall, RMS and max of the inclination error
  (angle between true and estimated down vector) and of the heading error (vertical component
  of the error rotation), from ``--from-s`` on (after the initial convergence and the automatic
  Reset Zero); per joint, RMS and max of the joint-angle error; per phase of the script, the
  overall RMS. Without and with the magnetic disturbance;
- the hinge constraint (:mod:`bpms.filter.hinge`) for every filter, VQF among them, on the
  script with the default magnet beside the right forearm: the forearm's heading error and the
  elbow's error in the magnet window and outside it, without and with the constraint. The
  elbow's error is the angle of the error of its relative orientation ``R_pᵀ R_d`` (all
  three degrees of freedom, sensor to sensor, so Reset Zero plays no part): a heading error of
  one segment shows there, while the flexion angle between the long axes hardly moves;
- the 6D mode's heading drift: ``--minutes`` of the script looped, every IMU with a seeded
  gyro bias of ±0.2 °/s per axis (``SensorModel.gyro_bias_axis_dps``), learnt at rest; the
  heading error of every IMU relative to its value at 1 s, at the end and its largest, beside
  VQF's 6D output on the same data.
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


def relative_error_deg(R: np.ndarray, R_true: np.ndarray, p: int, d: int) -> np.ndarray:
    """``[N]`` °: the angle of the error of the relative orientation ``R_pᵀ R_d``."""
    est = np.swapaxes(R[:, p], -1, -2) @ R[:, d]
    true = np.swapaxes(R_true[:, p], -1, -2) @ R_true[:, d]
    X = np.swapaxes(est, -1, -2) @ true
    c = (np.trace(X, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def _rms_all(x: np.ndarray) -> float:
    return float(np.sqrt(np.nanmean(np.square(x))))


@dataclass
class HingeFigures:
    """RMS errors in degrees: forearm heading and elbow relative orientation, in the magnet
    window and outside it (from 1 s), without and with the constraint."""

    head_in: tuple[float, float]
    head_out: tuple[float, float]
    elbow_in: tuple[float, float]
    elbow_out: tuple[float, float]
    clean_head: tuple[float, float]  # the same script without a magnet, whole recording


def hinge_figures(algorithm: str, seed: int = 0, heading: str = "magnetic") -> HingeFigures:
    """The processor with and without its hinge constraint (``BodyPoseProcessor.hinge``) on
    the script with and without the default magnet (right forearm, IMU 5; elbow 4 → 5)."""
    from bpms.io.options import Options

    out = {}
    for case in ("magnet", "clean"):
        rec = simulate(seed=seed, mag_disturbance=case == "magnet")
        options = Options()
        options.filter.algorithm = algorithm
        options.filter.heading = heading
        k = rec.t >= 1.0
        win = np.zeros(len(rec.t), bool)
        for d in rec.disturbances:
            win |= (rec.t >= d.t0) & (rec.t < d.t1)
        out[case] = []
        for on in (False, True):
            proc = BodyPoseProcessor(rec.calibration, options)
            if not on:
                proc.hinge = None
            R = proc.process(rec.raw, rec.errors).R
            out[case].append((np.degrees(heading_error(R[k], rec.truth.R[k]))[:, 5],
                              relative_error_deg(R[k], rec.truth.R[k], 4, 5), win[k]))
    m, c = out["magnet"], out["clean"]
    pair = lambda f: tuple(f(*m[j]) for j in range(2))  # noqa: E731
    return HingeFigures(pair(lambda h, e, w: _rms_all(h[w])), pair(lambda h, e, w: _rms_all(h[~w])),
                        pair(lambda h, e, w: _rms_all(e[w])), pair(lambda h, e, w: _rms_all(e[~w])),
                        tuple(_rms_all(c[j][0]) for j in range(2)))


def print_hinge(seed: int) -> None:
    from bpms.filter.algorithms import ALGORITHMS

    print(f"\nHinge constraint, simulated suit seed {seed}, default magnet beside the right "
          "forearm (17.4–24.8 s); RMS in degrees, without → with the constraint\n")
    print("| filter | forearm heading, magnet window | outside | elbow error, window | "
          "outside | forearm heading, no magnet |")
    print("|---|---|---|---|---|---|")
    for name in ALGORITHMS:
        f = hinge_figures(name, seed)
        cell = lambda v: f"{v[0]:.2f} → {v[1]:.2f}"  # noqa: E731
        print(f"| {name} | {cell(f.head_in)} | {cell(f.head_out)} | {cell(f.elbow_in)} | "
              f"{cell(f.elbow_out)} | {cell(f.clean_head)} |")


def looped(minutes: float) -> list:
    """The standard script repeated to last ``minutes``."""
    from bpms.firmware.sim.motion import default_script, script_duration

    one = default_script()
    return one * max(1, round(minutes * 60.0 / script_duration(one)))


def six_d_drift(minutes: float = 10.0, seed: int = 0, bias_dps: float = 0.2,
                algorithms: tuple[str, ...] = ("adaptive", "vqf")) -> dict[str, np.ndarray]:
    """``{filter: [N, 18]}`` heading error (°) relative to its value at 1 s, each filter in
    the 6D mode (``FilterOptions.heading = "relative"``, the processor as a session runs it,
    hinge constraint included), on ``minutes`` of the looped script with a seeded gyro bias of
    ±``bias_dps`` per axis; ``"t"``: the times."""
    from bpms.firmware.sim.sensors import SensorModel
    from bpms.io.options import Options

    rec = simulate(seed=seed, script=looped(minutes),
                   model=SensorModel(gyro_bias_axis_dps=bias_dps))
    k0 = round(1.0 / 0.02)
    out = {}
    for name in algorithms:
        options = Options()
        options.filter.algorithm = name
        options.filter.heading = "relative"
        R = BodyPoseProcessor(rec.calibration, options).process(rec.raw, rec.errors).R
        h = heading_error(R, rec.truth.R)
        out[name] = np.degrees(np.angle(np.exp(1j * (h - h[k0]))))
    out["t"] = rec.t
    return out


def print_6d(minutes: float, seed: int) -> None:
    d = six_d_drift(minutes, seed)
    t = d.pop("t")
    print(f"\n6D mode, simulated suit seed {seed}: {t[-1] / 60:.1f} min of the script looped, "
          "gyro bias ±0.2 °/s per axis (seeded, different per IMU), learnt at rest; heading "
          "relative to 1 s, degrees\n")
    print("| filter | RMS over IMUs at the end | largest IMU at the end | largest anywhere |")
    print("|---|---|---|---|")
    for name, h in d.items():
        print(f"| {name} 6D | {_rms_all(h[-1]):.2f}° | {np.abs(h[-1]).max():.2f}° | "
              f"{np.abs(h).max():.2f}° |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--from-s", type=float, default=1.0,
                        help="ignore errors before this time, s (initial convergence)")
    parser.add_argument("--no-tables", dest="tables", action="store_false",
                        help="skip the Mahony per-IMU, per-joint and per-phase tables")
    parser.add_argument("--minutes", type=float, default=10.0,
                        help="length of the 6D drift run, min")
    args = parser.parse_args()
    if args.tables:
        print_tables(args.seed, args.from_s)
    print_hinge(args.seed)
    print_6d(args.minutes, args.seed)


if __name__ == "__main__":
    main()
