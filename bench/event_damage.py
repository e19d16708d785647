"""Random bit flips in a raw recording: what they cost (issue 43 item 1).

    python bench/event_damage.py RAW_FILE [--trials 200] [--flips 1] [--seed 0] [--events]

Each trial flips ``--flips`` random bits in the records part of a copy of RAW_FILE (the
header is left alone; ``--events``: in its event records only), filters the copy through the
one door (``process_file``) and compares it with the intact file's numbers: the frame count,
the frames whose joint angles are not all finite beyond the intact file's, and the frames
whose joint angles differ at all. Prints the totals.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from bpms.filter.door import process_file
from bpms.io.rawfile import read_header


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("raw")
    p.add_argument("--trials", type=int, default=200)
    p.add_argument("--flips", type=int, default=1)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--events", action="store_true", help="flip bits in event records only")
    args = p.parse_args(argv)
    src = Path(args.raw)
    data = src.read_bytes()
    _, offset = read_header(src)
    intact = process_file(src)
    want = intact.joint_angles
    has = np.isfinite(want).all(axis=1)
    rng = np.random.default_rng(args.seed)
    places = np.arange(offset, len(data))
    if args.events:  # every byte of every event record (its JSON starts {"kind":)
        spans, at = [], 0
        while (k := data.find(b'{"kind":"', at)) >= 0:
            length = int.from_bytes(data[k - 4:k], "little")
            spans.append(np.arange(k - 14, k + length + 6))
            at = k + 1
        places = np.concatenate(spans)
    shifted = lost_angles = hit_events = changed = 0
    worst = 0
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "Raw_trial_1.bpmsraw"
        for _ in range(args.trials):
            copy = bytearray(data)
            for at in rng.choice(places, args.flips):
                copy[int(at)] ^= 1 << int(rng.integers(0, 8))
            path.write_bytes(bytes(copy))
            got = process_file(path)
            if any("event record" in p for p in got.problems):
                hit_events += 1
            if len(got) != len(intact):
                shifted += 1
                continue
            gone = int((has & ~np.isfinite(got.joint_angles).all(axis=1)).sum())
            lost_angles += gone > 0
            worst = max(worst, gone)
            changed += not np.array_equal(got.joint_angles, want, equal_nan=True)
    print(f"{src.name}: {args.trials} trials of {args.flips} flipped bit(s); "
          f"{hit_events} hit an event record")
    print(f"  frame count changed: {shifted}")
    print(f"  trials with frames losing their angles: {lost_angles} (at most {worst} frames)")
    print(f"  trials whose joint angles differ from the intact file's: {changed}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
