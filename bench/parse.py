"""Benchmark: streaming parser and vectorised decoder on a 30-minute session (90,000 frames).

Run: .venv/bin/python bench/parse.py [--frames N]
Prints frames/s for each path (one core; best of a few repetitions).
Aims (issue 2): decoder ≥ 1,000,000 frames/s, streaming parser ≥ 100,000 frames/s.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bpms.io.frames import FRAME_SIZE, decode_frames, encode_frames
from bpms.io.parser import FrameParser


def best_of(repeats: int, fn) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=90_000)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    n = args.frames
    rng = np.random.default_rng(0)
    raw = rng.integers(-600, 600, (n, 18, 9))
    errors = rng.random((n, 18, 3)) < 0.001
    stream = encode_frames(raw, errors)
    print(f"{n} frames, {len(stream) / 1e6:.1f} MB")

    t = best_of(args.repeats, lambda: decode_frames(stream))
    print(f"vectorised decoder        : {n / t:12,.0f} frames/s  ({t * 1e3:.1f} ms)")

    for label, chunk in (("Bluetooth-like 1 KiB", 1024), ("64 KiB", 65536), ("one frame", 340)):
        def run(chunk: int = chunk) -> None:
            parser = FrameParser()
            for i in range(0, len(stream), chunk):
                parser.feed(stream[i:i + chunk])
            assert parser.stats.frames == n
        t = best_of(args.repeats, run)
        print(f"streaming parser {label:>20}: {n / t:12,.0f} frames/s  ({t * 1e3:.0f} ms)")

    corrupted_array = np.frombuffer(stream, dtype=np.uint8).copy()
    hits = rng.integers(0, len(corrupted_array), n // 100)
    corrupted_array[hits] ^= 0xFF  # ~1 % of frames damaged
    corrupted = corrupted_array.tobytes()

    def run_corrupted() -> None:
        parser = FrameParser()
        for i in range(0, len(corrupted), 1024):
            parser.feed(corrupted[i:i + 1024])
        parser.flush()

    t = best_of(args.repeats, run_corrupted)
    print(f"streaming parser, 1 % of frames corrupted: {n / t:12,.0f} frames/s")
    assert FRAME_SIZE == 340


if __name__ == "__main__":
    main()
