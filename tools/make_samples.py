"""Make the sample recordings in docs/samples/ (docs/samples/README.md describes them).

They are SIMULATED: made by BPMS Suite's simulated suit (bpms.firmware.sim) from a scripted
motion, with its sensor noise and mounting errors, not recorded on a person. Each one says so
in its file name (``Raw_simulated_...``) and in its header's notes. The same command makes the
same bytes (fixed seeds and start times).

    .venv/bin/python tools/make_samples.py            # writes docs/samples/*.bpmsraw
    .venv/bin/python tools/make_samples.py --check    # exit 1 when a sample would change
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDER = ROOT / "docs" / "samples"
#: 2026-01-05T09:00:00Z: the samples' (made-up) start time, the same on every run.
START_TIME = 1767603600.0


@dataclass(frozen=True)
class Sample:
    name: str
    seed: int
    what: str

    @property
    def file_name(self) -> str:
        return f"Raw_simulated_{self.name}.bpmsraw"


def _script(name: str):
    from bpms.firmware.sim.motion import Move, Still, Walk

    if name == "arm_raise":
        return [Still("still (start)", 2.0),
                Move("right arm forward raise", 1.5, {"sh_r_flex": 60}, hold=0.5),
                Move("right arm down", 1.5, hold=0.3),
                Move("elbow flexion", 1.2, {"elbow_r": 100, "elbow_l": 100}, hold=0.3),
                Move("elbows extended", 1.2, hold=0.2),
                Still("still (end)", 1.0)]
    if name == "walk":
        return [Still("still (start)", 2.0), Walk(steps=6), Still("still (end)", 1.5)]
    raise ValueError(name)


SAMPLES = (
    Sample("arm_raise", 11, "standing still 2 s, the right arm raised forward to 60° and "
                            "lowered, both elbows bent to 100° and extended, still 1 s"),
    Sample("walk", 12, "standing still 2 s, six steps of 0.9 s walking north-east (the "
                       "subject faces 30° east of magnetic north), still 1.5 s"),
)


def notes(sample: Sample) -> str:
    """The header notes: what the sample is, and that it is simulated."""
    return (f"SIMULATED recording (not a person): BPMS Suite's simulated suit, seed "
            f"{sample.seed}: {sample.what}. Made by tools/make_samples.py.")


def write(sample: Sample, folder: Path) -> Path:
    from bpms.firmware.sim.session import simulate
    from bpms.io.rawfile import new_header, write_raw

    rec = simulate(seed=sample.seed, script=_script(sample.name))
    path = folder / sample.file_name
    path.unlink(missing_ok=True)
    header = new_header(calibration=rec.calibration.values, notes=notes(sample),
                        source="simulated suit (bpms.firmware.sim)",
                        extra={"accel_range_g": float(rec.model.accel_range_g),
                               "start_time": START_TIME,
                               "start_time_utc": "2026-01-05T09:00:00Z", "simulated": True})
    write_raw(path, START_TIME + rec.t, rec.frames, header)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--check", action="store_true",
                        help="compare with docs/samples instead of writing")
    args = parser.parse_args(argv)
    if args.check:
        with tempfile.TemporaryDirectory() as tmp:
            changed = [s.file_name for s in SAMPLES
                       if write(s, Path(tmp)).read_bytes() != (FOLDER / s.file_name).read_bytes()]
        for name in changed:
            print(f"docs/samples/{name} would change", file=sys.stderr)
        return 1 if changed else 0
    FOLDER.mkdir(parents=True, exist_ok=True)
    for sample in SAMPLES:
        path = write(sample, FOLDER)
        print(f"{path.relative_to(ROOT)}: {path.stat().st_size / 1e3:.0f} kB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
