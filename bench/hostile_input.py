"""Cost of hostile input (run on demand): ``python bench/hostile_input.py``.

- Legacy pickle reader on crafted files (every few bytes a record start whose string never
  ends) of 12 KB … 800 KB, beside an intact legacy file of the same size (reference): the
  time must grow linearly with the size.
- UDP receiver: CPU per datagram with a sequence jump of 40,000 at every datagram, beside
  in-order datagrams (reference).
"""

from __future__ import annotations

import pickle
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import contextlib

from bpms.io.legacy_raw import read_legacy_raw
from bpms.io.rawfile import RawFileError
from bpms.io.udp.sequence import SequenceTracker

FRAME = b"$#" + bytes(336) + b"#$"


def timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def read(path: Path) -> None:
    with contextlib.suppress(RawFileError):
        read_legacy_raw(path)


def legacy() -> None:
    good = pickle.dumps([1.0, FRAME], protocol=0)
    print("legacy pickle reader: size, crafted s, intact s (reference), crafted s per MB")
    with tempfile.TemporaryDirectory() as tmp:
        for kb in (12, 48, 200, 800):
            crafted = Path(tmp) / "crafted.raw"
            crafted.write_bytes(good + b"(lS" * (kb * 1024 // 3))
            intact = Path(tmp) / "intact.raw"
            intact.write_bytes(good * max(1, kb * 1024 // len(good)))
            tc, ti = timed(lambda: read(crafted)), timed(lambda: read(intact))  # noqa: B023
            print(f"  {kb:5d} KB  {tc:7.3f} s  {ti:7.3f} s  {tc / (kb / 1024):7.2f} s/MB")


def udp() -> None:
    n = 20_000
    for label, step in (("in order (reference)", 1), ("jump of 40,000", 40_000)):
        t = SequenceTracker()
        seq = 0
        start = time.perf_counter()
        for _ in range(n):
            t.observe(1, seq)
            seq = (seq + step) % (1 << 32)
        per = (time.perf_counter() - start) / n
        print(f"UDP sequence tracking, {label:22}: {per * 1e6:6.2f} µs per datagram")


if __name__ == "__main__":
    import logging

    logging.basicConfig(level=logging.ERROR)
    legacy()
    udp()
