"""Live latency at 50 Hz over a pseudo-terminal: the pipeline beside a minimal relay.

Run: ``.venv/bin/python bench/live.py [--minutes 0.5] [--untuned]`` (Linux/macOS: a pty).

The simulated suit streams in real time (50 Hz) on a pty, read by the project's serial source
(:class:`bpms.pipeline.sources.SuitFrameSource`). Measured one after the other in this run:

- **relay**: the same source read by one thread and handed to a second thread through a queue,
  nothing else (the floor any live pipeline pays on this machine);
- **pipeline**: :class:`bpms.pipeline.session.LiveSession` with raw and filtered recording on
  (warm-up and frozen heap, :mod:`bpms.pipeline.steady`);
- with ``--untuned``, also the pipeline with warm-up and gc freezing switched off.

Printed for each: frame → pose latency (host took the frame in → sample ready) p50, p99,
p99.9 and max in ms, the worst of the first 10 frames, the longest garbage-collection pause
(``gc.callbacks``, from the first frame on) and the number of full (generation 2) collections,
and CPU time per frame (ms, whole process).
Aim (issue 18.4): p99.9 ≤ 5 ms and no gc pause over 5 ms in a 10-minute run. Figures only.
"""

from __future__ import annotations

import argparse
import gc
import os
import queue
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bpms.firmware.sim.arbiter import Arbiter, MotionSource
from bpms.firmware.sim.server import PtyServer
from bpms.io.options import SerialOptions
from bpms.pipeline.sources import SuitFrameSource


class GcWatch:
    """Garbage collections (``gc.callbacks``): (start, ``time.perf_counter()`` s; duration,
    s; generation). ``since``: only collections from then on count (the first frame)."""

    def __init__(self) -> None:
        self.pauses: list[tuple[float, float, int]] = []
        self.since = 0.0
        self._t0 = 0.0

    def __call__(self, phase: str, info: dict) -> None:
        if phase == "start":
            self._t0 = time.perf_counter()
        else:
            self.pauses.append((self._t0, time.perf_counter() - self._t0, info["generation"]))

    def counted(self) -> list[tuple[float, int]]:
        return [(d, g) for t, d, g in self.pauses if t >= self.since]

    def __enter__(self) -> GcWatch:
        gc.callbacks.append(self)
        return self

    def __exit__(self, *exc: object) -> None:
        gc.callbacks.remove(self)


def _suit() -> PtyServer:
    return PtyServer(Arbiter(MotionSource.simulated(seed=1), realtime=True)).start()


def relay(seconds: float) -> tuple[np.ndarray, GcWatch, float]:
    """(latencies s, gc watch, CPU s per frame) of the minimal relay."""
    server = _suit()
    source = SuitFrameSource(server.path, SerialOptions())
    source.connect()
    handoff: queue.Queue = queue.Queue()
    latencies: list[float] = []
    stop = threading.Event()

    def reader() -> None:
        while not stop.is_set():
            for event in source.read(0.1):
                handoff.put(event)

    def taker() -> None:
        while not stop.is_set():
            try:
                event = handoff.get(timeout=0.1)
            except queue.Empty:
                continue
            if not latencies:
                watch.since = event.arrival
            latencies.append(time.perf_counter() - event.arrival)

    threads = [threading.Thread(target=f, daemon=True) for f in (reader, taker)]
    cpu0 = time.process_time()
    watch = GcWatch()
    with watch:
        for t in threads:
            t.start()
        time.sleep(seconds)
        stop.set()
        for t in threads:
            t.join(2)
    cpu = time.process_time() - cpu0
    source.close()
    server.stop()
    return np.array(latencies), watch, cpu / max(len(latencies), 1)


def pipeline(seconds: float, tuned: bool = True) -> tuple[np.ndarray, GcWatch, float]:
    """(latencies s, gc watch, CPU s per frame) of the LiveSession with recording on."""
    import bpms.pipeline.session as session_module
    from bpms.pipeline.session import LiveSession

    original = session_module.prepare_live_path
    if not tuned:
        session_module.prepare_live_path = lambda processor: 0.0
    server = _suit()
    try:
        with tempfile.TemporaryDirectory(prefix="bpms-live-") as tmp:
            session = LiveSession(SuitFrameSource(server.path, SerialOptions()),
                                  recording_dir=tmp)
            sub = session.subscribe(maxlen=200_000)
            session.source.connect()
            session.start_logging(raw=True, filtered=True, name="bench")
            cpu0 = time.process_time()
            with GcWatch() as watch:
                session.start()
                time.sleep(seconds)
                session.stop()
            cpu = time.process_time() - cpu0
            samples = sub.drain()
            if samples:  # the warm-up's collection happens before the first frame
                watch.since = time.perf_counter() - (time.time() - samples[0].host_time)
    finally:
        session_module.prepare_live_path = original
        server.stop()
    lat = np.array([s.latency_s for s in samples])
    return lat, watch, cpu / max(len(lat), 1)


def report(name: str, lat: np.ndarray, watch: GcWatch, cpu: float) -> None:
    ms = lat * 1e3
    pauses = watch.counted()
    longest = max((p for p, _ in pauses), default=0.0) * 1e3
    full = sum(1 for _, g in pauses if g == 2)
    if not len(ms):
        print(f"{name:<18} no frames")
        return
    p50, p99, p999 = np.percentile(ms, [50, 99, 99.9])
    print(f"{name:<18}{len(ms):8d}{p50:8.2f}{p99:8.2f}{p999:9.2f}{ms.max():8.2f}"
          f"{ms[:10].max():10.2f}{longest:10.2f}{full:7d}{cpu * 1e3:10.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=0.5, help="length of each run")
    parser.add_argument("--untuned", action="store_true",
                        help="also run the pipeline without warm-up and gc freezing (first)")
    args = parser.parse_args()
    seconds = args.minutes * 60.0
    runs = []
    runs.append(("relay", *relay(seconds)))
    if args.untuned:
        runs.append(("pipeline untuned", *pipeline(seconds, tuned=False)))
    runs.append(("pipeline", *pipeline(seconds)))
    print(f"\nframe → pose latency at 50 Hz over a pty, {args.minutes:g} min per run (ms)")
    print(f"{'':<18}{'frames':>8}{'p50':>8}{'p99':>8}{'p99.9':>9}{'max':>8}{'first 10':>10}"
          f"{'gc max':>10}{'gen2':>7}{'CPU/frame':>10}")
    for name, lat, watch, cpu in runs:
        report(name, lat, watch, cpu)
    print(f"load average: {', '.join(f'{x:.1f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
