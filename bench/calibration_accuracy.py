"""Joint-angle accuracy of the pose calibrations against the simulated suit's truth
(docs/pose-calibration.md, "What calibration is worth").

For each calibration posture (neutral, suit), mounting error (3, 10, 15° rms per axis), subject
height and seed, the simulated suit records its functional movements and the first part of the
standard trial; the recording is filtered with each pose calibration (``reset-zero``,
``posture`` declaring the posture the simulator held, ``functional``) through the one door, and
every joint angle is compared with the simulator's own (its degrees of freedom), from the
frame after the calibration to the end. Joint positions are compared relative to the pelvis,
with the subject's measured segment lengths given to the product.

    python bench/calibration_accuracy.py                 # 5 seeds, heights 1.60 and 1.90 m
    python bench/calibration_accuracy.py --seeds 2 --quick   # a smaller run

Prints Markdown tables: RMSE per configuration (overall and worst joint), per joint for the
goal's configuration (10°, suit posture), and joint positions.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from bpms.filter.body_model import POINT_NAMES
from bpms.filter.door import open_for_processing
from bpms.firmware.sim.body import SubjectDimensions
from bpms.firmware.sim.session import simulate
from bpms.io.options import BodyOptions, Options

METHODS = ("reset-zero", "posture", "functional")
POSTURES = ("neutral", "suit")
DURATION_S = 60.0  # the functional movements (≈ 30 s), then the trial's arm and trunk moves
START_S = 2.0  # after the still window's capture


def run_one(path: Path, rec, method: str, posture: str, dims: SubjectDimensions
            ) -> tuple[np.ndarray, np.ndarray]:
    """(per-joint RMSE ° [28], per-point position RMSE m [21]) of one method on one
    recording."""
    options = Options()
    options.body = BodyOptions(**dims.lengths(), height=dims.height)
    opened = open_for_processing(path, options=options)
    opened.use_pose_calibration(method, posture if method == "posture" else None)
    res = opened.result()
    k = rec.t >= START_S
    err = np.angle(np.exp(1j * (res.joint_angles[k] - rec.truth.joint_angles[k])))
    rmse = np.degrees(np.sqrt(np.nanmean(err ** 2, axis=0)))
    pelvis = POINT_NAMES.index("pelvis")
    order = [rec.truth.point_names.index(n) for n in POINT_NAMES]
    mine = res.joint_positions[k] - res.joint_positions[k][:, pelvis:pelvis + 1]
    true = rec.truth.joint_positions[k][:, order]
    true = true - true[:, pelvis:pelvis + 1]
    pos = np.sqrt(np.nanmean(np.sum((mine - true) ** 2, axis=-1), axis=0))
    return rmse, pos


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--heights", type=float, nargs="+", default=[1.60, 1.90])
    p.add_argument("--errors", type=float, nargs="+", default=[3.0, 10.0, 15.0])
    p.add_argument("--quick", action="store_true", help="only the 10° mounting error")
    args = p.parse_args(argv)
    errors = [10.0] if args.quick else args.errors
    names = None
    table: dict[tuple, list[np.ndarray]] = {}
    positions: dict[tuple, list[np.ndarray]] = {}
    t0 = time.perf_counter()
    # the floor: a perfect neutral pose and no mounting error, Reset Zero (the filter's own
    # error, which no calibration removes)
    configs = [("neutral", 0.0, ("reset-zero",))]
    configs += [(posture, error, METHODS) for posture in POSTURES for error in errors]
    with tempfile.TemporaryDirectory() as tmp:
        for posture, error, methods in configs:
            for height in args.heights:
                dims = SubjectDimensions.of_height(height)
                for seed in range(args.seeds):
                    rec = simulate(seed=seed, posture=posture, functional=True,
                                   mounting_error_deg=error, subject=dims,
                                   duration_s=DURATION_S)
                    names = rec.truth.joint_names
                    path = rec.save_raw(Path(tmp) / f"{posture}-{error}-{height}-{seed}.raw")
                    for method in methods:
                        rmse, pos = run_one(path, rec, method, posture, dims)
                        table.setdefault((method, posture, error), []).append(rmse)
                        positions.setdefault((method, posture, error), []).append(pos)
    elapsed = time.perf_counter() - t0
    n = args.seeds * len(args.heights)
    print(f"# Pose calibration accuracy ({n} recordings per row: seeds 0..{args.seeds - 1}, "
          f"heights {', '.join(f'{h:g}' for h in args.heights)} m; {elapsed:.0f} s)\n")
    print("| method | posture | mounting error (° rms) | joint angles RMSE (°) | worst joint "
          "| its RMSE (°) | joint positions RMSE (cm) |")
    print("|---|---|---|---|---|---|---|")
    for (method, posture, error), runs in table.items():
        per_joint = np.sqrt(np.mean(np.square(runs), axis=0))
        worst = int(np.argmax(per_joint))
        overall = float(np.sqrt(np.mean(per_joint ** 2)))
        pos = 100 * float(np.sqrt(np.mean(np.square(positions[(method, posture, error)]))))
        if error == 0.0:
            method = f"{method} (floor)"
        print(f"| {method} | {posture} | {error:g} | {overall:.2f} | {names[worst]} | "
              f"{per_joint[worst]:.2f} | {pos:.2f} |")
    goal = [k for k in table if k[1] == "suit" and k[2] == 10.0]
    if goal:
        print("\n## Per joint, suit posture, 10° mounting error (RMSE, °)\n")
        print("| joint | " + " | ".join(k[0] for k in goal) + " |")
        print("|---|" + "---|" * len(goal))
        cols = [np.sqrt(np.mean(np.square(table[k]), axis=0)) for k in goal]
        for j, name in enumerate(names):
            print(f"| {name} | " + " | ".join(f"{c[j]:.2f}" for c in cols) + " |")
        print("\n## Joint positions relative to the pelvis, suit posture, 10° (RMSE, cm)\n")
        floor = ("reset-zero", "neutral", 0.0)
        keys = [floor, *goal]
        print("| point | " + " | ".join("floor (neutral, 0°, reset-zero)" if k == floor
                                        else k[0] for k in keys) + " |")
        print("|---|" + "---|" * len(keys))
        cols = [100 * np.sqrt(np.mean(np.square(positions[k]), axis=0)) for k in keys]
        for j, name in enumerate(POINT_NAMES[1:], 1):
            print(f"| {name} | " + " | ".join(f"{c[j]:.2f}" for c in cols) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
