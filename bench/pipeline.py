"""Benchmark: the headless live pipeline with raw + filtered logging and UDP forwarding on.

1. Latency at 50 Hz: a recording replayed in real time; frame-in (the source hands the frame
   over) to pose-out (the PoseSample is published), p50 / p99 / max.
2. Sustained rate: a 30-minute recording (90,000 frames) replayed as fast as possible through
   the whole pipeline; frames/s from the first frame in to the last pose out.

Run: .venv/bin/python bench/pipeline.py [--seconds 20] [--frames 90000]
Aims (issue 4): p99 ≤ 2 ms, sustained ≥ 5,000 frames/s (100× real time).
"""

from __future__ import annotations

import argparse
import socket
import tempfile
import time
from pathlib import Path

import numpy as np

from bpms.firmware.sim.session import simulate
from bpms.io.rawfile import new_header, read_raw, write_raw
from bpms.io.replay import ReplaySource
from bpms.pipeline.session import LiveSession


def make_recording(folder: Path, frames: int) -> Path:
    rec = simulate(seed=1)
    reps = -(-frames // len(rec.t))
    data = (rec.frames * reps)[: frames * 340]
    path = folder / f"bench_{frames}.bpmsraw"
    write_raw(path, 1.7e9 + np.arange(frames) * 0.02, data, new_header())
    return path


def udp_sink() -> socket.socket:
    """A bound UDP port nobody reads (as when the receiver is another machine: its CPU is
    not ours); the kernel drops what overflows its buffer."""
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    return sink


def run(path: Path, folder: Path, speed: float | None, expected: int) -> tuple[float, list]:
    sink = udp_sink()
    session = LiveSession(ReplaySource(read_raw(path), speed=speed), recording_dir=folder)
    sub = session.subscribe(maxlen=expected)
    session.start_logging(raw=True, filtered=True, name="bench")
    session.start_forwarding([f"127.0.0.1:{sink.getsockname()[1]}"])
    t0 = time.perf_counter()
    session.start()
    while session.status().processed < expected:
        time.sleep(0.01)
    elapsed = time.perf_counter() - t0
    status = session.status()
    session.stop()
    sink.close()
    samples = sub.drain()
    print(f"  forwarded {status.forwarded} datagrams, {status.forward_errors} send errors, "
          f"{status.dropped} deliveries dropped")
    return elapsed, [s.latency_s for s in samples]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0, help="real-time latency run, s")
    ap.add_argument("--frames", type=int, default=90_000, help="frames in the sustained run")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        n_live = int(args.seconds * 50)
        live = make_recording(folder, n_live)
        print(f"latency at 50 Hz, {n_live} frames, raw + filtered logging + UDP forwarding:")
        _, lat = run(live, folder, 1.0, n_live)
        lat_ms = np.array(lat[50:]) * 1e3  # skip the first second (JIT warm-up)
        print(f"  frame-in → pose-out: p50 {np.percentile(lat_ms, 50):.2f} ms, "
              f"p99 {np.percentile(lat_ms, 99):.2f} ms, max {lat_ms.max():.2f} ms")
        big = make_recording(folder, args.frames)
        print(f"sustained, {args.frames} frames as fast as possible:")
        elapsed, _ = run(big, folder, None, args.frames)
        print(f"  {args.frames / elapsed:,.0f} frames/s ({args.frames / elapsed / 50:.0f}× real "
              f"time), {elapsed:.1f} s for a {args.frames / 50 / 60:.0f}-minute session")


if __name__ == "__main__":
    main()
