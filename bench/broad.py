"""The selectable attitude filters on the BROAD subset (real IMU data, optical truth).

Run: ``.venv/bin/python bench/broad.py [--data DIR] [--trials SUBSTR ...] [--max-s S]
[--no-loo] [--extra] [--sim]``.
Data: ``../shared/data/broad`` beside the repository root (README there). Each filter runs on
each trial at the trial's own rate (≈ 285.7 Hz) and resampled to the suit's 50 Hz (linear
interpolation of the IMU signals at k·20 ms, truth and movement mask taken at the nearest
sample), with its factory settings, starting from the first sample (each filter aligns
itself). Units handed to each filter as it expects them: Mahony (SPEC §5) gets the
accelerometer in counts of 1 g pointing down (Gravity = 256 counts/g), the magnetometer
scaled to ±100 and gyro rad/s; the observer and VQF get specific force in m/s², the field in
µT/50 and rad/s. Outputs are rotated from NED to BROAD's ENU. Nothing is aligned that the
dataset's metric does not align: ``q_err = q_imu ⊗ q_opt⁻¹`` (earth frame), total error
``2 acos|w|``, heading ``2 atan|z/w|``, inclination ``2 acos √(w² + z²)``, RMSE in degrees over
the movement phases (samples without optical truth skipped), as the dataset's own code.

Leave-one-trial-out at the suit's 50 Hz (unless ``--no-loo``; with 3 or more trials). For
each filter a small grid of its
settings (:data:`LOO_GRIDS`, option names); for each held-out trial the setting with the
lowest mean total RMSE on the other trials is chosen and its error on the held-out trial
reported — an honest estimate of the error on a trial the settings were not chosen on. Printed
beside the in-sample figures (factory settings, which were chosen on all 7 trials) and the gap
between them. This is nested cross-validation for a grid search: the inner selection on the
training trials is the mean error over them (each training trial its own validation fold,
since the filters fit nothing but these settings). What it cannot cover is what was designed
by looking at all 7 trials (the adaptive observer's additions, the grids themselves): the
held-out figure is optimistic by that much, which trials this project does not have measure.

Also printed (50 Hz): the heading RMSE on the magnet trials (31, 33), and the 6D mode — no
magnetometer, heading relative to the start — per whole trial: heading error about the
vertical after removing its circular mean over the first 5 s with optical truth, RMSE over
every frame with optical truth (the ``adaptive`` filter with its heading correction off,
beside VQF's own 6D output ``quat6D``).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bpms.filter.algorithms import ALGORITHMS, G_MS2, ObserverBank, make_bank
from bpms.filter.bank import MahonyBank
from bpms.filter.disturbance import DisturbanceTracker
from bpms.filter.processor import MAG_TRUST_FLAGGED
from bpms.filter.rotations import dcm_to_quaternion
from bpms.filter.vqf_filter import Q_ENU_TO_NED, quat_mul
from bpms.io.options import FilterOptions

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATA = REPO.parent / "shared" / "data" / "broad"
SUIT_RATE_HZ = 50.0
MAHONY_GRAVITY = 256.0  # counts per g handed to the original filter
#: Extra row (--extra): the original filter with the published BROAD Mahony gains
#: (Kp 0.74, Ki 0.0012 per unit vector error → per accel count: ÷ Gravity). Not a default.
MAHONY_TUNED = "mahony-kp0.74"
#: Published averages over all 39 trials (total, heading, inclination RMSE, degrees).
PUBLISHED = {"Madgwick (β = 0.12)": (4.96, 3.92, 2.71),
             "Mahony (Kp = 0.74, Ki = 0.0012)": (7.49, 6.30, 3.70),
             "VQF (paper, several datasets)": (2.9, float("nan"), float("nan"))}


#: Leave-one-out grids per filter: FilterOptions names → values (the factory value included).
LOO_GRIDS: dict[str, dict[str, tuple[float, ...]]] = {
    "mahony": {"kp_rollpitch": (0.005, 0.02), "kp_yaw": (0.3, 1.2)},
    "observer": {"observer_k_incl": (0.5, 1.0), "observer_k_head": (0.1, 0.2),
                 "observer_mag_norm_th": (0.03, 0.05), "observer_mag_dip_th_deg": (3.0, 5.0)},
    "vqf": {"vqf_tau_acc_s": (1.5, 3.0, 6.0), "vqf_tau_mag_s": (4.5, 9.0, 18.0)},
    "adaptive": {"adaptive_k_incl": (0.5, 1.0, 2.0), "adaptive_k_head": (0.1, 0.2),
                 "adaptive_mag_norm_th": (0.03, 0.05), "adaptive_mag_dip_th_deg": (3.0, 5.0)},
}


@dataclass
class Trial:
    name: str
    rate: float
    gyr: np.ndarray   # [N, 3] rad/s
    acc: np.ndarray   # [N, 3] m/s², specific force
    mag: np.ndarray   # [N, 3] µT
    opt_quat: np.ndarray  # [N, 4] body → ENU, NaN where missing
    movement: np.ndarray  # [N] bool


@dataclass
class Row:
    """RMSE in degrees of one filter on one trial at one rate."""

    trial: str
    filter: str
    rate: float
    total: float
    heading: float
    inclination: float
    seconds: float  # processing time


def find_data(data: str | Path | None = None) -> Path | None:
    """The BROAD folder (``data`` or the default beside the repository), None when absent."""
    path = Path(data) if data else DEFAULT_DATA
    return path if path.is_dir() and any(path.glob("*.hdf5")) else None


def load_trial(path: Path, max_s: float | None = None) -> Trial:
    import h5py

    with h5py.File(path, "r") as f:
        rate = float(f.attrs["sampling_rate"])
        n = len(f["imu_gyr"]) if max_s is None else min(len(f["imu_gyr"]), round(max_s * rate))
        get = lambda key: np.asarray(f[key][:n], dtype=np.float64)  # noqa: E731
        return Trial(path.stem, rate, get("imu_gyr"), get("imu_acc"), get("imu_mag"),
                     get("opt_quat"), np.asarray(f["movement"][:n], dtype=bool))


def resample(trial: Trial, rate: float) -> Trial:
    """The trial at ``rate`` Hz: IMU signals linearly interpolated, truth/movement nearest."""
    t_src = np.arange(len(trial.gyr)) / trial.rate
    t = np.arange(0.0, t_src[-1], 1.0 / rate)
    interp = lambda x: np.stack([np.interp(t, t_src, x[:, k]) for k in range(3)], 1)  # noqa: E731
    near = np.clip(np.rint(t * trial.rate).astype(int), 0, len(t_src) - 1)
    return Trial(trial.name, rate, interp(trial.gyr), interp(trial.acc), interp(trial.mag),
                 trial.opt_quat[near], trial.movement[near])


def _ned_to_enu(q_ned: np.ndarray) -> np.ndarray:
    # the ENU ↔ NED rotation is its own inverse (180°)
    return quat_mul(np.broadcast_to(Q_ENU_TO_NED, q_ned.shape), q_ned)


def run_filter(name: str, trial: Trial, settings: dict[str, float] | None = None,
               heading: str = "magnetic") -> np.ndarray:
    """Body → ENU quaternions ``[N, 4]`` of filter ``name`` on ``trial`` (factory settings,
    or these FilterOptions values), through its filter bank as the suite runs it: for the
    observer and the adaptive observer the disturbance flags (:mod:`bpms.filter.disturbance`)
    lower the heading trust to ``MAG_TRUST_FLAGGED`` while they are up. ``heading``:
    ``"relative"`` is the 6D mode."""
    dt = 1.0 / trial.rate
    options = FilterOptions(dt=dt, heading=heading, **(settings or {}))
    if name == MAHONY_TUNED:  # the published Mahony gains in the suite's units (not a default)
        options = FilterOptions(dt=dt, kp_rollpitch=0.74 / MAHONY_GRAVITY,
                                ki_rollpitch=0.0012 / MAHONY_GRAVITY, kp_yaw=0.74,
                                ki_yaw=0.0012, heading=heading)
    if name in ("mahony", MAHONY_TUNED):
        bank = MahonyBank(np.array([MAHONY_GRAVITY]), options)
        out = bank.process((-trial.acc * MAHONY_GRAVITY / 9.81)[:, None],
                           (trial.mag * 2.0)[:, None], trial.gyr[:, None])
        return _ned_to_enu(dcm_to_quaternion(out.R[:, 0]))
    if name not in ALGORITHMS:
        raise ValueError(name)
    # the suite's units: the gravity direction in counts of 1 g (here 9.81 per g), the
    # field ×2 (µT → about ±100), rad/s
    gravity = np.array([G_MS2])
    acc, mag, gyr = (-trial.acc)[:, None], (trial.mag * 2.0)[:, None], trial.gyr[:, None]
    bank = make_bank(gravity, dataclasses.replace(options, algorithm=name))
    terms = {}
    if isinstance(bank, ObserverBank):
        flags = DisturbanceTracker(gravity, dt).update(acc, mag, gyr)
        terms["mag_trust"] = np.where(flags.mag, MAG_TRUST_FLAGGED, 1.0)
    out = bank.process(acc, mag, gyr, **terms)
    return _ned_to_enu(dcm_to_quaternion(out.R[:, 0]))


def errors(q_imu: np.ndarray, q_opt: np.ndarray, movement: np.ndarray) -> tuple[float, ...]:
    """(total, heading, inclination) RMSE in degrees, the dataset's definitions."""
    q_imu = q_imu / np.linalg.norm(q_imu, axis=1, keepdims=True)
    q_opt = q_opt / np.linalg.norm(q_opt, axis=1, keepdims=True)
    inv = q_opt * np.array([1.0, -1.0, -1.0, -1.0])
    e = quat_mul(q_imu, inv)
    e = e / np.linalg.norm(e, axis=1, keepdims=True)
    w, z = e[:, 0], e[:, 3]
    with np.errstate(invalid="ignore", divide="ignore"):
        total = 2 * np.arccos(np.clip(np.abs(w), 0, 1))
        heading = 2 * np.arctan(np.abs(z / w))
        incl = 2 * np.arccos(np.clip(np.sqrt(w**2 + z**2), 0, 1))
    rmse = lambda x: float(np.degrees(np.sqrt(np.nanmean(x[movement] ** 2))))  # noqa: E731
    return rmse(total), rmse(heading), rmse(incl)


def evaluate(data: Path, trials: list[str] | None = None, max_s: float | None = None,
             filters: tuple[str, ...] = ALGORITHMS, rates: tuple[str, ...] = ("own", "50"),
             progress: bool = False) -> list[Row]:
    """Every filter on every (matching) trial at each rate."""
    rows = []
    paths = sorted(p for p in data.glob("*.hdf5")
                   if not trials or any(s in p.stem for s in trials))
    for path in paths:
        original = load_trial(path, max_s)
        for rate in rates:
            trial = original if rate == "own" else resample(original, SUIT_RATE_HZ)
            for name in filters:
                t0 = time.perf_counter()
                q = run_filter(name, trial)
                took = time.perf_counter() - t0
                rows.append(Row(trial.name, name, trial.rate,
                                *errors(q, trial.opt_quat, trial.movement), took))
                if progress:
                    print(f"  {trial.name} {name} {trial.rate:.1f} Hz: {took:.2f} s",
                          file=sys.stderr)
    return rows


@dataclass
class Fold:
    """One held-out trial of one filter: the settings chosen on the other trials and the
    held-out RMSE (degrees, total / heading / inclination)."""

    filter: str
    trial: str
    chosen: dict[str, float]
    total: float
    heading: float
    inclination: float


def grid(name: str) -> list[dict[str, float]]:
    """Every combination of :data:`LOO_GRIDS` ``[name]``."""
    g = LOO_GRIDS[name]
    return [dict(zip(g, values, strict=True)) for values in itertools.product(*g.values())]


def grid_errors(name: str, trials: list[Trial]) -> np.ndarray:
    """``[settings, trials, 3]`` RMSE of every grid setting on every trial."""
    return np.array([[errors(run_filter(name, t, s), t.opt_quat, t.movement) for t in trials]
                     for s in grid(name)])


def leave_one_out(name: str, trials: list[Trial], held_out: list[int] | None = None,
                  table: np.ndarray | None = None) -> list[Fold]:
    """Leave-one-trial-out folds of filter ``name`` (all trials, or only ``held_out``): the
    grid setting with the lowest mean total RMSE on the other trials, scored on the held-out
    one. ``table``: :func:`grid_errors` if already computed."""
    table = grid_errors(name, trials) if table is None else table
    settings = grid(name)
    folds = []
    for k in range(len(trials)) if held_out is None else held_out:
        others = [j for j in range(len(trials)) if j != k]
        best = int(np.argmin(table[:, others, 0].mean(axis=1)))
        folds.append(Fold(name, trials[k].name, settings[best], *table[best, k]))
    return folds


def load_50hz(data: Path, trials: list[str] | None = None,
              max_s: float | None = None) -> list[Trial]:
    paths = sorted(p for p in data.glob("*.hdf5")
                   if not trials or any(s in p.stem for s in trials))
    return [resample(load_trial(p, max_s), SUIT_RATE_HZ) for p in paths]


def print_loo(folds: list[Fold], rows: list[Row]) -> None:
    """Held-out RMSE per trial and filter at 50 Hz, beside the in-sample averages."""
    filters = list(dict.fromkeys(f.filter for f in folds))
    print("\nLeave-one-trial-out at 50 Hz (settings chosen on the other trials from "
          "LOO_GRIDS), held-out RMSE total / heading / inclination\n")
    print("| held-out trial | " + " | ".join(filters) + " |")
    print("|---|" + "---|" * len(filters))
    for trial in dict.fromkeys(f.trial for f in folds):
        cells = [f"{x.total:.2f} / {x.heading:.2f} / {x.inclination:.2f}"
                 for name in filters for x in folds if x.trial == trial and x.filter == name]
        print(f"| {trial} | " + " | ".join(cells) + " |")
    means = {name: np.mean([[x.total, x.heading, x.inclination] for x in folds
                            if x.filter == name], axis=0) for name in filters}
    print("| **held-out average** | " + " | ".join(
        f"**{m[0]:.2f}** / {m[1]:.2f} / {m[2]:.2f}" for m in means.values()) + " |")
    cells = []
    for name in filters:
        sel = [r for r in rows if r.filter == name and round(r.rate) == round(SUIT_RATE_HZ)]
        cells.append(f"**{np.mean([r.total for r in sel]):.2f}** / "
                     f"{np.mean([r.heading for r in sel]):.2f} / "
                     f"{np.mean([r.inclination for r in sel]):.2f}" if sel else "–")
    print("| in-sample (factory settings) | " + " | ".join(cells) + " |")
    print("\nLOO (held-out) against in-sample, total RMSE, 50 Hz:\n")
    print("| filter | leave-one-out | in-sample | gap |")
    print("|---|---|---|---|")
    for name in filters:
        sel = [r.total for r in rows if r.filter == name and round(r.rate) == round(SUIT_RATE_HZ)]
        if sel:
            ins = float(np.mean(sel))
            print(f"| {name} | {means[name][0]:.2f}° | {ins:.2f}° | {means[name][0] - ins:+.2f}° |")
    print("\nchosen settings per held-out trial:")
    for f in folds:
        print(f"- {f.filter} without {f.trial}: " + ", ".join(
            f"{k} = {v:g}" for k, v in f.chosen.items()))


def print_table(rows: list[Row]) -> None:
    filters = list(dict.fromkeys(r.filter for r in rows))
    rates = sorted({r.rate for r in rows}, reverse=True)
    print("RMSE in degrees over the movement phases, total / heading / inclination\n")
    print("| trial | rate | " + " | ".join(filters) + " |")
    print("|---|---|" + "---|" * len(filters))
    for trial in dict.fromkeys(r.trial for r in rows):
        for rate in rates:
            cells = []
            for f in filters:
                r = [x for x in rows if x.trial == trial and x.filter == f and x.rate == rate]
                cells.append(f"{r[0].total:.2f} / {r[0].heading:.2f} / {r[0].inclination:.2f}"
                             if r else "–")
            print(f"| {trial} | {rate:.1f} Hz | " + " | ".join(cells) + " |")
    for rate in rates:
        cells = []
        for f in filters:
            sel = [x for x in rows if x.filter == f and x.rate == rate]
            m = [np.mean([getattr(x, k) for x in sel]) for k in ("total", "heading",
                                                                   "inclination")]
            cells.append(f"**{m[0]:.2f}** / {m[1]:.2f} / {m[2]:.2f}")
        print(f"| **average** | {rate:.1f} Hz | " + " | ".join(cells) + " |")
    print("\nPublished averages over all 39 BROAD trials (total / heading / inclination):")
    for name, (a, b, c) in PUBLISHED.items():
        print(f"- {name}: {a:.2f} / {b:.2f} / {c:.2f}".replace("nan", "–"))
    took = {f: sum(x.seconds for x in rows if x.filter == f) for f in filters}
    print("\nprocessing time: " + ", ".join(f"{f} {s:.1f} s" for f, s in took.items()))


MAGNET_TRIALS = ("31_", "33_")


def print_magnet_heading(rows: list[Row]) -> None:
    """Heading RMSE on the magnet trials at 50 Hz, every filter beside VQF (factory)."""
    sel = [r for r in rows if r.trial.startswith(MAGNET_TRIALS)
           and round(r.rate) == round(SUIT_RATE_HZ)]
    if not sel:
        return
    filters = list(dict.fromkeys(r.filter for r in sel))
    print("\nMagnet trials, heading RMSE at 50 Hz (factory settings)\n")
    print("| trial | " + " | ".join(filters) + " |")
    print("|---|" + "---|" * len(filters))
    for trial in dict.fromkeys(r.trial for r in sel):
        print(f"| {trial} | " + " | ".join(
            f"{r.heading:.2f}°" for f in filters for r in sel
            if r.trial == trial and r.filter == f) + " |")


def heading_about_vertical(q_imu: np.ndarray, q_opt: np.ndarray) -> np.ndarray:
    """``[N]`` rad, signed: the vertical part of ``q_imu ⊗ q_opt⁻¹`` (NaN without truth)."""
    q_imu = q_imu / np.linalg.norm(q_imu, axis=1, keepdims=True)
    q_opt = q_opt / np.linalg.norm(q_opt, axis=1, keepdims=True)
    e = quat_mul(q_imu, q_opt * np.array([1.0, -1.0, -1.0, -1.0]))
    return 2.0 * np.arctan2(e[:, 3], e[:, 0])


def relative_heading_rmse(q_imu: np.ndarray, q_opt: np.ndarray, rate: float,
                          align_s: float = 5.0) -> float:
    """Heading RMSE (°) over every frame with optical truth after removing the circular mean
    of the heading error over the first ``align_s`` s with truth (heading relative to the
    start)."""
    h = heading_about_vertical(q_imu, q_opt)
    ok = np.flatnonzero(np.isfinite(h))
    h0 = np.angle(np.exp(1j * h[ok[:round(align_s * rate)]]).mean())
    d = np.angle(np.exp(1j * (h[ok] - h0)))
    return float(np.degrees(np.sqrt(np.mean(d**2))))


def run_6d(name: str, trial: Trial) -> np.ndarray:
    """Body → ENU quaternions of filter ``name`` in the 6D mode (no magnetometer; for VQF its
    own ``quat6D``)."""
    return run_filter(name, trial, heading="relative")


def print_6d(trials: list[Trial]) -> None:
    print("\n6D mode (no magnetometer), heading RMSE per whole trial relative to the start, "
          "50 Hz\n")
    print("| trial | length | adaptive 6D | vqf 6D |")
    print("|---|---|---|---|")
    total = {"adaptive": [], "vqf": []}
    for tr in trials:
        cells = []
        for name in total:
            e = relative_heading_rmse(run_6d(name, tr), tr.opt_quat, tr.rate)
            total[name].append(e)
            cells.append(f"{e:.2f}°")
        print(f"| {tr.name} | {len(tr.gyr) / tr.rate:.0f} s | " + " | ".join(cells) + " |")
    print("| **average** | | " + " | ".join(f"**{np.mean(v):.2f}°**" for v in total.values())
          + " |")


def print_simulated(seed: int = 0) -> None:
    """The simulated suit (``simulate(seed)``, 18 IMUs at 50 Hz, factory options but the
    filter choice): RMS inclination / heading / joint-angle errors in degrees from t = 1 s,
    undisturbed, magnetically disturbed (``mag_disturbance=True``) and the walk phase."""
    sys.path.insert(0, str(REPO / "bench"))
    from accuracy import accuracy

    from bpms.filter.processor import BodyPoseProcessor
    from bpms.firmware.sim.session import simulate
    from bpms.io.options import Options

    recs = {"undisturbed": simulate(seed=seed), "magnet": simulate(seed=seed,
                                                                   mag_disturbance=True)}
    rms = lambda x: float(np.sqrt(np.mean(x**2)))  # noqa: E731
    print(f"Simulated suit, seed {seed}: RMS errors in degrees from t = 1 s "
          "(inclination / heading / joint angles)\n")
    print("| filter | undisturbed | magnet | walk 59.2–69.1 s | magnet 17–25 s |")
    print("|---|---|---|---|---|")
    for name in ALGORITHMS:
        cells = []
        acc = {}
        for case, rec in recs.items():
            options = Options()
            options.filter.algorithm = name
            result = BodyPoseProcessor(rec.calibration, options).process(rec.raw, rec.errors)
            acc[case] = accuracy(rec, result, 1.0)
        for case, lo, hi in (("undisturbed", 0, 1e9), ("magnet", 0, 1e9),
                             ("undisturbed", 59.2, 69.1), ("magnet", 17.0, 25.0)):
            a = acc[case]
            k = (a.t >= lo) & (a.t < hi)
            cells.append(f"{rms(a.incl_all[k]):.2f} / {rms(a.head_all[k]):.2f} / "
                         f"{rms(a.joint_all[k]):.2f}")
        print(f"| {name} | " + " | ".join(cells) + " |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", help=f"BROAD folder (default {DEFAULT_DATA})")
    parser.add_argument("--trials", nargs="*", help="only trials whose name contains these")
    parser.add_argument("--max-s", type=float, help="only the first S seconds of each trial")
    parser.add_argument("--extra", action="store_true",
                        help=f"add {MAHONY_TUNED}: the original filter with the published "
                             "Mahony gains (a reference, not a selectable default)")
    parser.add_argument("--no-loo", dest="loo", action="store_false",
                        help="skip the leave-one-trial-out figures at 50 Hz (LOO_GRIDS per "
                             "filter; printed by default when 3 or more trials are chosen)")
    parser.add_argument("--sim", action="store_true",
                        help="also the simulated suit (undisturbed, magnet, walk) per filter")
    args = parser.parse_args(argv)
    data = find_data(args.data)
    if data is None:
        print(f"broad.py: no BROAD data in {args.data or DEFAULT_DATA}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    filters = (*ALGORITHMS, MAHONY_TUNED) if args.extra else ALGORITHMS
    rows = evaluate(data, args.trials, args.max_s, filters=filters, progress=True)
    print_table(rows)
    print_magnet_heading(rows)
    trials = load_50hz(data, args.trials, args.max_s)
    if args.loo and len(trials) >= 3:
        folds = [f for name in ALGORITHMS for f in leave_one_out(name, trials)]
        print_loo(folds, rows)
    print_6d(trials)
    if args.sim:
        print()
        print_simulated()
    print(f"total run time {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
