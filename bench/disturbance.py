"""Precision and recall of the disturbance flags against known truth (issue 30.2).

Run: ``.venv/bin/python bench/disturbance.py [--set measure|dev] [--no-broad]`` (≈ 40 s).

**Simulated suit.** The script of docs/simulated-suit.md with fast moves added (two fast arm
swings and a quick squat: linear accelerations up to ≈ 3 g on the hands) and magnets standing
still beside a body part while it moves (:data:`MEASURE`: nine placements, strengths 40–200 in
units of the earth's field = 100, directions north, east, west, down and between; one recording
per seed without any magnet). Truth per frame and IMU, from the simulator's own field and
accelerations (nothing from the code under test):

- *mag*: ``|m_true − m_earth| / |m_earth|`` > ``DisturbanceSettings.mag_th`` (0.10), or the
  horizontal part of ``m_true`` turned from north by more than
  ``DisturbanceSettings.mag_turn_th`` (0.05) of the earth's field (the chord of the turn on
  the earth's horizontal field: 5.7° at the simulator's 60° dip), with ``m_true`` the
  simulated field at the IMU (earth's plus the magnets'), world axes;
- *acc*: the true linear acceleration's magnitude, RMS over ``DisturbanceSettings.tau_acc_s``
  (0.25 s, exponential, causal), > ``DisturbanceSettings.acc_th_g`` (0.2 g).

Scored: every frame from 5 s on (the field reference is learnt in the still start) × every IMU.
The thresholds were fixed before :data:`MEASURE` was first run; the detector's design was
worked out on :data:`DEV` (other seeds, three of its own placements), which is printed too.
Beside ours on the same frames: VQF's own ``magDistDetected`` (``vqf`` package, 9D, factory
settings).

**BROAD** (the 7 trials in ``../shared/data/broad``, 50 Hz): the files give no disturbance
phases, so the truth is derived: ``imu_mag`` rotated into the world with ``opt_quat``, against
the undisturbed field (the mean world field over the 5 s before the movement starts, averaged
over the four undisturbed trials 02, 07, 11 and 16 — the same room); truth = deviation > 10 % of
its norm, or its horizontal part turned from the undisturbed one by more than 5 % of its norm
(8° at BROAD's 69° dip). Scored:
movement frames with optical truth turning slower than 2 rad/s (faster, the
optical and inertial clocks' offset alone moves the rotated field by more than 10 %: at 4 rad/s
and above the undisturbed trials' median is already 11 %).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bpms.filter.disturbance import Disturbance, DisturbanceSettings, DisturbanceTracker
from bpms.filter.processor import BodyPoseProcessor
from bpms.firmware.sim.motion import Move, Step, default_script, generate_motion
from bpms.firmware.sim.session import Recording, magnet_near, simulate
from bpms.io.frames import IMU_NAMES, N_IMUS

REPO = Path(__file__).resolve().parents[1]
FROM_S = 5.0  # s: scored from here on (the reference is learnt in the still start)
G = 9.81


@dataclass(frozen=True)
class Magnet:
    """A magnet beside IMU ``imu`` from the start of phase ``start`` to the end of ``end``."""

    imu: int
    start: str
    end: str
    strength: float
    direction: tuple[float, float, float]
    offset: tuple[float, float, float] = (0.1, 0.15, 0.0)


#: The measured set: seeds × (each placement, and none).
MEASURE_SEEDS = (11, 12, 13)
MEASURE: tuple[Magnet, ...] = (
    Magnet(5, "elbow flexion", "arms relaxed", 60.0, (0.0, 1.0, 0.0)),  # the miss
    Magnet(5, "elbow flexion", "arms relaxed", 150.0, (0.0, 1.0, 0.0)),
    Magnet(14, "squat 1 down", "squat 1 up", 100.0, (0.0, 0.0, 1.0), (0.15, -0.1, 0.0)),
    Magnet(6, "trunk twist", "trunk neutral", 80.0, (1.0, 0.0, 0.0), (0.2, 0.0, 0.0)),
    Magnet(17, "head turn left", "head turn right", 60.0, (0.6, 0.8, 0.0), (0.1, 0.1, -0.05)),
    Magnet(9, "left arm forward raise", "left arm down", 100.0, (0.0, -1.0, 0.0),
           (0.15, -0.1, 0.0)),
    Magnet(0, "squat 2 down", "squat 2 up", 60.0, (0.7, 0.0, 0.7), (0.1, 0.15, 0.05)),
    Magnet(1, "walk", "walk", 200.0, (0.0, 0.0, 1.0), (1.5, 0.3, 0.0)),  # on the floor ahead
    Magnet(4, "both arms side raise", "both arms down", 40.0, (0.0, 1.0, 0.0)),
)
#: The design set (what the detector was worked out on).
DEV_SEEDS = (1, 2)
DEV: tuple[Magnet, ...] = (
    Magnet(5, "elbow flexion", "arms relaxed", 60.0, (0.0, 1.0, 0.0)),
    Magnet(14, "squat 1 down", "squat 1 up", 100.0, (0.0, 0.0, 1.0), (0.15, -0.1, 0.0)),
    Magnet(6, "trunk twist", "trunk neutral", 80.0, (1.0, 0.0, 0.0), (0.2, 0.0, 0.0)),
)


def fast_moves() -> list[Step]:
    """Two fast arm swings (0.4 s each way) and a quick squat: strong linear accelerations."""
    return [Move("fast arm swing", 0.4, {"sh_r_flex": 70, "sh_l_flex": -30}),
            Move("fast arm back", 0.4),
            Move("fast arm swing 2", 0.4, {"sh_r_flex": -30, "sh_l_flex": 70}),
            Move("fast arm back 2", 0.4, hold=0.5),
            Move("quick squat", 0.7, {"hip_r_flex": 40, "hip_l_flex": 40, "knee_r": 50,
                                      "knee_l": 50, "ankle_r": 20, "ankle_l": 20}),
            Move("quick up", 0.6, hold=0.5)]


def script() -> list[Step]:
    """The standard script with :func:`fast_moves` before the head turns."""
    steps = default_script()
    k = next(i for i, s in enumerate(steps) if s.name == "head turn left")
    return steps[:k] + fast_moves() + steps[k:]


def _phase(phases: list[tuple[float, float, str]], name: str) -> tuple[float, float]:
    return next((a, b) for a, b, n in phases if n == name)


def recording(seed: int, magnet: Magnet | None, steps: list[Step] | None = None) -> Recording:
    """One simulated recording of ``steps`` (default :func:`script`) with ``magnet``."""
    steps = script() if steps is None else steps
    if magnet is None:
        return simulate(seed=seed, script=steps)
    motion = generate_motion(script=steps)
    t0 = _phase(motion.phases, magnet.start)[0]
    t1 = _phase(motion.phases, magnet.end)[1]
    dist = magnet_near(motion, magnet.imu, t0, t1, magnet.offset, magnet.strength,
                       magnet.direction)
    return simulate(seed=seed, script=steps, mag_disturbance=True, disturbances=[dist])


def sim_truth(rec: Recording, settings: DisturbanceSettings | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(mag truth, acc truth ``[N, 18]`` bool, field deviation (fraction), RMS linear
    acceleration (g)) of a simulated recording, by the rule of the module docstring."""
    s = settings or DisturbanceSettings()
    world = np.einsum("nkij,nkj->nki", rec.truth.R, rec.truth.sensors.mag)
    dip = np.deg2rad(rec.model.dip_deg)
    earth = 100.0 * np.array([np.cos(dip), 0.0, np.sin(dip)])
    dev = np.linalg.norm(world - earth, axis=-1) / 100.0
    # the horizontal part turned from north, as a chord in units of the earth's field
    turned = 2.0 * np.cos(dip) * np.abs(np.sin(0.5 * np.arctan2(world[..., 1], world[..., 0])))
    a2 = (np.linalg.norm(rec.truth.imu_acceleration, axis=-1) / G) ** 2
    k = 1.0 - np.exp(-0.02 / s.tau_acc_s)
    ms = np.empty_like(a2)
    run = np.zeros(a2.shape[1])
    for t in range(len(a2)):
        run += k * (a2[t] - run)
        ms[t] = run
    lin = np.sqrt(ms)
    mag = (dev > s.mag_th) | (turned > s.mag_turn_th)
    return mag, lin > s.acc_th_g, dev, lin


def sim_flags(rec: Recording, settings: DisturbanceSettings | None = None) -> Disturbance:
    """The detector on a recording's calibrated sensors (as the processor calibrates them)."""
    proc = BodyPoseProcessor(rec.calibration)
    acc, mag, gyr = proc.calibrate(rec.raw)
    tracker = DisturbanceTracker(proc.sensor_calibration.gravity, 0.02, settings)
    return tracker.update(acc, mag, gyr, rec.errors)


def vqf_mag_flags(acc: np.ndarray, mag: np.ndarray, gyr: np.ndarray, dt: float
                  ) -> np.ndarray:
    """``[N, n]`` VQF's ``magDistDetected`` (specific force m/s², any field unit, rad/s)."""
    from vqf import VQF

    out = np.zeros(acc.shape[:2], np.bool_)
    for i in range(acc.shape[1]):
        res = VQF(dt).updateBatch(*(np.ascontiguousarray(v[:, i], dtype=np.float64)
                                    for v in (gyr, acc, mag)))
        out[:, i] = res["magDistDetected"]
    return out


def sim_vqf_flags(rec: Recording) -> np.ndarray:
    proc = BodyPoseProcessor(rec.calibration)
    acc, mag, gyr = proc.calibrate(rec.raw)
    f = -acc * G / proc.sensor_calibration.gravity[None, :, None]
    return vqf_mag_flags(f, mag / 100.0, gyr, 0.02)


@dataclass
class Score:
    """Counts over (frame, IMU) pairs."""

    tp: int = 0
    fp: int = 0
    fn: int = 0
    per_imu: np.ndarray = field(default_factory=lambda: np.zeros((N_IMUS, 3), np.int64))

    def add(self, flag: np.ndarray, truth: np.ndarray, sel: np.ndarray) -> None:
        f, g = flag & sel, truth & sel
        counts = np.stack([(f & g).sum(0), (f & ~g).sum(0), (~f & g & sel).sum(0)], -1)
        if counts.shape[0] == N_IMUS:
            self.per_imu += counts
        self.tp += int(counts[:, 0].sum())
        self.fp += int(counts[:, 1].sum())
        self.fn += int(counts[:, 2].sum())

    @property
    def precision(self) -> float:
        return self.tp / (self.tp + self.fp) if self.tp + self.fp else float("nan")

    @property
    def recall(self) -> float:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else float("nan")

    def __str__(self) -> str:
        return (f"precision {100 * self.precision:5.1f} %, recall {100 * self.recall:5.1f} % "
                f"(tp {self.tp}, fp {self.fp}, fn {self.fn})")


def score_sim(seeds: tuple[int, ...], magnets: tuple[Magnet, ...], compare: bool = True
              ) -> dict[str, Score]:
    """Scores of our flags (and, with ``compare``, the older indicators' and VQF's mag flag)
    over every seed × (each magnet, and none)."""
    scores = {k: Score() for k in ("mag", "acc", "vqf mag")}
    for seed in seeds:
        for magnet in (*magnets, None):
            rec = recording(seed, magnet)
            tm, ta, _, _ = sim_truth(rec)
            sel = np.broadcast_to((rec.t >= FROM_S)[:, None], tm.shape)
            flags = sim_flags(rec)
            scores["mag"].add(flags.mag, tm, sel)
            scores["acc"].add(flags.acc, ta, sel)
            if compare:
                scores["vqf mag"].add(sim_vqf_flags(rec), tm, sel)
    return scores


def print_sim(name: str, scores: dict[str, Score]) -> None:
    print(f"\nSimulated suit, set '{name}', per frame and IMU from {FROM_S:g} s:\n")
    print("| flag | precision | recall | tp | fp | fn |")
    print("|---|---|---|---|---|---|")
    for key, s in scores.items():
        if s.tp + s.fp + s.fn:
            print(f"| {key} | {100 * s.precision:.1f} % | {100 * s.recall:.1f} % | {s.tp} | "
                  f"{s.fp} | {s.fn} |")
    print("\nper IMU (mag precision / recall, acc precision / recall; – no positives):\n")
    print("| IMU | mag | acc |")
    print("|---|---|---|")
    for i, imu in enumerate(IMU_NAMES):
        cells = []
        for key in ("mag", "acc"):
            tp, fp, fn = scores[key].per_imu[i]
            p = f"{100 * tp / (tp + fp):.0f} %" if tp + fp else "–"
            r = f"{100 * tp / (tp + fn):.0f} %" if tp + fn else "–"
            cells.append(f"{p} / {r}")
        print(f"| {i} {imu} | " + " | ".join(cells) + " |")


# -- BROAD ---------------------------------------------------------------------------------
#: Truth threshold on BROAD (fraction of the undisturbed field's norm) and the rate limit.
BROAD_TH = 0.10
BROAD_MAX_RATE = 2.0  # rad/s
UNDISTURBED = ("02_", "07_", "11_", "16_")


def _bench_broad():
    spec = importlib.util.spec_from_file_location("bench_broad_for_flags",
                                                  REPO / "bench" / "broad.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def broad_world_field(trial) -> tuple[np.ndarray, np.ndarray]:
    """(``imu_mag`` in BROAD's world frame ``[N, 3]`` µT, has optical truth ``[N]``)."""
    from bpms.filter.rotations import quaternion_to_dcm

    q = trial.opt_quat
    ok = np.isfinite(q).all(axis=1)
    R = np.full((len(q), 3, 3), np.nan)
    R[ok] = quaternion_to_dcm(q[ok] / np.linalg.norm(q[ok], axis=1, keepdims=True))
    return np.einsum("nij,nj->ni", R, trial.mag), ok


def broad_reference(trials) -> np.ndarray:
    """The undisturbed world field (µT): the mean over the 5 s before the movement, averaged
    over the undisturbed trials."""
    refs = []
    for tr in trials:
        if tr.name.startswith(UNDISTURBED):
            world, ok = broad_world_field(tr)
            first = int(np.flatnonzero(tr.movement)[0])
            k = np.arange(max(0, first - round(5 * tr.rate)), first)
            refs.append(world[k[ok[k]]].mean(axis=0))
    return np.mean(refs, axis=0)


def broad_truth(trial, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(truth ``[N]`` bool, scored ``[N]`` bool) of one trial (module docstring)."""
    world, ok = broad_world_field(trial)
    dev = np.linalg.norm(world - ref, axis=1) / np.linalg.norm(ref)
    turn = np.angle(np.exp(1j * (np.arctan2(world[:, 1], world[:, 0])
                                 - np.arctan2(ref[1], ref[0]))))
    slow = np.linalg.norm(trial.gyr, axis=1) < BROAD_MAX_RATE
    horizontal = np.hypot(ref[0], ref[1]) / np.linalg.norm(ref)
    turned = 2.0 * horizontal * np.abs(np.sin(0.5 * turn)) > DisturbanceSettings().mag_turn_th
    truth = (dev > BROAD_TH) | turned
    return truth, trial.movement & ok & slow


def score_broad(data: Path) -> list[tuple[str, Score, Score, float]]:
    """Per trial: (name, our mag score, VQF's, fraction of movement with acc flagged)."""
    bench = _bench_broad()
    trials = bench.load_50hz(data)
    ref = broad_reference(trials)
    rows = []
    for tr in trials:
        truth, sel = broad_truth(tr, ref)
        # the suite's accelerometer convention: the gravity direction, 9.81 units per g
        flags = DisturbanceTracker(np.array([G]), 1.0 / tr.rate).update(
            -tr.acc[:, None], tr.mag[:, None], tr.gyr[:, None])
        ours, vqf = Score(), Score()
        ours.add(flags.mag, truth[:, None], sel[:, None])
        vqf.add(vqf_mag_flags(tr.acc[:, None], tr.mag[:, None], tr.gyr[:, None],
                              1.0 / tr.rate), truth[:, None], sel[:, None])
        rows.append((tr.name, ours, vqf, float(flags.acc[tr.movement, 0].mean())))
    return rows


def print_broad(rows) -> None:
    print(f"\nBROAD at 50 Hz: mag flag against the derived truth (deviation > "
          f"{100 * BROAD_TH:.0f} % or turned by 5 %, frames slower than {BROAD_MAX_RATE:g} "
          "rad/s)\n")
    print("| trial | truth + | ours: precision / recall | VQF: precision / recall | "
          "acc flagged (movement) |")
    print("|---|---|---|---|---|")
    total_o, total_v = Score(), Score()
    pr = lambda s: (f"{100 * s.precision:.0f} % / {100 * s.recall:.0f} %"  # noqa: E731
                    .replace("nan %", "–"))
    for name, o, v, acc in rows:
        for t, s in ((total_o, o), (total_v, v)):
            t.tp, t.fp, t.fn = t.tp + s.tp, t.fp + s.fp, t.fn + s.fn
        print(f"| {name} | {o.tp + o.fn} | {pr(o)} (fp {o.fp}) | {pr(v)} (fp {v.fp}) | "
              f"{100 * acc:.0f} % |")
    print(f"| **all** | {total_o.tp + total_o.fn} | **{pr(total_o)}** | {pr(total_v)} | |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", choices=("measure", "dev"), default="measure")
    parser.add_argument("--no-broad", dest="broad", action="store_false")
    parser.add_argument("--data", help="BROAD folder (default ../shared/data/broad)")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    s = DisturbanceSettings()
    print(f"Thresholds: mag {100 * s.mag_th:.0f} % of the earth's field, or its horizontal "
          f"part turned by {100 * s.mag_turn_th:.0f} % of it (+ {1000 * s.skew_s:g}"
          f" ms × rate), acc {s.acc_th_g:g} g RMS over {s.tau_acc_s:g} s")
    if args.set == "measure":
        print_sim("measure", score_sim(MEASURE_SEEDS, MEASURE))
    print_sim("dev", score_sim(DEV_SEEDS, DEV, compare=args.set == "dev"))
    if args.broad:
        data = _bench_broad().find_data(args.data)
        if data is None:
            print("\nBROAD: no data folder, skipped")
        else:
            print_broad(score_broad(data))
    print(f"\ntotal run time {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
