"""Make docs/samples/optical_simulated_arm_raise.csv: the optical (Vicon Nexus CSV) export of the
simulation behind docs/samples/Raw_simulated_arm_raise.bpmsraw (tools/make_samples.py, seed 11),
for the worked example of docs/compare.md: the simulated suit's true orientations of six
segments seen through known IMU-to-cluster and world rotations, 0.73 s later on the optical
clock, at 100 Hz, with 0.2° of orientation noise and one 0.3 s occlusion per body
(:func:`bpms.analysis.compare_synth.optical_from_truth`, seed 11).

Run from the repository root: ``python tools/make_compare_sample.py [--check]``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "samples" / "optical_simulated_arm_raise.csv"
#: Plug-in Gait names of the segments the arm-raise sample moves (IMU index → body).
BODIES = {6: "Pelvis", 8: "Thorax", 4: "RHumerus", 5: "RRadius", 10: "LHumerus", 11: "LRadius"}
SEED = 11


def write(path: Path):
    sys.path.insert(0, str(ROOT / "tools"))
    from make_samples import SAMPLES, _script

    from bpms.analysis.compare_synth import optical_from_truth
    from bpms.firmware.sim.session import simulate

    sample = next(s for s in SAMPLES if s.name == "arm_raise")
    rec = simulate(seed=sample.seed, script=_script(sample.name))
    return optical_from_truth(path, rec.t, rec.truth.R, rec.truth.imu_position, BODIES,
                              seed=SEED, gaps=1)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="compare with the committed file instead of writing")
    args = parser.parse_args(argv)
    if args.check:
        with tempfile.TemporaryDirectory() as tmp:
            new = write(Path(tmp) / OUT.name).path.read_bytes()
        if new != OUT.read_bytes():
            print(f"{OUT} would change", file=sys.stderr)
            return 1
        return 0
    out = write(OUT)
    print(f"{out.path}: offset {out.offset_s:+.3f} s, {sum(out.gaps.values())} occluded "
          "samples", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
