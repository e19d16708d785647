"""Throughput of the UDP codec and loopback forwarding, and of the legacy raw-file reader.

Run: ``.venv/bin/python bench/udp.py [--frames 50000]``. Prints one line per figure. The suit
makes 50 frames/s, so every rate here is compared with that.
"""

from __future__ import annotations

import argparse
import pickle
import tempfile
import time
from pathlib import Path

import numpy as np

from bpms.io.frames import encode_frame
from bpms.io.legacy_raw import read_legacy_raw
from bpms.io.udp.codec import decode_datagram, encode_pose, encode_raw_frame
from bpms.io.udp.receiver import UdpSource
from bpms.io.udp.sender import UdpForwarder


def rate(n: int, seconds: float, what: str) -> None:
    print(f"{what:<46} {n / seconds:>12,.0f} /s  ({seconds / n * 1e6:7.1f} µs each, "
          f"{n / seconds / 50:,.0f}× real time)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=50_000)
    n = ap.parse_args().frames
    rng = np.random.default_rng(0)
    frames = [encode_frame(r) for r in rng.integers(-2000, 2000, (1000, 18, 9))]
    q = rng.normal(size=(18, 4))
    angles = rng.normal(size=28)

    t = time.perf_counter()
    dgs = [encode_raw_frame(frames[i % 1000], session=1, seq=i, suit_time=i * 0.02,
                            send_time=0.0) for i in range(n)]
    rate(n, time.perf_counter() - t, "encode RAW_FRAME")
    t = time.perf_counter()
    for d in dgs:
        decode_datagram(d)
    rate(n, time.perf_counter() - t, "decode RAW_FRAME")
    pose = encode_pose(q, angles, session=1, seq=0, suit_time=0.0, send_time=0.0)
    t = time.perf_counter()
    for _ in range(n // 5):
        decode_datagram(pose)
    rate(n // 5, time.perf_counter() - t, "decode POSE")

    with UdpSource("127.0.0.1:0") as src, UdpForwarder([f"127.0.0.1:{src.address[1]}"]) as fw:
        t = time.perf_counter()
        got = 0
        for start in range(0, n, 200):
            for i in range(start, min(n, start + 200)):
                fw.send_frame(frames[i % 1000])
            while src.stats.datagrams < min(n, start + 200):
                got += src.read(timeout=0.5) is not None
        rate(n, time.perf_counter() - t, "loopback forward + receive (one thread)")
        s = src.stats
        print(f"  received {s.received:,}, lost {s.lost}, send errors {fw.stats.errors}")

    with tempfile.TemporaryDirectory() as tmp:
        for protocol in (0, 2):
            path = Path(tmp) / f"legacy{protocol}.txt"
            with path.open("wb") as f:
                for i in range(n):
                    pickle.dump([1e9 + i * 0.02, frames[i % 1000].decode("latin1")], f,
                                protocol=protocol)
            t = time.perf_counter()
            rec = read_legacy_raw(path)
            rate(len(rec), time.perf_counter() - t,
                 f"legacy raw read, protocol {protocol} ({path.stat().st_size / n:.0f} B/rec)")


if __name__ == "__main__":
    main()
